"""Randomized interleaved timing: every pass gets its rounds, each round visits every pass once in a seeded
shuffled order, pass and floor back to back; sweeps with ``interleave: N`` give the rows of plain timing."""
import math

import pytest
import torch

from ssbench.bench import canonical_json, run_sweep
from ssbench.bench import effects as E
from ssbench.bench import timing as T
from ssbench.bench.interleave import time_interleaved

from .test_sweep import _toy


def _inputs(scale, output=None):
    z = -torch.rand(1, 1, 6, 8) - 1
    call = lambda: z * scale                                          # noqa: E731
    return E.BenchInputs(call, z if output is None else output, torch.ones(1, 1, 6, 8, dtype=torch.bool), 4, z)


def _recording_timer(inputs, ms):
    """A fake block timer: pass ``i`` takes ``ms[i]`` ms a call, its floor 1 ms; returns the call log."""
    log = []

    def timer(call, number):
        owner = next((i for i, x in enumerate(inputs) if call is x.call), None)
        log.append(("p", owner) if owner is not None else ("f", log[-1][1]))
        return number * (ms[owner] if owner is not None else 1.0) * 1e-3
    return timer, log


def test_each_round_visits_every_pass_once_in_a_seeded_shuffled_order():
    inputs = [_inputs(k + 1) for k in range(4)]
    timer, log = _recording_timer(inputs, [2.0, 3.0, 4.0, 5.0])
    rows = time_interleaved([(x, 1, 0) for x in inputs], T.TimingSpec(min_run_time=0.05, fused_floor=False, rounds=6), timer=timer)
    assert [r["time_blocks"] for r in rows] == [6] * 4
    assert all(a[0] == "p" and b == ("f", a[1]) for a, b in zip(log[::2], log[1::2]))   # floor after its pass
    orders = [[e[1] for e in log[2 * 4 * r:2 * 4 * (r + 1):2]] for r in range(6)]
    assert all(sorted(o) == [0, 1, 2, 3] for o in orders) and len({tuple(o) for o in orders}) > 1
    for i, r in enumerate(rows):                                       # constant fake times: exact fields
        assert r["time_median_ms"] == pytest.approx(2.0 + i) and r["floor_ratio"] == pytest.approx(2.0 + i)
        assert r["time_iqr_ms"] == pytest.approx(0) and r["timing_error"] is None
    timer2, log2 = _recording_timer(inputs, [2.0, 3.0, 4.0, 5.0])
    time_interleaved([(x, 1, 0) for x in inputs], T.TimingSpec(min_run_time=0.05, fused_floor=False, rounds=6), timer=timer2)
    assert log2 == log                                                  # same order seed, same order
    timer3, log3 = _recording_timer(inputs, [2.0, 3.0, 4.0, 5.0])
    time_interleaved([(x, 1, 0) for x in inputs], T.TimingSpec(min_run_time=0.05, fused_floor=False, rounds=6), order_seed=7,
                     timer=timer3)
    assert log3 != log and sorted(log3) == sorted(log)


def test_a_nonfinite_pass_is_not_timed_and_the_others_are():
    bad = torch.zeros(1, 1, 6, 8)
    bad[0, 0, 1, 1] = float("nan")
    inputs = [_inputs(1.0), _inputs(2.0, output=bad)]
    timer, log = _recording_timer(inputs, [2.0, 3.0])
    rows = time_interleaved([(x, 1, 0) for x in inputs], T.TimingSpec(min_run_time=0.05, fused_floor=False, rounds=3), timer=timer)
    assert rows[0]["time_blocks"] == 3 and rows[0]["timing_error"] is None
    assert "1 NaN/Inf" in rows[1]["timing_error"] and math.isnan(rows[1]["time_median_ms"])
    assert rows[0]["timing_processes"] == 1 and rows[1]["timing_processes"] == 0
    assert {e[1] for e in log} == {0}


def test_slow_passes_get_their_planned_rounds_and_threads_are_restored():
    before = torch.get_num_threads()
    inputs = [_inputs(1.0), _inputs(2.0)]
    timer, _ = _recording_timer(inputs, [1.0, 1.0])
    rows = time_interleaved([(inputs[0], 1, 0), (inputs[1], 2, 0)], T.TimingSpec(min_run_time=0.01, rounds=3),
                            timer=timer)
    assert [r["threads"] for r in rows] == [1, 2] and torch.get_num_threads() == before


def test_a_sweep_with_interleave_gives_the_rows_of_plain_timing(toy, tmp_path):
    plain = run_sweep(_toy(timing={"min_run_time": 0.01, "interleave": 0, "processes": 1}), tmp_path / "plain", progress=False)
    inter = run_sweep(_toy(timing={"min_run_time": 0.01, "interleave": 5, "processes": 1}), tmp_path / "inter", progress=False)
    assert [canonical_json(r) for r in inter.rows] == [canonical_json(r) for r in plain.rows]
    assert inter.ran == 12 and inter.errors == 4
    for r in inter.rows:
        if r["error"]:
            assert math.isnan(r["floor_ratio"]) and r["timing_error"].startswith("not timed")
        else:
            assert r["floor_ratio"] > 0 and r["time_blocks"] >= 3 and r["timing_error"] is None
    again = run_sweep(_toy(timing={"min_run_time": 0.01, "interleave": 5, "processes": 1}), tmp_path / "inter", progress=False)
    assert again.ran == 0 and again.skipped == 12                      # resumable like any sweep


@pytest.mark.parametrize("bad", [1, -1, 2.5, True])
def test_interleave_must_be_off_or_a_group_size(bad):
    assert T.TimingSpec().interleave == 8 and T.TimingSpec(interleave=0).interleave == 0
    with pytest.raises(ValueError, match="^interleave:"):
        T.TimingSpec(interleave=bad)
