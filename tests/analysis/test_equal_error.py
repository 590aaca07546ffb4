"""Equal-error cost: log–log interpolation is exact on the σ/√n law; the AO ladder follows σ/√n with an
independent seed (real ray tracing, tiny image)."""
import math

import numpy as np
import pytest

from ssbench.analysis.equal_error import Ladder, best_rows, equal_error_n, equal_error_table


@pytest.mark.parametrize("seed", range(5))
def test_interpolation_recovers_n_of_the_sigma_over_root_n_law(seed):
    rng = np.random.default_rng(seed)
    sigma = float(rng.uniform(0.05, 0.5))
    ns = [2, 4, 8, 16, 32, 64]
    errs = [sigma / math.sqrt(n) for n in ns]
    n_true = float(rng.uniform(2.5, 60))
    eq = equal_error_n(ns, errs, sigma / math.sqrt(n_true))
    assert eq.status == "interpolated" and eq.n == pytest.approx(n_true, rel=1e-9)
    far = equal_error_n(ns, errs, sigma / math.sqrt(1000.0))          # below the ladder: the law continued
    assert far.status == "extrapolated" and far.n == pytest.approx(1000.0, rel=1e-9)


def test_edges_of_the_ladder():
    ns, errs = [2, 4, 8], [0.3, 0.2, 0.1]
    assert (equal_error_n(ns, errs, 0.5).status, equal_error_n(ns, errs, 0.5).n) == ("at_most", 2.0)
    assert equal_error_n(ns, errs, 0.5).text == "≤ 2"
    assert equal_error_n(ns, [0.3, 0.0, 0.0], 0.0).n == 4.0                    # first ladder point at zero
    flat = equal_error_n(ns, [0.2, 0.2, 0.2], 0.1)
    assert flat.status == "unreachable" and flat.text == "> 8"
    # the NaN point is dropped: interpolation between (2, 0.3) and (8, 0.1) in log-log
    assert equal_error_n([2, 4, 8], [0.3, float("nan"), 0.1], 0.2).n == pytest.approx(2 * 4 ** (math.log(1.5)
                                                                                              / math.log(3)))
    with pytest.raises(ValueError, match="ns"):
        equal_error_n([4, 2], [0.1, 0.2], 0.1)
    with pytest.raises(ValueError, match="target"):
        equal_error_n([2, 4], [0.1, 0.2], -1.0)


def test_seconds_fit_is_exact_on_a_linear_cost():
    lad = Ladder("rays", (2, 4, 8, 16), (0.4, 0.3, 0.2, 0.1), tuple(0.05 + 0.01 * n for n in (2, 4, 8, 16)))
    assert lad.seconds_at(10.0) == pytest.approx(0.15) and lad.seconds_at(100.0) == pytest.approx(1.05)


def test_best_rows_and_the_table_on_a_synthetic_ladder():
    sigma = 0.2
    ns = (2, 4, 8, 16, 32)
    lad = Ladder("rays", ns, tuple(sigma / math.sqrt(n) for n in ns), tuple(0.001 * n for n in ns))
    rows = [{"config_id": "a", "scene": "s", "method": "m", "e": sigma / math.sqrt(9), "time_median_ms": 3.0},
            {"config_id": "b", "scene": "s", "method": "m", "e": sigma / math.sqrt(9), "time_median_ms": 2.0},
            {"config_id": "c", "scene": "s", "method": "m", "e": 0.001, "time_median_ms": 1.0, "error": "X: y"},
            {"config_id": "d", "scene": "s", "method": "k", "e": float("nan"), "time_median_ms": 1.0},
            {"config_id": "e", "scene": "t", "method": "m", "e": 0.5, "time_median_ms": 1.0}]
    best = best_rows(rows, "e")
    assert {k: r["config_id"] for k, r in best.items()} == {("s", "m"): "b", ("t", "m"): "e"}   # tie -> faster
    (entry,) = equal_error_table(rows, {"s": lad}, "e")                        # scene t has no ladder
    assert entry["config_id"] == "b" and entry["n"] == pytest.approx(9.0)
    assert entry["gt_ms"] == pytest.approx(9.0) and entry["ratio"] == pytest.approx(4.5)


@pytest.mark.slow
@pytest.mark.mitsuba
def test_ao_ladder_follows_sigma_over_root_n_with_an_independent_seed():
    import torch
    torch.set_num_threads(1)
    from ssbench.analysis.equal_error import ao_ladder
    rays = 64
    lad = ao_ladder("crease", 32, 24, 0.5, rays, seed=0, ns=[2, 8, 64])
    assert lad.ns == (2, 8, 64) and lad.kind == "rays" and all(s > 0 for s in lad.seconds)
    # E[RMSE²] = σ̄²(1/n + 1/R): the model from the reference's own standard error, not from the ladder
    for err, pred in zip(lad.errors, lad.predicted):
        assert err == pytest.approx(pred, rel=0.3)          # seeds 0-2 measured within 0.91-1.29
    assert lad.errors[0] > lad.errors[1] > lad.errors[2] > 0       # n = R with an independent seed is not 0
    eq = lad.n_for(lad.errors[1])
    assert eq.n == pytest.approx(8.0, rel=1e-6)
