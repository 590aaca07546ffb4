"""Timing that can be trusted: interleaved rounds of the pass and its *gather floor*, median and IQR.

:func:`time_pass` checks the pass output first (no NaN/Inf on valid pixels; otherwise nothing is timed and
``timing_error`` says why), then times the pass beside its **gather floors** (:mod:`ssbench.bench.floors`: a
torch gather of as many depth texels per pixel as the pass reads, and the same reads fused into one Dr.Jit
kernel when Dr.Jit has an LLVM backend) at a fixed torch thread count:

1. inside :func:`~ssbench.bench.heap.steady_heap`: otherwise glibc's malloc page-faults a pass's temporaries on every call or not,
   depending on what the process ran before — by far the largest gap between two runs (up to 4x);
2. after ``warmup`` untimed calls of each (at least one: it sizes the blocks);
3. in ``rounds`` rounds, each a block of pass calls then a block of floor calls (about ``min_run_time /
   rounds`` seconds each, one call at least). ``floor_ratio`` is the median of the per-round ratios and
   ``floor_ratio_iqr`` their IQR: the spread includes the machine's drift during the run, and the ratio
   cancels what the pass and the floor share (a slow or busy machine).

Cost: about ``2 * min_run_time`` plus the warm-up; a pass slower than a block gets the rounds that budget pays
for, but at least :data:`MIN_ROUNDS` (or ``rounds`` if fewer); ``time_blocks`` is the number run. Why many
rounds: with identically distributed rounds, the medians of two runs of n rounds differ by less than the
larger of their IQRs with probability ~86 % (n = 5), ~96 % (9), ~99 % (15); the two blocks a blocked
autorange gives a pass slower than ``min_run_time / 2`` give ~54 %. Measured agreement on a shared machine
is lower: there a pass's speed can switch between regimes every second or so (an SSR march at 160×120 between
~60 and ~100 ms per call) that the floor follows only in part, so the rounds of one run are not independent,
and a process's memory layout shifts all of its rounds alike. Sweeps therefore time configurations in
interleaved groups (:mod:`ssbench.bench.interleave`) and pool the rounds of several processes
(:mod:`ssbench.bench.processes`). See ``benchmarks/bench_sweep_timing.py`` and
``benchmarks/bench_sweep_repeats.py``, where claims about speed belong.

Fields it returns (:data:`TIMING_FIELDS`): ``time_median_ms, time_iqr_ms, time_blocks, floor_median_ms,
floor_iqr_ms, floor_samples, floor_ratio, floor_ratio_iqr, fused_floor_median_ms, fused_floor_ratio,
fused_floor_ratio_iqr, threads, timing_min_run_time, timing_processes, timing_error``. The fused fields are
``nan`` without an LLVM backend or with ``fused_floor: false``; ``timing_processes`` is how many processes' rounds
were pooled (:mod:`ssbench.bench.processes`).
"""
from __future__ import annotations

import dataclasses
import math
import time
import timeit
from typing import Any, Callable, Mapping, Optional, Sequence

import numpy as np
import torch

from .heap import steady_heap

__all__ = ["TimingSpec", "TimingSpecError", "nonfinite_on_valid", "median_iqr", "steady_heap", "sync_device",
           "timeit_calls", "warm_up", "plan_rounds", "run_rounds", "round_fields", "prepare", "time_pass", "agree",
           "TIMING_FIELDS", "MIN_ROUNDS"]

TIMING_FIELDS = ("time_median_ms", "time_iqr_ms", "time_blocks", "floor_median_ms", "floor_iqr_ms",
                 "floor_samples", "floor_ratio", "floor_ratio_iqr", "fused_floor_median_ms", "fused_floor_ratio",
                 "fused_floor_ratio_iqr", "threads", "timing_min_run_time",
                 "timing_processes", "timing_error")

