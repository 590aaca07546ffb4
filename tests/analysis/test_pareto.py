"""Pareto fronts: the vectorised mask against a brute-force O(n²) dominance check, ties, NaN and error rows."""
import math

import numpy as np
import pytest

from ssbench.analysis.pareto import dominates, pareto_mask, pareto_rows, row_time_ms


def brute_force(errors, times):
    pts = list(zip(errors, times))
    ok = [math.isfinite(e) and math.isfinite(t) for e, t in pts]
    return np.array([ok[i] and not any(ok[j] and dominates(pts[j], pts[i]) for j in range(len(pts)) if j != i)
                     for i in range(len(pts))])


@pytest.mark.parametrize("seed", range(12))
def test_mask_equals_brute_force_on_random_points_with_ties_and_nan(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 80))
    e = rng.integers(0, 6, n).astype(float)                # few distinct values: many ties in each coordinate
    t = rng.integers(0, 6, n).astype(float)
    if seed % 2:
        e, t = rng.random(n), rng.random(n)                 # continuous points too
    e[rng.random(n) < 0.1] = np.nan
    t[rng.random(n) < 0.1] = np.inf
    got = pareto_mask(e, t)
    assert got.dtype == bool and got.tolist() == brute_force(e.tolist(), t.tolist()).tolist()


def test_ties_duplicates_and_unusable_points():
    # two identical best points both stay; an equal-time point with a larger error and an equal-error point with
    # a larger time are dominated; a NaN-error point with the smallest time neither joins nor dominates
    e = [1.0, 1.0, 2.0, 1.0, math.nan, 0.5]
    t = [2.0, 2.0, 2.0, 3.0, 0.1, 5.0]
    assert pareto_mask(e, t).tolist() == [True, True, False, False, False, True]
    assert pareto_mask([], []).tolist() == []
    with pytest.raises(ValueError, match="errors, times"):
        pareto_mask([1.0, 2.0], [1.0])


def test_rows_skip_errors_filter_by_scene_and_sort_by_time():
    rows = [{"scene": "a", "e": 3.0, "t": 1.0}, {"scene": "a", "e": 1.0, "t": 4.0},
            {"scene": "a", "e": 2.0, "t": 5.0}, {"scene": "b", "e": 0.1, "t": 0.1},
            {"scene": "a", "e": 0.0, "t": 0.0, "error": "RuntimeError: boom"}, {"scene": "a", "e": None, "t": 0.5}]
    front, mask = pareto_rows(rows, "e", "t", where=lambda r: r["scene"] == "a")
    assert [r["t"] for r in front] == [1.0, 4.0] and mask.tolist() == [True, True, False, False, False, False]
    front, _ = pareto_rows(rows, lambda r: r["e"], "t")
    assert [r["scene"] for r in front] == ["b"]
    ts = [r["t"] for r in front]
    assert ts == sorted(ts)


def test_row_time_prefers_the_timing_block_and_adds_the_blur():
    assert row_time_ms({"time_median_ms": 4.0, "seconds": 1.0}) == 4.0
    assert row_time_ms({"time_median_ms": float("nan"), "seconds": 0.25, "blur_seconds": 0.5}) == 750.0
    assert row_time_ms({"time_median_ms": 1.5, "blur_seconds": None}) == 1.5
    assert row_time_ms({"seconds_per_frame": 0.002, "seconds": 9.0}) == 2.0
    assert math.isnan(row_time_ms({"seconds": "n/a"}))


def test_the_figure_draws_and_returns_each_scenes_front(tmp_path):
    import matplotlib.image as mimage
    from ssbench.analysis.equal_error import Ladder
    from ssbench.analysis.figures import error_time_figure
    rng = np.random.default_rng(3)
    rows = [{"scene": s, "method": m, "e": float(rng.random()), "f": float(rng.random()),
             "time_median_ms": float(rng.uniform(1, 100))} for s in ("a", "b") for m in ("x", "y") for _ in range(9)]
    path = tmp_path / "et.png"
    lad = Ladder("rays", (2, 4), (0.5, 0.3), (0.01, 0.02), label="gt")
    fronts = error_time_figure(rows, [("e", "E"), ("f", "F")], str(path), ladders={"a": lad}, ladder_metric="e")
    assert set(fronts) == {(s, k) for s in ("a", "b") for k in ("e", "f")}
    for (s, k), front in fronts.items():
        assert front == pareto_rows(rows, k, where=lambda r: r["scene"] == s)[0] and front
    assert mimage.imread(str(path)).shape[:2] == (round(90 * 2.9 * 2), round(90 * 3.6 * 2))
