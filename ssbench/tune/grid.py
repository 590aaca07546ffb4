"""Grid narrowing: a coarse grid over a box, then a smaller box around the best point, a few rounds.

This is the search XeGTAO's auto-tune uses for GTAO's settings, applied to every method: round ``k`` evaluates
the full ``points^d`` grid of the current box, keeps the best point, and shrinks the box by ``shrink`` around it
(shifted back inside the bounds). With an odd ``points`` the best point is a grid node of the next round, so the
best value never gets worse; points already evaluated are not evaluated again.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from typing import Callable, Mapping, Optional

import torch

__all__ = ["GridResult", "grid_narrow", "check_bounds"]


@dataclasses.dataclass(frozen=True)
class GridResult:
    """Outcome of :func:`grid_narrow`.

    Attributes:
        best: ``{name: value}`` of the lowest value found.
        value: ``f(best)``.
        evaluations: distinct points evaluated.
        rounds: per round ``{"box": {name: [lo, hi]}, "best": {...}, "value": float}``.
    """

    best: dict
    value: float
    evaluations: int
    rounds: list


def check_bounds(bounds: Mapping[str, tuple], arg: str = "bounds") -> dict[str, tuple[float, float]]:
    """``bounds`` as ``{name: (lo, hi)}`` floats with ``lo < hi`` finite; ``ValueError`` naming ``arg``."""
    if not isinstance(bounds, Mapping) or not bounds:
        raise ValueError(f"{arg}: expected a non-empty mapping name -> (lo, hi), got {bounds!r}")
    out = {}
    for k, b in bounds.items():
        try:
            lo, hi = (float(x) for x in b)
        except (TypeError, ValueError):
            raise ValueError(f"{arg}: {k} needs (lo, hi), got {b!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ValueError(f"{arg}: {k} needs finite lo < hi, got ({lo!r}, {hi!r})")
        out[str(k)] = (lo, hi)
    return out


def _axes(box: dict, points: int) -> list[list[float]]:
    return [torch.linspace(lo, hi, points, dtype=torch.float64).tolist() for lo, hi in box.values()]


def _shrunk(box: dict, best: dict, bounds: dict, shrink: float) -> dict:
    """The box ``shrink`` times as wide, centred on ``best`` and shifted to lie inside ``bounds``."""
    out = {}
    for k, (lo, hi) in box.items():
        half = 0.5 * (hi - lo) * shrink
        blo, bhi = bounds[k]
        a, b = best[k] - half, best[k] + half
        if a < blo:
            a, b = blo, blo + 2 * half
        if b > bhi:
            a, b = bhi - 2 * half, bhi
        out[k] = (max(a, blo), min(b, bhi))
    return out


def grid_narrow(f: Callable[[dict], float], bounds: Mapping[str, tuple], *, points: int = 5, rounds: int = 3,
                shrink: float = 0.5, progress: Optional[Callable[[int, int], None]] = None) -> GridResult:
    """Minimise ``f({name: value})`` over the box ``bounds`` by grid narrowing.

    Args:
        f: the objective; ``nan`` counts as ``+inf`` (a rejected point).
        bounds: ``{name: (lo, hi)}``.
        points: grid nodes per axis and round (>= 2; odd keeps the best point on the next grid).
        rounds: grids to evaluate (>= 1).
        shrink: box width factor per round, in (0, 1).
        progress: called as ``progress(done, total)`` after each evaluation of a round.

    Returns:
        :class:`GridResult`; ties keep the first point in grid order.

    Example:
        >>> r = grid_narrow(lambda v: (v["x"] - 0.3) ** 2, {"x": (0.0, 1.0)}, points=5, rounds=6)
        >>> r.best["x"], r.evaluations           # 5 nodes, then 2 new ones per round
        (0.296875, 15)
    """
    box = check_bounds(bounds)
    for name, v, ok in (("points", points, isinstance(points, int) and points >= 2),
                        ("rounds", rounds, isinstance(rounds, int) and rounds >= 1)):
        if isinstance(v, bool) or not ok:
            raise ValueError(f"{name}: must be an integer >= {2 if name == 'points' else 1}, got {v!r}")
    if isinstance(shrink, bool) or not isinstance(shrink, (int, float)) or not 0 < shrink < 1:
        raise ValueError(f"shrink: must be a number in (0, 1), got {shrink!r}")
    limits, names = dict(box), list(box)
    seen: dict[tuple, float] = {}
    best, best_v, log = None, math.inf, []
    for _ in range(rounds):
        grid = list(itertools.product(*_axes(box, points)))
        for i, node in enumerate(grid):
            key = tuple(round(x, 12) for x in node)
            if key not in seen:
                v = float(f(dict(zip(names, node))))
                seen[key] = math.inf if math.isnan(v) else v
            if seen[key] < best_v or best is None:
                best, best_v = dict(zip(names, node)), seen[key]
            if progress is not None:
                progress(i + 1, len(grid))
        log.append({"box": {k: list(b) for k, b in box.items()}, "best": dict(best), "value": best_v})
        box = _shrunk(box, best, limits, shrink)
    return GridResult(best, best_v, len(seen), log)