#: fewest rounds a slow pass is cut to: with 9 identically distributed rounds the medians of two runs fall within
#: the larger IQR ~96 % of the time (5 rounds: ~86 %, measured 53-73 % for slow SSR marchers across processes)
MIN_ROUNDS = 9


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


class TimingSpecError(ValueError):
    """A bad :class:`TimingSpec` field: ``field`` names it, ``reason`` says why; the message is ``"field: reason"``."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field, self.reason = field, reason


@dataclasses.dataclass(frozen=True)
class TimingSpec:
    """The ``timing:`` block of a sweep file.

    Attributes:
        min_run_time: seconds of timed calls per measurement (the pass and its floor each), spread over the
            rounds; a slow pass may take longer (see the module docstring).
        warmup: untimed calls of the pass and the floor before timing (at least one is always made).
        floor: also time the torch gather floor (``False``: floor fields are ``nan``, and no fused floor).
        fused_floor: also time the fused (Dr.Jit) floor when this machine has one (``False``: its fields are
            ``nan``).
        rounds: interleaved rounds of pass and floor blocks (median and IQR over them), at least 3.
        interleave: ``N >= 2`` (default 8): a sweep times its configurations in groups of ``N``, in randomized
            interleaved rounds (:mod:`ssbench.bench.interleave`), so that each one's rounds spread over the whole
            group (repeated runs agree far better on a shared machine); ``0``: time each configuration alone,
            right after its evaluation, and write its row at once.
        processes: ``N >= 2`` (default 3): time each group again in ``N - 1`` fresh Python processes, one after
            another, and pool the rounds of all ``N`` (:mod:`ssbench.bench.processes`): a process's memory
            layout and the machine's state while it runs shift all of its rounds alike, which no number of
            rounds in one process samples; pooling makes the median and IQR take it in, so that repeated runs
            agree within the IQR. Costs ``N`` times the timing plus one evaluation of the group per extra
            process. ``1``: time in this process only (quicker; needed for effects or methods registered at
            run time, which a fresh process does not see).
    """

    min_run_time: float = 0.2
    warmup: int = 1
    floor: bool = True
    fused_floor: bool = True
    rounds: int = 15
    interleave: int = 8
    processes: int = 3

    def __post_init__(self) -> None:
        if isinstance(self.min_run_time, bool) or not isinstance(self.min_run_time, (int, float)) \
                or not self.min_run_time > 0 or not math.isfinite(self.min_run_time):
            raise TimingSpecError("min_run_time", f"must be a number > 0, got {self.min_run_time!r}")
        if not _is_int(self.warmup) or self.warmup < 0:
            raise TimingSpecError("warmup", f"must be an integer >= 0, got {self.warmup!r}")
        for name in ("floor", "fused_floor"):
            if not isinstance(getattr(self, name), bool):
                raise TimingSpecError(name, f"expected true or false, got {getattr(self, name)!r}")
        if not _is_int(self.rounds) or self.rounds < 3:
            raise TimingSpecError("rounds", f"must be an integer >= 3, got {self.rounds!r}")
        if not _is_int(self.interleave) or self.interleave < 0 or self.interleave == 1:
            raise TimingSpecError("interleave", f"must be 0 (off) or an integer >= 2, got {self.interleave!r}")
        if not _is_int(self.processes) or self.processes < 1:
            raise TimingSpecError("processes", f"must be an integer >= 1, got {self.processes!r}")


def nonfinite_on_valid(output: torch.Tensor, valid: torch.Tensor) -> int:
    """NaN/Inf values of ``output`` :math:`(B, C, H, W)` on the pixels where ``valid`` :math:`(B, 1, H, W)`.

    Example:
        >>> out = torch.tensor([[[[1.0, float("nan")], [float("inf"), 0.0]]]])
        >>> nonfinite_on_valid(out, torch.tensor([[[[True, False], [True, True]]]]))
        1
    """
    bad = ~torch.isfinite(output.float())
    return int((bad & valid.bool().expand_as(bad)).sum())


def median_iqr(values: Sequence[float]) -> tuple[float, float]:
    """Median and interquartile range of ``values`` (``numpy.quantile``, linear interpolation, as
    ``torch.utils.benchmark`` does).

    Example:
        >>> median_iqr([4.0, 1.0, 3.0, 2.0, 5.0])
        (3.0, 2.0)
    """
    if len(values) == 0:
        raise ValueError("values: expected at least one value, got none")
    q1, q2, q3 = np.quantile(np.asarray(values, dtype=np.float64), [0.25, 0.5, 0.75])
    return float(q2), float(q3 - q1)


def sync_device() -> None:
    """Wait for queued CUDA work (a no-op unless CUDA is in use): kernels launch asynchronously, so a timed
    block that does not end with this measures the launches, not the work."""
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        torch.cuda.synchronize()


def timeit_calls(call: Callable[[], Any], number: int) -> float:
    """Seconds taken by ``number`` calls of ``call`` (:class:`timeit.Timer`: garbage collection off), the device
    synchronised before the block starts and inside it after the last call (:func:`sync_device`)."""
    def block() -> None:
        for _ in range(number):
            call()
        sync_device()

    sync_device()
    return timeit.Timer(block, timer=time.perf_counter).timeit(1)


def warm_up(calls: Sequence[Callable[[], Any]], seconds: float = 0.0, *, at_least: int = 1,
            clock: Callable[[], float] = time.perf_counter) -> list[float]:
    """Call each of ``calls`` in turn, again and again, until ``seconds`` have passed and each ran at least
    ``at_least`` times (at least once); return each call's fastest duration (what :func:`plan_rounds` needs)."""
    best = [math.inf] * len(calls)
    start, n = clock(), 0
    while n < max(1, at_least) or clock() - start < seconds:
        for i, call in enumerate(calls):
            sync_device()
            t0 = clock()
            call()
            sync_device()
            best[i] = min(best[i], clock() - t0)
        n += 1
    return best


