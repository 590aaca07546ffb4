"""Gradients through the torch passes: autograd agrees with central differences (float64); probing; Adam steps."""
import math

import pytest
import torch

from ssbench.passes.ao.gtao import GTAOParams
from ssbench.passes.ao.hbao import HBAOParams
from ssbench.tune import Objective, inject, probe, refine

torch.set_num_threads(1)


@pytest.mark.parametrize("method, base, name, value", [
    ("gtao", GTAOParams(radius=1.0), "falloff_range", 0.5),
    ("gtao", GTAOParams(radius=1.0), "final_value_power", 1.7),
    ("gtao", GTAOParams(radius=1.0), "radius", 0.9),
    ("hbao", HBAOParams(radius=1.0), "ao_strength", 1.3),
    ("hbao", HBAOParams(radius=1.0), "tan_angle_bias", 0.3),
    ("hbao", HBAOParams(radius=1.0), "radius", 0.9),
])
def test_autograd_matches_central_difference(trough, method, base, name, value):
    obj = Objective(method, base, [trough])
    x = torch.tensor(value, dtype=torch.float64, requires_grad=True)
    loss = obj.loss({}, {name: x})
    (g,) = torch.autograd.grad(loss, x)
    h = 1e-6
    fd = (float(obj.loss({}, {name: torch.tensor(value + h, dtype=torch.float64)}))
          - float(obj.loss({}, {name: torch.tensor(value - h, dtype=torch.float64)}))) / (2 * h)
    assert math.isfinite(float(g)) and float(g) != 0.0
    assert float(g) == pytest.approx(fd, rel=1e-4, abs=1e-9)
    # the tensor path computes the number the float path (scored in float32) does
    assert float(loss.detach()) == pytest.approx(obj({name: value}), rel=1e-6)


def test_probe_finds_what_is_and_is_not_differentiable(trough):
    obj = Objective("hbao", HBAOParams(radius=1.0), [trough])
    start = {"max_radius_pixels": 50.0, "tan_angle_bias": 0.3, "ao_strength": 1.0}
    d = probe(lambda t: obj.loss(start, t), start, list(start))
    assert d["max_radius_pixels"]["differentiable"] is False
    assert d["tan_angle_bias"]["differentiable"] and d["ao_strength"]["differentiable"]
    g = Objective("gtao", GTAOParams(radius=1.0), [trough])
    s = {"sample_distribution_power": 2.0, "falloff_range": 0.6}
    dg = probe(lambda t: g.loss(s, t), s, list(s))
    assert dg["sample_distribution_power"]["grad"] == 0.0 and not dg["sample_distribution_power"]["differentiable"]
    assert dg["falloff_range"]["differentiable"]


def test_inject_keeps_the_original_and_names_unknown_fields():
    p = GTAOParams()
    q = inject(p, {"radius": torch.tensor(2.0)})
    assert isinstance(q.radius, torch.Tensor) and p.radius == 0.5
    with pytest.raises(ValueError, match="tensors: unknown field.*bogus"):
        inject(p, {"bogus": torch.tensor(1.0)})


def test_refine_reaches_a_quadratic_minimum_and_respects_bounds():
    loss = lambda t: (t["a"] - 0.3) ** 2 + (t["b"] - 5.0) ** 2      # noqa: E731  b's minimum is outside
    r = refine(loss, {"a": 0.9, "b": 0.0, "c": 7.0}, ["a", "b"], {"a": (0.0, 1.0), "b": (-1.0, 1.0)},
               steps=300, lr=0.02, dtype=torch.float64)
    assert r.best["a"] == pytest.approx(0.3, abs=1e-3) and r.best["b"] == pytest.approx(1.0, abs=1e-9)
    assert r.best["c"] == 7.0 and len(r.history) == 301
    assert r.value == pytest.approx(min(h["loss"] for h in r.history))


def test_refine_rejects_bad_arguments():
    loss = lambda t: t["a"] ** 2                                      # noqa: E731
    with pytest.raises(ValueError, match="steps"):
        refine(loss, {"a": 0.5}, ["a"], {"a": (0, 1)}, steps=-1)
    with pytest.raises(ValueError, match="lr"):
        refine(loss, {"a": 0.5}, ["a"], {"a": (0, 1)}, lr=0)
    with pytest.raises(ValueError, match="names"):
        refine(loss, {"a": 0.5}, [], {"a": (0, 1)})
