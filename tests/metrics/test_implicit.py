"""Implicit-surface metrics: per-pixel classes, summary, Lipschitz diagnostic, the h/w prediction."""
import math
from dataclasses import replace
from types import SimpleNamespace as NS

import pytest
import torch

from ssbench.metrics import implicit as M


def img(*rows, dtype=torch.float64):
    """(B, 1, H, W) from nested lists [b][h][w]."""
    return torch.tensor(rows, dtype=dtype).unsqueeze(1)


# ------------------------------------------------------------------------------------------ classes
def test_classify_covers_every_class_with_relative_and_absolute_tolerance():
    # truth t = 10 everywhere it hits: tol = 1e-6 + 1e-3·10 ≈ 0.01
    truth = NS(t=img([[10.0, 10.0, 10.0, 10.0, 10.0, 10.0]], [[50.0, 50.0, 10.0, 10.0, 10.0, 10.0]]),
               hit=img([[1, 1, 1, 1, 1, 1]], [[0, 0, 1, 1, 1, 1]], dtype=torch.bool),
               unfinished=img([[0, 0, 0, 0, 0, 0]], [[0, 0, 0, 0, 0, 1]], dtype=torch.bool))
    res = NS(t=img([[10.0099, 10.0101, 9.9899, 50.0, 9.995, 20.0]], [[50.0, 12.0, 10.0, 10.0, 10.0, 3.0]],
                   dtype=torch.float32),
             hit=img([[1, 1, 1, 0, 1, 1]], [[0, 1, 1, 1, 1, 1]], dtype=torch.bool))
    c, names = M.classify(res, truth)
    got = [[names[int(v)] for v in row] for row in c[:, 0, 0].tolist()]
    assert got == [["correct", "punch_through", "early_hit", "punch_through", "correct", "punch_through"],
                   ["true_miss", "false_hit", "correct", "correct", "correct", "unknown"]]
    assert c.dtype == torch.int8 and c.shape == (2, 1, 1, 6) and set(names) == set(M.CLASS_NAMES)
    loose, _ = M.classify(res, truth, rtol=0.0, atol=0.02)         # absolute only: 10.0101 now correct
    assert names[int(loose[0, 0, 0, 1])] == "correct" and names[int(loose[0, 0, 0, 2])] == "correct"
    assert M.class_counts(c) == {"true_miss": 1, "correct": 5, "punch_through": 3, "early_hit": 1,
                                 "false_hit": 1, "unknown": 1}


def test_classify_nan_depth_is_never_correct_and_errors_name_arguments():
    truth = NS(t=img([[2.0]]), hit=img([[1]], dtype=torch.bool), unfinished=img([[0]], dtype=torch.bool))
    res = NS(t=img([[math.nan]]), hit=img([[1]], dtype=torch.bool))
    assert int(M.classify(res, truth)[0]) == M.PUNCH_THROUGH
    with pytest.raises(ValueError, match="truth.hit"):
        M.classify(res, NS(t=truth.t, hit=img([[1, 1]], dtype=torch.bool), unfinished=truth.unfinished))
    with pytest.raises(TypeError, match="truth.unfinished"):
        M.classify(res, NS(t=truth.t, hit=truth.hit))
    with pytest.raises(ValueError, match="rtol"):
        M.classify(res, truth, rtol=-1.0)


def test_summary_numbers_by_hand():
    truth = NS(t=img([[2.0, 4.0, 5.0, 9.0, 9.0, 8.0]]), hit=img([[1, 1, 1, 0, 0, 1]], dtype=torch.bool),
               unfinished=img([[0, 0, 0, 0, 0, 0]], dtype=torch.bool),
               ambiguous_t=img([[math.inf, math.inf, math.inf, 3.0, math.inf, math.inf]]))
    res = NS(t=img([[2.001, 4.0, 7.0, 3.0, 9.0, 8.004]]), hit=img([[1, 1, 1, 1, 0, 1]], dtype=torch.bool),
             evaluations=img([[10, 20, 30, 40, 50, 100]], dtype=torch.int32), steps=img([[1, 2, 3, 4, 5, 6]]))
    s = M.summary(res, truth)
    # truth hits: px 0 (err .001 <= .003 correct), 1 (exact), 2 (farther root: punch-through), 5 (.004 <= .009)
    assert s["truth_hit_pixels"] == 4 and s["truth_miss_pixels"] == 2 and s["pixels"] == 6
    assert s["correct_rate"] == 0.75 and s["punch_through_rate"] == 0.25 and s["early_hit_rate"] == 0.0
    assert s["false_hit_rate"] == 0.5 and s["true_miss_rate"] == 0.5 and s["unknown_rate"] == 0.0
    assert s["false_hit_ambiguous"] == 1.0 and s["n_correct"] == 3
    assert s["depth_mae"] == pytest.approx((0.001 + 0 + 0.004) / 3)
    assert s["depth_max"] == pytest.approx(0.004)
    assert s["depth_rel_mae"] == pytest.approx((0.001 / 2 + 0.004 / 8) / 3)
    assert s["depth_rel_max"] == pytest.approx(0.0005)
    assert s["evaluations_mean"] == 250 / 6 and s["evaluations_p50"] == 35.0 and s["evaluations_max"] == 100.0
    assert s["evaluations_p95"] == pytest.approx(50 + 0.75 * 50)   # linear: position 0.95·5 = 4.75
    assert s["steps_mean"] == 3.5
    sm = M.summary(res, truth, mask=img([[1, 1, 0, 0, 0, 0]], dtype=torch.bool))
    assert sm["pixels"] == 2 and sm["correct_rate"] == 1.0 and math.isnan(sm["false_hit_rate"])