def plan_rounds(seconds: Sequence[float], min_run_time: float, rounds: int) -> tuple[int, list[int]]:
    """Rounds to run and calls per block for calls taking ``seconds`` each.

    Blocks last about ``min_run_time / rounds`` (one call at least). When that makes the rounds cost more than
    ``len(seconds) * min_run_time`` (a slow pass), they are cut to what that pays for, but not below
    :data:`MIN_ROUNDS` (nor ``rounds``).

    Example:
        >>> plan_rounds([0.001, 0.0001], min_run_time=0.2, rounds=10)     # fast calls: 20 ms blocks
        (10, [20, 200])
        >>> plan_rounds([0.05, 0.001], min_run_time=0.5, rounds=15)       # 50 ms a pass: 15 rounds cost 1.25 s
        (12, [1, 33])
        >>> plan_rounds([1.0, 0.001], min_run_time=0.5, rounds=15)        # 1 s a pass: never below MIN_ROUNDS
        (9, [1, 33])
    """
    block = min_run_time / rounds
    numbers = [max(1, int(block / max(t, 1e-12))) for t in seconds]
    per_round = sum(n * t for n, t in zip(numbers, seconds))
    fit = int(len(seconds) * min_run_time / per_round + 1e-9) if per_round > 0 else rounds
    return max(min(rounds, MIN_ROUNDS), min(rounds, fit)), numbers


def run_rounds(calls: Sequence[Callable[[], Any]], numbers: Sequence[int], rounds: int,
               timer: Callable[[Callable[[], Any], int], float] = timeit_calls) -> list[list[float]]:
    """``rounds`` rounds, each timing every call back to back (``numbers[i]`` calls of ``calls[i]`` as one
    block, ``timer(call, number)`` seconds); returns, per call, its seconds per call in each round."""
    out: list[list[float]] = [[] for _ in calls]
    for _ in range(rounds):
        for i, (call, n) in enumerate(zip(calls, numbers)):
            out[i].append(timer(call, n) / n)
    return out


