"""ssbench.evaluate.implicit / run_implicit: per-frame punch-through, class fractions, prediction, errors."""
import math

import pytest
import torch

from ssbench import evaluate
from ssbench.metrics.implicit import CLASS_NAMES

SIZE = dict(width=32, height=24)


@pytest.fixture(scope="module", autouse=True)
def _one_thread():
    """Tiny images gain nothing from more threads, and OpenMP barriers stall on shared cores."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def shell_rows():
    """Progressive and fixed step at the same N on the thin shell (the article's comparison), 10 frames."""
    kw = dict(frames=10, seed=0, lipschitz_samples=2000, **SIZE)
    prog = evaluate.run_implicit("thin_shell", "progressive", {"steps": 32}, keep="all", **kw)
    fixed = evaluate.run_implicit("thin_shell", "fixed", {"steps": 32}, **kw)
    return prog, fixed


def test_progressive_punch_through_falls_and_fixed_step_stays_flat(shell_rows):
    prog, fixed = (ev.row for ev in shell_rows)
    p, f = prog["punch_through_per_frame"], fixed["punch_through_per_frame"]
    assert len(p) == len(f) == 10
    assert len(set(f)) == 1 and f[0] > 0.5                                  # a fixed lattice never learns
    assert all(b <= a for a, b in zip(p, p[1:]))                             # t' only shrinks on a static scene
    assert p[-1] < 0.5 * p[0]
    assert abs(p[0] - f[0]) < 0.1                                            # frame 1: the same N, jittered
    assert prog["static"] and prog["truth_traced"] == 1                      # one trace, reused for 10 frames
    assert prog["invalidated_per_frame"] == [0] * 10 and fixed["invalidated_per_frame"] is None


def test_h_over_w_prediction_is_in_the_row(shell_rows):
    prog, fixed = (ev.row for ev in shell_rows)
    pp, pf = prog["predicted_punch_through"], fixed["predicted_punch_through"]
    assert len(pp) == len(pf) == 10 and prog["prediction_h"] == "t'/N" and fixed["prediction_h"] == "t_far/N"
    assert len(set(pf)) == 1 and pp[0] == pytest.approx(pf[0], abs=1e-6)     # frame 1: t' = t_far for both
    assert all(b < a for a, b in zip(pp, pp[1:]))
    for measured, predicted in ((prog["punch_through_per_frame"], pp), (fixed["punch_through_per_frame"], pf)):
        assert abs(measured[0] - predicted[0]) < 0.1 and abs(measured[-1] - predicted[-1]) < 0.15


def test_class_fractions_sum_to_one_and_row_is_complete(shell_rows):
    prog, _ = shell_rows
    row = prog.row
    assert sum(row[f"frac_{n}"] for n in CLASS_NAMES.values()) == pytest.approx(1.0)
    assert row["correct_rate"] + row["punch_through_rate"] + row["early_hit_rate"] == pytest.approx(1.0)
    assert row["punch_through_rate"] == row["punch_through_per_frame"][-1]
    assert row["evaluations_mean"] <= row["evaluations_p95"] <= row["evaluations_max"]
    assert row["seconds_per_frame"] > 0 and len(row["seconds_frames"]) == 10 and row["threads"] >= 1
    assert row["lambda_declared"] == 1.0 and row["lambda_overshoot"] is False
    assert row["truth_certified"] == 1.0 and row["truth_ambiguous_pixels"] == 0 and row["nonfinite"] == 0
    assert row["truth_engine"] == prog.truth.engine in ("drjit", "torch")
    assert row["depth_max"] < 1e-3 and (row["width"], row["height"]) == (32, 24)
    assert sorted(prog.results) == list(range(10)) and sorted(prog.classes) == list(range(10))
    assert prog.truth is prog.truths[0] and tuple(prog.result.t.shape) == (1, 1, 24, 32)


@pytest.mark.parametrize("method", ["fixed", "sphere", "progressive"])
def test_every_method_one_frame(method):
    calls = []
    ev = evaluate.run_implicit("torus", method, frames=1, lipschitz_samples=0, width=24, height=18,
                               on_frame=lambda k, res, cam, cls: calls.append((k, cls is not None)))
    row = ev.row
    assert calls == [(0, True)] and list(ev.results) == [0]
    assert sum(row[f"frac_{n}"] for n in CLASS_NAMES.values()) == pytest.approx(1.0)
    assert row["frac_correct"] > 0.15 and row["nonfinite"] == 0
    assert (row["overshoot_pixels"] is not None) == (method == "sphere")
    assert (row["predicted_punch_through"] is None) == (method == "sphere")


def test_animated_object_motion_is_invalidated_the_next_frame():
    row = evaluate.implicit("animated", "progressive", frames=13, truth_frames="none", lipschitz_samples=0, **SIZE)
    inv = row["invalidated_per_frame"]
    assert sum(inv[:11]) == 0 and inv[11] > 0                                # the ball moves from frame 11 on
    assert not row["static"] and row["truth_traced"] == 0 and math.isnan(row["punch_through_rate"])
    assert row["punch_through_per_frame"] == [None] * 13


def test_lambda_diagnostic_flags_the_displaced_torus():
    from ssbench.implicit.scene import load
    bad = evaluate.lipschitz_diagnostic(load("displaced_torus").surface(0), 4000)
    good = evaluate.lipschitz_diagnostic(load("torus").surface(0), 4000)
    assert bad["lambda_overshoot"] is True and bad["lambda_observed"] > 1.5 and bad["lambda_declared"] == 1.0
    assert good["lambda_overshoot"] is False


def test_steps_param():
    assert [evaluate.steps_param(m) for m in ("fixed", "progressive", "sphere")] == ["steps", "steps", "max_steps"]


@pytest.mark.parametrize("args, kwargs, err, match", [
    (("no_such_scene", "fixed"), {}, KeyError, "no_such_scene"),
    (("sphere", "raymarch"), {}, KeyError, "unknown implicit method 'raymarch'"),
    (("sphere", "fixed", {"stepz": 3}), {}, ValueError, "unknown parameter.*'stepz'"),
    (("sphere", "fixed", {"steps": 0}), {}, ValueError, "steps"),
    (("sphere", "fixed"), {"frames": 0}, ValueError, "frames"),
    (("sphere", "fixed"), {"truth_frames": "some"}, ValueError, "truth_frames"),
    (("sphere", "fixed"), {"keep": "first"}, ValueError, "keep"),
    (("sphere", "fixed"), {"seed": -3}, ValueError, "seed"),
    (("double_root", "sphere"), {}, ValueError, "lipschitz"),
])
def test_bad_input_names_the_problem(args, kwargs, err, match):
    with pytest.raises(err, match=match):
        evaluate.implicit(*args, lipschitz_samples=0, width=8, height=6, **kwargs)


def test_plain_sphere_tracing_shows_the_displaced_torus_holes():
    """The catalog's displaced_torus declares λ = 1 (false): the safeguard hides the article's failure case,
    plain sphere tracing (safeguard=False) shows it as punch-through against the certified truth."""
    guarded = evaluate.run_implicit("displaced_torus", "sphere", frames=1).row
    plain = evaluate.run_implicit("displaced_torus", "sphere", {"safeguard": False}, frames=1).row
    assert guarded["punch_through_rate"] == 0.0 and guarded["overshoot_pixels"] > 100
    assert plain["punch_through_rate"] > 0.1 and plain["overshoot_pixels"] == 0
    assert plain["params"]["safeguard"] is False
