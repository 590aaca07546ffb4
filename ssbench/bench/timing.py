"""Timing that can be trusted: blocked autorange, median and IQR, and the *gather floor* measured beside it.

:func:`time_pass` checks the pass output first (no NaN/Inf on valid pixels; otherwise nothing is timed and
``timing_error`` says why), warms the pass up, then times it with ``torch.utils.benchmark`` (blocked
autorange: median and interquartile range of per-block times) at a fixed thread count, and in the same run
times the **gather floor**: a pure gather (:func:`ssbench.passes.common.fetch`) of as many depth texels per
pixel as the pass reads. ``floor_ratio = time / floor`` survives a noisy machine better than the time itself.

Fields it returns (:data:`TIMING_FIELDS`): ``time_median_ms, time_iqr_ms, time_blocks, floor_median_ms,
floor_iqr_ms, floor_samples, floor_ratio, floor_ratio_iqr, threads, timing_min_run_time, timing_error``.

Claims about speed belong in ``benchmarks/`` (e.g. ``benchmarks/bench_sweep_timing.py``), never in unit tests.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable, Mapping, Optional

import torch
import torch.utils.benchmark as tb

__all__ = ["TimingSpec", "Stats", "measure", "gather_floor", "nonfinite_on_valid", "time_pass", "agree",
           "TIMING_FIELDS"]

TIMING_FIELDS = ("time_median_ms", "time_iqr_ms", "time_blocks", "floor_median_ms", "floor_iqr_ms",
                 "floor_samples", "floor_ratio", "floor_ratio_iqr", "threads", "timing_min_run_time",
                 "timing_error")


@dataclasses.dataclass(frozen=True)
class TimingSpec:
    """The ``timing:`` block of a sweep file.

    Attributes:
        min_run_time: seconds of blocked autorange per measurement (the pass and its floor each).
        warmup: untimed calls before timing (the evaluation already ran the pass once).
        floor: also time the gather floor (``False``: floor fields are ``nan``).
    """

    min_run_time: float = 0.2
    warmup: int = 1
    floor: bool = True

    def __post_init__(self) -> None:
        if isinstance(self.min_run_time, bool) or not isinstance(self.min_run_time, (int, float)) \
                or not self.min_run_time > 0 or not math.isfinite(self.min_run_time):
            raise ValueError(f"min_run_time: must be a number > 0, got {self.min_run_time!r}")
        if isinstance(self.warmup, bool) or not isinstance(self.warmup, int) or self.warmup < 0:
            raise ValueError(f"warmup: must be an integer >= 0, got {self.warmup!r}")
        if not isinstance(self.floor, bool):
            raise ValueError(f"floor: expected true or false, got {self.floor!r}")


@dataclasses.dataclass(frozen=True)
class Stats:
    """Median and IQR (seconds per call) of a blocked-autorange measurement, and its number of blocks."""

    median: float
    iqr: float
    blocks: int


def measure(call: Callable[[], Any], *, min_run_time: float, threads: int, warmup: int = 1) -> Stats:
    """Time ``call()`` with ``torch.utils.benchmark.Timer.blocked_autorange`` at ``threads`` torch threads,
    after ``warmup`` untimed calls."""
    prev = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        for _ in range(warmup):
            call()
        m = tb.Timer("call()", globals={"call": call}, num_threads=threads).blocked_autorange(
            min_run_time=min_run_time)
    finally:
        torch.set_num_threads(prev)
    return Stats(float(m.median), float(m.iqr), len(m.times))


def floor_indices(texture: torch.Tensor, samples: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Random ``(col, row)`` of shape :math:`(B, samples, H, W)`: ``samples`` texels per pixel of ``texture``.

    Example:
        >>> col, row = floor_indices(torch.zeros(1, 1, 4, 6), 3)
        >>> tuple(col.shape), int(col.max()) < 6, int(row.max()) < 4
        ((1, 3, 4, 6), True, True)
    """
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ValueError(f"samples: must be an integer >= 1, got {samples!r}")
    B, _, H, W = texture.shape
    gen = torch.Generator().manual_seed(seed)
    col = torch.randint(0, W, (B, samples, H, W), generator=gen).to(texture.device)
    row = torch.randint(0, H, (B, samples, H, W), generator=gen).to(texture.device)
    return col, row


def gather_floor(texture: torch.Tensor, samples: int, *, min_run_time: float, threads: int,
                 seed: int = 0) -> Stats:
    """Time a pure gather of ``samples`` texels per pixel of ``texture`` (indices drawn outside the timing)."""
    from ..passes.common import fetch
    col, row = floor_indices(texture, samples, seed)
    return measure(lambda: fetch(texture, col, row), min_run_time=min_run_time, threads=threads, warmup=1)