def round_fields(per_round: Sequence[Sequence[float]]) -> dict:
    """The time (and, given a second list, floor; a third, fused floor) fields of per-round seconds per call
    ``[pass, floor, fused]``: medians and IQRs in ms, ``floor_ratio`` and ``floor_ratio_iqr`` the median and IQR
    of per-round ratios (``fused_floor_ratio`` likewise).

    Example:
        >>> f = round_fields([[0.010, 0.012, 0.011], [0.002, 0.002, 0.001]])
        >>> f["time_median_ms"], f["time_blocks"], f["floor_ratio"], f["floor_ratio_iqr"]
        (11.0, 3, 6.0, 3.0)
    """
    tm, ti = median_iqr(per_round[0])
    out = {"time_median_ms": tm * 1e3, "time_iqr_ms": ti * 1e3, "time_blocks": len(per_round[0])}
    if len(per_round) > 1:
        fm, fi = median_iqr(per_round[1])
        rm, ri = median_iqr([p / f for p, f in zip(per_round[0], per_round[1])])
        out.update(floor_median_ms=fm * 1e3, floor_iqr_ms=fi * 1e3, floor_ratio=rm, floor_ratio_iqr=ri)
    if len(per_round) > 2:
        fm, _ = median_iqr(per_round[2])
        rm, ri = median_iqr([p / f for p, f in zip(per_round[0], per_round[2])])
        out.update(fused_floor_median_ms=fm * 1e3, fused_floor_ratio=rm, fused_floor_ratio_iqr=ri)
    return out


def prepare(inputs, spec: TimingSpec, threads: int, seed: int = 0) -> tuple[dict, Optional[list]]:
    """The row of an untimed pass (``nan`` times) and the calls to time, ``[pass, floor]`` (``[pass]`` without a
    floor); the calls are ``None`` when the output has NaN/Inf on valid pixels (``timing_error`` says so)."""
    nan = math.nan
    row = {"time_median_ms": nan, "time_iqr_ms": nan, "time_blocks": 0, "floor_median_ms": nan,
           "floor_iqr_ms": nan, "floor_samples": int(inputs.samples), "floor_ratio": nan, "floor_ratio_iqr": nan,
           "fused_floor_median_ms": nan, "fused_floor_ratio": nan, "fused_floor_ratio_iqr": nan,
           "threads": int(threads), "timing_min_run_time": float(spec.min_run_time), "timing_processes": 0,
           "timing_error": None}
    bad = nonfinite_on_valid(inputs.output, inputs.valid)
    if bad:
        row["timing_error"] = f"output has {bad} NaN/Inf values on valid pixels; not timed"
        return row, None
    calls = [inputs.call]
    if spec.floor:
        from .floors import fused_floor, torch_floor
        calls.append(torch_floor(inputs.texture, int(inputs.samples), seed))
        fused = fused_floor(inputs.texture, int(inputs.samples), seed) if spec.fused_floor else None
        if fused is not None:
            calls.append(fused)
    return row, calls


def time_pass(inputs, spec: TimingSpec, threads: int, seed: int = 0, *,
              timer: Callable[[Callable[[], Any], int], float] = timeit_calls) -> dict:
    """The timing fields (:data:`TIMING_FIELDS`) of a pass given its :class:`~ssbench.bench.effects.BenchInputs`
    (the protocol is the module docstring's; ``timer`` times one block, replaceable in tests).

    The output is checked first; with NaN/Inf on valid pixels nothing is timed, the numbers are ``nan`` and
    ``timing_error`` names the count. Times are in milliseconds per call.
    """
    from .interleave import time_interleaved              # a group of one: its rounds back to back
    return time_interleaved([(inputs, threads, seed)], spec, timer=timer)[0]


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
