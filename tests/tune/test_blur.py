"""Tuning with a blur: blur_* tunables, their gradients (autograd vs central differences), names and errors."""
import math

import pytest
import torch

from ssbench.evaluate import blur_fn
from ssbench.passes.ao.gtao import GTAOParams
from ssbench.passes.ao.hbao import HBAOParams
from ssbench.tune import BLUR_DEFAULTS, Objective, apply_blur, baseline, probe, resolve_space, tunable_names, tune

from .conftest import trough_case

torch.set_num_threads(1)


@pytest.mark.parametrize("blur", ["box", "cross_bilateral", "joint_bilateral"])
def test_apply_blur_at_defaults_is_the_evaluate_blur(trough, blur):
    ao = torch.rand(1, 1, trough.gbuffer.height, trough.gbuffer.width, dtype=torch.float64,
                    generator=torch.Generator().manual_seed(1))
    g = trough.gbuffer
    assert torch.equal(apply_blur(blur, ao, g), blur_fn(blur)(ao, g))
    assert torch.equal(apply_blur(blur, ao, g, BLUR_DEFAULTS[blur]), blur_fn(blur)(ao, g))


@pytest.mark.parametrize("method, base, blur, name, value", [
    ("gtao", GTAOParams(radius=1.0), "joint_bilateral", "blur_sigma_color", 0.004),
    ("gtao", GTAOParams(radius=1.0), "joint_bilateral", "blur_sigma_space", 1.2),
    ("hbao", HBAOParams(radius=1.0), "joint_bilateral", "blur_sigma_space", 2.0),
    ("gtao", GTAOParams(radius=1.0), "cross_bilateral", "blur_falloff", 0.02),
    ("hbao", HBAOParams(radius=1.0), "cross_bilateral", "blur_falloff", 0.05),
])
def test_blur_gradient_matches_central_difference(trough, method, base, blur, name, value):
    obj = Objective(method, base, [trough], blur=blur)
    d = probe(lambda t: obj.loss({}, t), {name: value}, [name])[name]
    assert d["differentiable"], d
    x = torch.tensor(value, dtype=torch.float64, requires_grad=True)
    (g,) = torch.autograd.grad(obj.loss({}, {name: x}), x)
    h = 1e-6
    fd = (float(obj.loss({}, {name: torch.tensor(value + h, dtype=torch.float64)}))
          - float(obj.loss({}, {name: torch.tensor(value - h, dtype=torch.float64)}))) / (2 * h)
    assert float(g) == pytest.approx(d["grad"]) and float(g) == pytest.approx(fd, rel=1e-4, abs=1e-9)
    assert float(obj.loss({}, {name: x}).detach()) == pytest.approx(obj({name: value}), rel=1e-5)


def test_threshold_is_not_differentiable_and_the_pass_parameters_still_are(trough):
    obj = Objective("gtao", GTAOParams(radius=1.0), [trough], blur="cross_bilateral")
    start = {"blur_threshold": 0.1, "blur_falloff": 0.02, "falloff_range": 0.6}
    d = probe(lambda t: obj.loss(start, t), start, list(start))
    assert not d["blur_threshold"]["differentiable"] and d["blur_threshold"]["why"] == "no autograd path"
    assert d["blur_falloff"]["differentiable"] and d["falloff_range"]["differentiable"]


def test_the_blur_changes_the_objective_and_invalid_blur_values_are_rejected(trough):
    plain = Objective("gtao", GTAOParams(radius=1.0), [trough])
    blurred = Objective("gtao", GTAOParams(radius=1.0), [trough], blur="joint_bilateral")
    assert plain({}) != blurred({}) and blurred({}) == blurred({"blur_sigma_color": 0.01, "blur_sigma_space": 1.5})
    bad = blurred.evaluate({"blur_sigma_color": 0.0})
    assert bad["status"] == "invalid" and bad["error"] == math.inf and "blur_sigma_color" in bad["reason"]
    assert plain.evaluate({"blur_sigma_color": 0.02})["status"] == "invalid"             # no blur to take it


def test_unknown_blurs_and_blur_parameters_list_the_valid_names():
    known = r"known: box, cross_bilateral, joint_bilateral"
    with pytest.raises(ValueError, match=r"blur: unknown blur 'joint'.*" + known):
        resolve_space("gtao", 0.5, blur="joint")
    with pytest.raises(ValueError, match=known):
        tunable_names("gtao", "gauss")
    with pytest.raises(ValueError, match=known):
        Objective("gtao", baseline("gtao", 0.5), [trough_case()], blur="gauss")
    with pytest.raises(ValueError, match=known):
        tune("gtao", ["a"], cases=([trough_case("a")], []), blur="gauss")
    with pytest.raises(ValueError, match=r"names: 'blur_sigma' is not a tunable parameter of gtao with blur "
                                         r"joint_bilateral \(did you mean 'blur_sigma_space'\?\); tunable: radius, "
                                         r"falloff_range, final_value_power, blur_sigma_color, blur_sigma_space"):
        resolve_space("gtao", 0.5, ["blur_sigma"], blur="joint_bilateral")
    with pytest.raises(ValueError, match=r"bounds: 'blur_sigma_color' is not a tunable parameter of hbao;.*"
                                         r"blur_\* parameters need a blur: box, cross_bilateral, joint_bilateral"):
        resolve_space("hbao", 0.5, bounds={"blur_sigma_color": (0.001, 0.1)})
    assert tunable_names("hbao", "cross_bilateral")[-2:] == ["blur_falloff", "blur_threshold"]
    assert tunable_names("hbao", "box") == tunable_names("hbao")
    s = resolve_space("gtao", 0.5, ["blur_sigma_space"], {"blur_sigma_space": (1.0, 2.0)}, blur="joint_bilateral")
    assert s == {"blur_sigma_space": (1.0, 2.0)}


@pytest.mark.parametrize("blur", ["joint_bilateral", "cross_bilateral"])
def test_tune_with_a_blur_never_ends_worse_than_the_default_on_training(blur):
    train = [trough_case("a", target=0.8), trough_case("b", target=0.9, slope=0.8)]
    held = [trough_case("c", target=0.85, slope=2.5)]
    r = tune("hbao", ["a", "b"], ["c"], cases=(train, held), blur=blur, points=2, rounds=1, steps=3)
    s = r.summary
    assert s["train_tuned"] <= s["train_default"] and r.settings["blur"] == blur
    params = {p["name"]: p for p in r.params}
    assert list(params)[-2:] == list(BLUR_DEFAULTS[blur])
    for n, v in BLUR_DEFAULTS[blur].items():
        assert params[n]["default"] == v
    assert math.isfinite(s["held_default"]) and math.isfinite(s["held_tuned"])
    # the default row is exactly the blurred default configuration
    obj = Objective("hbao", baseline("hbao", 0.5), train, blur=blur)
    assert s["train_default"] == pytest.approx(obj({}))
    if blur == "cross_bilateral":
        assert not params["blur_threshold"]["differentiable"] and params["blur_falloff"]["differentiable"]
    else:
        assert params["blur_sigma_color"]["differentiable"] and params["blur_sigma_space"]["differentiable"]
    only = tune("gtao", ["a"], cases=(train[:1], []), blur=blur, names=list(BLUR_DEFAULTS[blur])[:1], points=3,
                rounds=1, steps=2)
    assert [p["name"] for p in only.params] == list(BLUR_DEFAULTS[blur])[:1]
    assert only.summary["train_tuned"] <= only.summary["train_default"]