def test_chord_from_a_reference():
    truth = NS(t=img([[2.0, 9.0]]), t_exit=img([[2.5, 9.0]]), hit=img([[1, 0]], dtype=torch.bool))
    assert M.chord(truth).flatten().tolist() == [0.5, 0.0]


# ------------------------------------------------------------------------------------------ Lipschitz
@pytest.fixture(scope="module")
def scenes():
    from ssbench.implicit.scene import load
    return {n: load(n).surface(0) for n in ("sphere", "displaced_torus", "badly_scaled", "torus")}


def test_lipschitz_check_flags_the_displaced_torus_not_the_sphere(scenes):
    g = torch.Generator().manual_seed(1)
    bad = M.lipschitz_check(scenes["displaced_torus"], samples=20_000, generator=g)
    # sup |∇f| = 1 + 0.045·20·max|∇(sin sin sin)| = 1.9 (the catalog's 1 + 0.9√3 is a looser bound)
    assert bad["declared"] == 1.0 and bad["overshoot"] and 1.8 < bad["observed_max_grad"] <= 1.9 + 1e-9
    assert bad["ratio"] == bad["observed_max_grad"] and bad["nonfinite"] == 0 and bad["near_samples"] > 5000
    for name in ("sphere", "torus"):
        ok = M.lipschitz_check(scenes[name], samples=20_000)
        assert not ok["overshoot"] and ok["observed_max_grad"] == pytest.approx(1.0, abs=1e-9), name
    none = M.lipschitz_check(scenes["badly_scaled"], samples=5_000)
    assert none["declared"] is None and not none["overshoot"] and none["observed_max_grad"] > 2000
    a = M.lipschitz_check(scenes["sphere"], samples=1000)
    assert a == M.lipschitz_check(scenes["sphere"], samples=1000)  # default generator: deterministic


def test_lipschitz_check_errors():
    from ssbench.passes.implicit.common import FunctionSurface
    with pytest.raises(ValueError, match="bounds"):
        M.lipschitz_check(FunctionSurface(lambda p: p.norm(dim=-1) - 1, lipschitz=1.0))
    with pytest.raises(ValueError, match="samples"):
        M.lipschitz_check(FunctionSurface(lambda p: p.norm(dim=-1) - 1, bounds=((-1,) * 3, (1,) * 3)), samples=0)


# ------------------------------------------------------------------------------------------ h / w prediction
def _simulate(h_frames, w, gen):
    """Jittered sampling of 1-D slabs [c, c + w]: samples s0 + k·h with s0 ~ U[0, h) each frame."""
    alive = torch.ones_like(w, dtype=torch.bool)
    curve, hits = [], []
    c = 5.0 + 3.0 * torch.rand(w.shape, generator=gen, dtype=torch.float64)
    for h in h_frames:
        s0 = h * torch.rand(w.shape, generator=gen, dtype=torch.float64)
        first = s0 + torch.ceil((c - s0) / h) * h                  # first sample at or after c
        found = first <= c + w
        hits.append(found.double().mean())
        alive &= ~found
        curve.append(alive.double().mean())
    return torch.stack(curve), torch.stack(hits)


def test_prediction_matches_monte_carlo_of_jittered_sampling():
    gen = torch.Generator().manual_seed(0)
    n = 100_000
    w = (0.25 * torch.rand(n, generator=gen, dtype=torch.float64) ** 2).view(1, 1, 1, n)   # many chords < h
    h_frames = [0.25, 0.25, 0.2, 0.3, 0.25, 0.25, 0.25, 0.25]
    sim, found1 = _simulate(h_frames, w, gen)
    pred = M.predicted_punch_through(h_frames, w)
    assert pred.shape == (8,) and torch.all(pred[1:] <= pred[:-1])
    assert torch.allclose(sim, pred, atol=4 * math.sqrt(0.25 / n))
    per_frame = M.detection_prediction(torch.tensor(h_frames, dtype=torch.float64).view(-1, 1, 1, 1, 1), w)
    assert torch.allclose(found1, per_frame.mean(dim=(1, 2, 3, 4)), atol=4 * math.sqrt(0.25 / n))
    # per-pixel maps and repeats of the last step
    maps = torch.full((1, 1, 1, n), 0.25, dtype=torch.float64)
    assert torch.allclose(M.predicted_punch_through(maps, w, frames=3), M.predicted_punch_through([0.25] * 3, w))
    assert M.predicted_punch_through([0.5, 0.25], w, frames=4)[3] == M.predicted_punch_through(
        [0.5, 0.25, 0.25, 0.25], w)[3]


