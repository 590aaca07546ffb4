"""Grid narrowing on analytic functions: it finds known minima, never gets worse, and rejects bad arguments."""
import math

import pytest

from ssbench.tune import grid_narrow


def test_finds_the_minimum_of_a_2d_quadratic():
    calls = []

    def f(v):
        calls.append(dict(v))
        return (v["x"] - 0.37) ** 2 + 3.0 * (v["y"] + 0.21) ** 2

    r = grid_narrow(f, {"x": (-1.0, 1.0), "y": (-1.0, 1.0)}, points=5, rounds=10)
    assert r.best["x"] == pytest.approx(0.37, abs=2e-3) and r.best["y"] == pytest.approx(-0.21, abs=2e-3)
    assert r.value == pytest.approx(f(r.best))
    assert r.evaluations == len(calls) - 1                                  # no point evaluated twice
    values = [rd["value"] for rd in r.rounds]
    assert all(b <= a for a, b in zip(values, values[1:])) and len(r.rounds) == 10
    widths = [rd["box"]["x"][1] - rd["box"]["x"][0] for rd in r.rounds]
    assert widths[1] == pytest.approx(widths[0] / 2) and widths[-1] < 0.01


def test_minimum_on_the_boundary_and_rejected_points():
    r = grid_narrow(lambda v: -v["x"], {"x": (0.0, 2.0)}, points=3, rounds=4)
    assert r.best["x"] == 2.0
    for rd in r.rounds:                                                     # boxes stay inside the bounds
        assert 0.0 <= rd["box"]["x"][0] < rd["box"]["x"][1] <= 2.0
    # nan and inf are rejections: the best point is the lowest finite one
    r = grid_narrow(lambda v: math.nan if v["x"] > 0.5 else (math.inf if v["x"] < 0.2 else v["x"]),
                    {"x": (0.0, 1.0)}, points=5, rounds=3)
    assert 0.2 <= r.best["x"] <= 0.5 and math.isfinite(r.value)


def test_progress_is_reported_per_node():
    seen = []
    grid_narrow(lambda v: v["x"] ** 2, {"x": (-1, 1)}, points=3, rounds=2, progress=lambda i, n: seen.append((i, n)))
    assert seen == [(1, 3), (2, 3), (3, 3)] * 2


@pytest.mark.parametrize("kw, match", [
    ({"points": 1}, "points: must be an integer >= 2"), ({"rounds": 0}, "rounds: must be an integer >= 1"),
    ({"shrink": 1.0}, "shrink: must be a number in"), ({"points": True}, "points"),
    ({"bounds": {"x": (1.0, 0.0)}}, "bounds: x needs finite lo < hi"), ({"bounds": {}}, "bounds: expected"),
    ({"bounds": {"x": 3}}, "bounds: x needs"),
])
def test_bad_arguments_name_the_argument(kw, match):
    args = {"bounds": {"x": (0.0, 1.0)}, **kw}
    bounds = args.pop("bounds")
    with pytest.raises(ValueError, match=match):
        grid_narrow(lambda v: 0.0, bounds, **args)
