"""The search space, the objective (budget rejection, invalid values) and ``tune`` end to end on synthetic cases."""
import math

import pytest
import torch

from ssbench.passes.ao.gtao import GTAOParams
from ssbench.tune import Objective, baseline, median_timer, resolve_space, tunable_names, tune
from ssbench.tune.space import coerce_fixed

from .conftest import trough_case

torch.set_num_threads(1)


def test_unknown_method_and_parameters_list_the_valid_names():
    with pytest.raises(ValueError, match=r"method: unknown AO method 'gtoa' \(did you mean 'gtao'\?\); known: "
                                         r"crytek, ssao, hbao, gtao"):
        tunable_names("gtoa")
    with pytest.raises(ValueError, match="names: 'radus' is not a tunable parameter of gtao.*tunable: radius, "
                                         "falloff_range, final_value_power"):
        resolve_space("gtao", 0.5, ["radus"])
    with pytest.raises(ValueError, match="bounds: 'quality' is not a tunable"):
        resolve_space("gtao", 0.5, bounds={"quality": (0, 1)})
    with pytest.raises(ValueError, match="params: unknown parameter 'slices'.*known: quality, slice_count"):
        coerce_fixed("gtao", {"slices": 2})
    with pytest.raises(ValueError, match="names: radius both fixed"):
        resolve_space("gtao", 0.5, ["radius"], fixed={"radius": 1.0})
    with pytest.raises(ValueError, match="bounds: radius needs finite lo < hi"):
        resolve_space("gtao", 0.5, bounds={"radius": (1.0, 1.0)})
    with pytest.raises(ValueError, match="gt_radius: must be"):
        baseline("gtao", 0.0)


def test_space_and_baseline():
    s = resolve_space("ssao", 2.0)
    assert list(s) == ["kernel_radius", "min_distance", "max_distance", "strength"]
    assert s["kernel_radius"] == (0.5, 8.0) and s["strength"] == (0.5, 2.0)      # radius range scales with R
    assert list(resolve_space("hbao", 0.5, fixed={"ao_strength": 1.0})) == ["radius", "tan_angle_bias"]
    b = baseline("ssao", 0.7, {"kernel_size": 8, "strength": 2})
    assert (b.kernel_radius, b.kernel_size, b.strength) == (0.7, 8, 2.0) and isinstance(b.strength, float)
    assert baseline("gtao", 0.5, {"radius": 0.9}).radius == 0.9                  # fixed radius wins


def test_objective_is_deterministic_and_flags_invalid_values():
    obj = Objective("ssao", baseline("ssao", 0.5), [trough_case()])
    a, b = obj({"kernel_radius": 0.8}), obj.evaluate({"kernel_radius": 0.8})
    assert a == b["error"] and math.isfinite(a) and len(obj.history) == 1      # memoised
    fresh = Objective("ssao", baseline("ssao", 0.5), [trough_case()])
    assert fresh({"kernel_radius": 0.8}) == a
    bad = obj.evaluate({"min_distance": 0.05, "max_distance": 0.01})
    assert bad["status"] == "invalid" and bad["error"] == math.inf and "max_distance" in bad["reason"]
    with pytest.raises(ValueError, match="budget_ms"):
        Objective("ssao", baseline("ssao", 0.5), [trough_case()], budget_ms=0)
    with pytest.raises(TypeError, match="base: expected HemisphereSSAOParams"):
        Objective("ssao", GTAOParams(), [trough_case()])


def test_budget_rejects_slow_configurations_with_a_fake_timer():
    calls = []

    def fake_timer(call, values):                    # "time" grows with the radius; no clock involved
        calls.append(values)
        return call(), 10.0 * values["radius"]

    cases = [trough_case("a", target=0.3)]           # a dark target: the largest radius fits best
    free = tune("gtao", ["a"], cases=(cases, []), names=["radius"], bounds={"radius": (0.2, 1.0)}, points=5,
                rounds=2, steps=0, timer=fake_timer)
    assert free.params[0]["tuned"] == pytest.approx(1.0) and free.params[0]["at_bound"] == "hi"
    capped = tune("gtao", ["a"], cases=(cases, []), names=["radius"], bounds={"radius": (0.2, 1.0)}, points=5,
                  rounds=2, steps=0, budget_ms=6.0, timer=fake_timer)
    assert capped.params[0]["tuned"] <= 0.6 and capped.search["rejected_over_budget"] >= 2
    assert capped.summary["time_ms_tuned"] <= 6.0 and capped.summary["train_tuned"] > free.summary["train_tuned"]
    assert all("radius" in v for v in calls)
    none = tune("gtao", ["a"], cases=(cases, []), names=["radius"], bounds={"radius": (0.2, 1.0)}, points=3,
                rounds=1, steps=2, budget_ms=1.0, timer=fake_timer)
    assert none.summary["source"] == "default" and not none.summary["within_budget"]
    assert "no configuration met the budget of 1 ms per frame (fastest measured 2 ms)" in none.summary["note"]
    assert none.summary["train_tuned"] == none.summary["train_default"] and math.isfinite(none.rows[0]["default"])
    assert none.search["gradient"] == [] and free.summary["within_budget"] and free.summary["note"] == ""
    obj = Objective("gtao", baseline("gtao", 0.5), cases, budget_ms=6.0, timer=fake_timer)
    rec = obj.evaluate({"radius": 0.9})
    assert rec["status"] == "over_budget" and rec["error"] == math.inf and rec["time_ms"] == 9.0


def test_tune_never_ends_worse_than_the_default_on_training():
    train = [trough_case("a", target=0.8), trough_case("b", target=0.9, slope=0.8)]
    held = [trough_case("c", target=0.85, slope=2.5)]
    r = tune("gtao", ["a", "b"], ["c"], cases=(train, held), points=3, rounds=2, steps=3)
    s = r.summary
    assert s["train_tuned"] <= s["train_default"] and s["source"] in ("default", "grid", "gradient")
    assert [(x["scene"], x["split"]) for x in r.rows] == [("a", "train"), ("b", "train"), ("c", "held_out")]
    assert math.isfinite(s["held_default"]) and math.isfinite(s["held_tuned"])
    assert s["held_improved"] == (s["held_tuned"] < s["held_default"])
    assert {p["name"] for p in r.params} == {"radius", "falloff_range", "final_value_power"}
    assert r.search["differentiable"] and len(r.search["gradient"]) == 4
    assert s["time_ms_default"] > 0 and r.settings["held_out"] == ["c"]
    with pytest.raises(ValueError, match="held_out: a also in train"):
        tune("gtao", ["a"], ["a"], cases=(train, held))
    with pytest.raises(ValueError, match="weighting: expected one of"):
        tune("gtao", ["a"], cases=(train, held), weighting="ambient")


def test_median_timer_returns_the_output_and_rejects_bad_repeats():
    out, ms = median_timer(2)(lambda: 41 + 1, {})
    assert out == 42 and ms >= 0
    with pytest.raises(ValueError, match="repeats"):
        median_timer(0)