def nonfinite_on_valid(output: torch.Tensor, valid: torch.Tensor) -> int:
    """NaN/Inf values of ``output`` :math:`(B, C, H, W)` on the pixels where ``valid`` :math:`(B, 1, H, W)`.

    Example:
        >>> out = torch.tensor([[[[1.0, float("nan")], [float("inf"), 0.0]]]])
        >>> nonfinite_on_valid(out, torch.tensor([[[[True, False], [True, True]]]]))
        1
    """
    bad = ~torch.isfinite(output.float())
    return int((bad & valid.bool().expand_as(bad)).sum())


def _ratio_iqr(t: Stats, f: Stats) -> float:
    """IQR of ``t/f`` propagated from the relative IQRs (first order)."""
    return (t.median / f.median) * math.hypot(t.iqr / t.median, f.iqr / f.median)


def time_pass(inputs, spec: TimingSpec, threads: int, seed: int = 0) -> dict:
    """The timing fields (:data:`TIMING_FIELDS`) of a pass given its :class:`~ssbench.bench.effects.BenchInputs`.

    The output is checked first; with NaN/Inf on valid pixels nothing is timed, the numbers are ``nan`` and
    ``timing_error`` names the count. Times are in milliseconds per call.
    """
    nan = math.nan
    row = {"time_median_ms": nan, "time_iqr_ms": nan, "time_blocks": 0, "floor_median_ms": nan,
           "floor_iqr_ms": nan, "floor_samples": int(inputs.samples), "floor_ratio": nan, "floor_ratio_iqr": nan,
           "threads": int(threads), "timing_min_run_time": float(spec.min_run_time), "timing_error": None}
    bad = nonfinite_on_valid(inputs.output, inputs.valid)
    if bad:
        row["timing_error"] = f"output has {bad} NaN/Inf values on valid pixels; not timed"
        return row
    t = measure(inputs.call, min_run_time=spec.min_run_time, threads=threads, warmup=spec.warmup)
    row.update(time_median_ms=t.median * 1e3, time_iqr_ms=t.iqr * 1e3, time_blocks=t.blocks)
    if spec.floor:
        f = gather_floor(inputs.texture, int(inputs.samples), min_run_time=spec.min_run_time, threads=threads,
                         seed=seed)
        row.update(floor_median_ms=f.median * 1e3, floor_iqr_ms=f.iqr * 1e3, floor_ratio=t.median / f.median,
                   floor_ratio_iqr=_ratio_iqr(t, f))
    return row


def agree(a: Mapping, b: Mapping, *, field: str = "floor_ratio", k: float = 1.0, rel: float = 0.0) -> bool:
    """Whether two timing rows agree on ``field`` within their spread.

    ``field`` is ``"floor_ratio"`` (spread ``floor_ratio_iqr``) or ``"time"`` (``time_median_ms`` with
    ``time_iqr_ms``). They agree when ``|a - b| <= k · max(iqr_a, iqr_b) + rel · max(a, b)``: ``k = 1, rel = 0``
    is "within the IQR"; ``rel`` adds a relative allowance for loaded machines. ``nan`` never agrees.

    Example:
        >>> a = {"floor_ratio": 10.0, "floor_ratio_iqr": 1.0}
        >>> agree(a, {"floor_ratio": 10.8, "floor_ratio_iqr": 0.5}), agree(a, {"floor_ratio": 12.0,
        ...                                                                     "floor_ratio_iqr": 0.5})
        (True, False)
    """
    keys = {"floor_ratio": ("floor_ratio", "floor_ratio_iqr"), "time": ("time_median_ms", "time_iqr_ms")}
    if field not in keys:
        raise ValueError(f"field: expected 'floor_ratio' or 'time', got {field!r}")
    m, q = keys[field]
    va, vb, qa, qb = (float(x[key]) for x, key in ((a, m), (b, m), (a, q), (b, q)))
    if any(math.isnan(v) for v in (va, vb, qa, qb)):
        return False
    return abs(va - vb) <= k * max(qa, qb) + rel * max(abs(va), abs(vb))


def timing_summary(rows, field: str = "floor_ratio") -> Optional[dict]:
    """Median and spread of ``field`` over timing rows (``None`` without any), for benchmark printouts."""
    vals = sorted(float(r[field]) for r in rows if field in r and not math.isnan(float(r[field])))
    if not vals:
        return None
    q = lambda p: vals[min(len(vals) - 1, int(round(p * (len(vals) - 1))))]      # noqa: E731
    return {"n": len(vals), "median": q(0.5), "iqr": q(0.75) - q(0.25), "min": vals[0], "max": vals[-1]}