def test_prediction_errors_and_edges():
    w = torch.tensor([0.1, 0.0], dtype=torch.float64).view(1, 1, 1, 2)
    assert M.detection_prediction(0.05, w).flatten().tolist() == [1.0, 0.0]
    assert M.predicted_punch_through(0.2, w, frames=2).tolist() == [0.5, 0.25]      # mask: chord > 0
    assert torch.isnan(M.predicted_punch_through(0.2, torch.zeros(1, 1, 1, 2), frames=1)).all()
    with pytest.raises(ValueError, match="h"):
        M.detection_prediction(0.0, w)
    with pytest.raises(ValueError, match="frames"):
        M.predicted_punch_through(0.2, w)
    with pytest.raises(ValueError, match="h_per_frame"):
        M.predicted_punch_through(torch.zeros(2, 2), w)


# ------------------------------------------------------------------------------------------ end to end
@pytest.mark.slow
def test_fixed_step_punch_through_on_the_thin_shell_matches_the_prediction():
    """Jittered fixed step (= the progressive method's first frame) against the certified truth and h/w."""
    from ssbench.implicit.scene import load
    from ssbench.passes.implicit.common import camera_rays
    from ssbench.passes.implicit.fixed import FixedStepParams, fixed_step
    from ssbench.reference.implicit import implicit
    sc = load("thin_shell")
    surf, cam = sc.surface(0), replace(sc.camera_at(0), width=32, height=24)
    truth = implicit(surf, cam, exits=True, use_cache=False)
    N = 32
    rates = []
    for seed in range(8):
        res = fixed_step(surf, cam, FixedStepParams(steps=N, jitter=True, seed=seed), dtype=torch.float64)
        s = M.summary(res, truth)
        assert s["unknown_rate"] == 0 and s["early_hit_rate"] == 0.0
        rates.append(s["punch_through_rate"])
    h = camera_rays(cam, dtype=torch.float64).t_far / N
    pred = float(M.predicted_punch_through(h, M.chord(truth), frames=1)[0])
    n = int(truth.hit.sum()) * len(rates)
    assert 0.5 < pred < 1.0 and abs(sum(rates) / len(rates) - pred) < 4 * math.sqrt(pred * (1 - pred) / n) + 0.01
    plain = fixed_step(surf, cam, FixedStepParams(steps=N), dtype=torch.float64)
    assert M.summary(plain, truth)["punch_through_rate"] > 0.5     # the article's right-hand image


def test_survivor_form_puts_only_unfound_pixels_at_risk():
    w = torch.tensor([0.05, 0.1, 0.0], dtype=torch.float64).view(1, 1, 1, 3)
    h = torch.full((3, 1, 1, 1, 3), 0.2, dtype=torch.float64)
    none = torch.zeros(3, 1, 1, 1, 3, dtype=torch.bool)
    # nobody is ever found: the survivor form equals the one-frame miss probability every frame (no product)
    assert M.survivor_punch_through(h, w, none).tolist() == pytest.approx([(0.75 + 0.5) / 2] * 3)
    found = none.clone()
    found[0, ..., 1] = found[1:, ..., :2] = True                 # pixel 1 found at frame 1, pixel 0 at frame 2
    assert M.survivor_punch_through(h, w, found).tolist() == pytest.approx([(0.75 + 0.5) / 2, 0.75 / 2, 0.0])
    with pytest.raises(ValueError, match="h_per_frame"):
        M.survivor_punch_through(h[0], w, found[0])
    assert torch.isnan(M.survivor_punch_through(h, torch.zeros_like(w), none)).all()


@pytest.mark.slow
def test_survivor_prediction_tracks_the_measured_progressive_curve_on_thin_shell():
    """The issue's acceptance: predicted vs measured punch-through within a factor 1.5 at frames 10–40 on
    thin_shell (pooled over 4 seeds, so late frames are not a handful of pixels), where the product form was
    off by ~5x at frame 40 (0.64 % vs 0.13 %)."""
    from ssbench.evaluate import run_implicit
    pred, meas = torch.zeros(40, dtype=torch.float64), torch.zeros(40, dtype=torch.float64)
    for seed in range(4):
        row = run_implicit("thin_shell", "progressive", {"seed": seed}, frames=40).row
        pred += torch.tensor(row["predicted_punch_through"], dtype=torch.float64)
        meas += torch.tensor(row["punch_through_per_frame"], dtype=torch.float64)
        assert row["predicted_frames_to_1pct"] == pytest.approx(row["frames_to_1pct"], abs=2)
    ratio = pred[9:] / meas[9:]
    assert bool(((ratio > 1 / 1.5) & (ratio < 1.5)).all()), ratio.tolist()
