"""Randomized interleaved timing of several passes (so drift in machine load hits every pass alike).

On a shared machine a pass's speed can switch between regimes every second or so (an SSR march at 160×120
between ~60 and ~100 ms per call, measured on the 2-core VM this was written on) and the gather floor follows
only in part. The rounds of a pass timed alone (:func:`ssbench.bench.timing.time_pass`, about
``2 · min_run_time`` long) then sit in one or two regimes: they are not independent, and two runs of one
configuration disagree by more than their IQR.

:func:`time_interleaved` times a group of passes together, as *randomized multiple interleaved trials* (Abedi &
Brecht, "Conducting repeatable experiments in highly variable cloud computing environments", ICPE 2017): after
each pass's warm-up (which also plans its rounds, :func:`~ssbench.bench.timing.plan_rounds`), round ``r`` runs
one round — a block of pass calls, then a block of floor calls — of every pass that still needs one, in an
order shuffled per round from ``order_seed``. Each pass's rounds spread over the whole group's timing (about
``2 · min_run_time`` per pass in the group), so its median and IQR take in the regimes the machine went
through. The fields are :func:`~ssbench.bench.timing.time_pass`'s.

A sweep times its configurations in groups of ``interleave`` (8 by default; ``0``: one at a time), each group one
task of the executor (:func:`ssbench.bench.sweep.run_group`). :func:`~ssbench.bench.timing.time_pass` is a
group of one: its rounds run back to back.
"""
from __future__ import annotations

import random
from typing import Any, Callable, Optional, Sequence

import torch

from . import timing as T

__all__ = ["interleaved_rounds", "summarize_rounds", "time_interleaved"]


def interleaved_rounds(items: Sequence[tuple[Any, int, int]], spec: T.TimingSpec, *, order_seed: int = 0,
                       timer: Callable[[Callable[[], Any], int], float] = T.timeit_calls
                       ) -> tuple[list[dict], list[Optional[list[list[float]]]]]:
    """The rounds of :func:`time_interleaved` before they are summarized: ``(rows, per_round)``.

    ``rows`` are the untimed rows of :func:`~ssbench.bench.timing.prepare` (``nan`` times; ``timing_error`` set
    for a pass with NaN/Inf output); ``per_round[i]`` is ``[pass seconds per call, floor seconds per call]``
    round by round (``[pass]`` without a floor), or ``None`` for a pass that was not timed.
    :mod:`ssbench.bench.processes` pools these lists over several processes.
    """
    prepared = [T.prepare(inputs, spec, threads, seed) for inputs, threads, seed in items]
    rows = [row for row, _ in prepared]
    live = [i for i, (_, calls) in enumerate(prepared) if calls is not None]
    plans: dict[int, tuple[int, list[int]]] = {}
    per_round: list[Optional[list[list[float]]]] = [None] * len(items)
    for i in live:
        per_round[i] = [[] for _ in prepared[i][1]]
    prev = torch.get_num_threads()
    try:
        with T.steady_heap():
            for i in live:
                torch.set_num_threads(items[i][1])
                best = T.warm_up(prepared[i][1], at_least=spec.warmup)
                plans[i] = T.plan_rounds(best, spec.min_run_time, spec.rounds)
            rng = random.Random(order_seed)
            for r in range(max((plans[i][0] for i in live), default=0)):
                order = [i for i in live if plans[i][0] > r]
                rng.shuffle(order)
                for i in order:
                    torch.set_num_threads(items[i][1])
                    got = T.run_rounds(prepared[i][1], plans[i][1], 1, timer)
                    for k, seconds in enumerate(got):
                        per_round[i][k] += seconds
    finally:
        torch.set_num_threads(prev)
    return rows, per_round


def time_interleaved(items: Sequence[tuple[Any, int, int]], spec: T.TimingSpec, *, order_seed: int = 0,
                     timer: Callable[[Callable[[], Any], int], float] = T.timeit_calls) -> list[dict]:
    """The timing fields of several passes timed in randomized interleaved rounds (see the module docstring).

    Args:
        items: ``(inputs, threads, seed)`` per pass: its :class:`~ssbench.bench.effects.BenchInputs`, torch
            threads while it runs, and the seed of its floor's texel indices.
        spec: the :class:`~ssbench.bench.timing.TimingSpec` (``min_run_time``, ``warmup``, ``floor``,
            ``rounds`` apply to each pass as in ``time_pass``).
        order_seed: seeds the per-round order (same seed, same order).
        timer: times one block (replaceable in tests).

    Returns:
        One dict of :data:`~ssbench.bench.timing.TIMING_FIELDS` per item, in order; a pass whose output has
        NaN/Inf on valid pixels is not timed (``timing_error`` says so).

    Example:
        >>> from ssbench.bench.effects import BenchInputs
        >>> z = -torch.rand(1, 1, 4, 6) - 1
        >>> inp = BenchInputs(lambda: z * 2, z, torch.ones_like(z, dtype=torch.bool), 3, z)
        >>> rows = time_interleaved([(inp, 1, 0), (inp, 1, 1)], T.TimingSpec(min_run_time=0.003, rounds=4))
        >>> [r["time_blocks"] for r in rows], all(r["floor_ratio"] > 0 for r in rows)
        ([4, 4], True)
    """
    return summarize_rounds(*interleaved_rounds(items, spec, order_seed=order_seed, timer=timer), processes=1)


def summarize_rounds(rows: list[dict], per_round: Sequence[Optional[list[list[float]]]], processes: int) -> list[dict]:
    """``rows`` with the :func:`~ssbench.bench.timing.round_fields` of each timed pass's rounds (``None``: not
    timed, left as it is) and ``timing_processes``, the number of processes the rounds came from."""
    for row, rounds in zip(rows, per_round):
        if rounds is not None:
            row.update(T.round_fields(rounds), timing_processes=processes)
    return rows
