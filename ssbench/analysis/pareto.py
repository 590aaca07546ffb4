"""Pareto fronts of sweep rows: the configurations no other one beats on both error and time.

A point ``a`` *dominates* ``b`` when ``err_a ≤ err_b`` and ``t_a ≤ t_b`` with at least one strict inequality.
The front is the set of points no point dominates; identical points do not dominate each other, so duplicates
are all on the front (ties are kept, never broken arbitrarily). Points with a NaN, infinite or missing
coordinate (and rows that carry an ``error``) take no part: they are neither on the front nor dominate.

:func:`pareto_mask` is the vectorised ``O(n log n)`` computation on arrays; :func:`pareto_rows` applies it to
sweep rows (:mod:`ssbench.bench.sweep`) with :func:`row_time_ms` as the time axis.
"""
from __future__ import annotations

import math
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

__all__ = ["pareto_mask", "dominates", "row_time_ms", "row_value", "pareto_rows", "usable"]


def pareto_mask(errors: Sequence[float], times: Sequence[float]) -> np.ndarray:
    """Which points are on the Pareto front of minimising both ``errors`` and ``times``.

    Args:
        errors, times: :math:`(n,)` numbers; NaN/±inf marks a point that takes no part.

    Returns:
        :math:`(n,)` bool.

    Example:
        >>> pareto_mask([3.0, 1.0, 2.0, 2.0, float("nan")], [1.0, 3.0, 2.0, 2.5, 0.1]).tolist()
        [True, True, True, False, False]
        >>> pareto_mask([1.0, 1.0], [2.0, 2.0]).tolist()          # duplicates: both on the front
        [True, True]
    """
    e = np.asarray(errors, dtype=float).reshape(-1)
    t = np.asarray(times, dtype=float).reshape(-1)
    if e.shape != t.shape:
        raise ValueError(f"errors, times: lengths differ ({e.size} vs {t.size})")
    out = np.zeros(e.size, dtype=bool)
    ok = np.flatnonzero(np.isfinite(e) & np.isfinite(t))
    if ok.size == 0:
        return out
    e_ok, t_ok = e[ok], t[ok]
    order = np.lexsort((e_ok, t_ok))                       # by time, then error
    ts, es = t_ok[order], e_ok[order]
    starts = np.flatnonzero(np.r_[True, ts[1:] != ts[:-1]])            # first index of each equal-time group
    group = np.cumsum(np.r_[True, ts[1:] != ts[:-1]]) - 1
    group_min = es[starts]                                  # sorted by error inside a group: its first
    before = np.r_[np.inf, np.minimum.accumulate(group_min)[:-1]]      # best error at strictly smaller time
    keep = (es == group_min[group]) & (es < before[group])
    out[ok[order[keep]]] = True
    return out


def dominates(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether ``a = (error, time)`` dominates ``b`` (the definition, for checks and brute force).

    Example:
        >>> dominates((1, 1), (1, 2)), dominates((1, 2), (1, 2)), dominates((0, 3), (1, 2))
        (True, False, False)
    """
    return a[0] <= b[0] and a[1] <= b[1] and (a[0] < b[0] or a[1] < b[1])


def _num(v: Any) -> float:
    if v is None or isinstance(v, bool) or isinstance(v, str):
        return math.nan
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def row_time_ms(row: Mapping) -> float:
    """Milliseconds per call of a sweep row's pass (NaN when unknown).

    ``time_median_ms`` (the ``timing:`` block's median over rounds) when finite, else the evaluation's own
    ``seconds_per_frame`` (implicit) or ``seconds``; plus ``blur_seconds`` (AO with a blur: the timed pass
    excludes the blur, the effect's cost includes it).

    Example:
        >>> row_time_ms({"time_median_ms": 2.0, "seconds": 9.0, "blur_seconds": 0.001})
        3.0
        >>> row_time_ms({"seconds_per_frame": 0.004}), math.isnan(row_time_ms({}))
        (4.0, True)
    """
    t = _num(row.get("time_median_ms"))
    if not math.isfinite(t):
        t = 1e3 * _num(row.get("seconds_per_frame", row.get("seconds")))
    blur = _num(row.get("blur_seconds"))
    return t + (1e3 * blur if math.isfinite(blur) else 0.0)


def row_value(row: Mapping, key: Union[str, Callable[[Mapping], Any]]) -> float:
    """``row[key]`` as a float (``key`` may be a function of the row); NaN when missing or not a number."""
    return _num(key(row) if callable(key) else row.get(key))


def usable(row: Mapping) -> bool:
    """A row without an ``error`` (a failing configuration is a row too, but has no numbers to plot)."""
    return not row.get("error")


def pareto_rows(rows: Iterable[Mapping], error: Union[str, Callable], time: Union[str, Callable] = row_time_ms,
                *, where: Optional[Callable[[Mapping], bool]] = None) -> tuple[list, np.ndarray]:
    """The rows on the front of ``error`` vs ``time`` (sorted by time), and the mask over ``rows``.

    Args:
        rows: sweep rows (dicts).
        error, time: a row key or a function of the row (default time: :func:`row_time_ms`).
        where: only rows for which this is true take part (e.g. one scene); error rows never do.

    Example:
        >>> rows = [{"e": 1.0, "t": 5.0}, {"e": 2.0, "t": 1.0}, {"e": 3.0, "t": 4.0}, {"e": 0.5, "error": "X"}]
        >>> front, mask = pareto_rows(rows, "e", "t")
        >>> [r["t"] for r in front], mask.tolist()
        ([1.0, 5.0], [True, True, False, False])
    """
    rows = list(rows)
    take = [usable(r) and (where is None or where(r)) for r in rows]
    e = np.array([row_value(r, error) if k else math.nan for r, k in zip(rows, take)], dtype=float)
    t = np.array([row_value(r, time) if k else math.nan for r, k in zip(rows, take)], dtype=float)
    mask = pareto_mask(e, t)
    idx = sorted(np.flatnonzero(mask), key=lambda i: (t[i], e[i]))
    return [rows[i] for i in idx], mask
