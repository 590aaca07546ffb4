"""Timing structure and the gather floor's sample count (no claims about speed: see benchmarks/)."""
import dataclasses
import math
import types

import pytest
import torch

from ssbench.bench import effects as E
from ssbench.bench import timing as T


def _inputs(samples=5, output=None):
    z = -torch.rand(1, 1, 6, 8) - 1
    out = z if output is None else output
    return E.BenchInputs(lambda: z * 2, out, torch.ones(1, 1, 6, 8, dtype=torch.bool), samples, z)


def test_time_pass_fields_and_the_floors_gather_the_pass_sample_count(monkeypatch):
    from ssbench.bench import floors as F
    seen = []
    real_torch, real_fused = F.torch_floor, F.fused_floor

    def spy(name, real):
        def f(texture, samples, *a):
            seen.append((name, tuple(texture.shape), samples))
            return real(texture, samples, *a)
        return f
    monkeypatch.setattr(F, "torch_floor", spy("torch", real_torch))
    monkeypatch.setattr(F, "fused_floor", spy("fused", real_fused))
    row = T.time_pass(_inputs(samples=7), T.TimingSpec(min_run_time=0.01, warmup=0), threads=1)
    assert set(row) == set(T.TIMING_FIELDS)
    assert seen == [("torch", (1, 1, 6, 8), 7), ("fused", (1, 1, 6, 8), 7)] and row["floor_samples"] == 7
    assert row["time_median_ms"] > 0 and row["floor_median_ms"] > 0
    # fast calls run every round; a loaded machine can make the warm-up slow enough to cut them (plan_rounds)
    assert min(T.MIN_ROUNDS, T.TimingSpec().rounds) <= row["time_blocks"] <= T.TimingSpec().rounds
    assert row["floor_ratio"] > 0 and row["floor_ratio_iqr"] >= 0
    fused = real_fused(_inputs().texture, 7)
    if fused is None:                                                   # no LLVM backend here: nan, not 0
        assert math.isnan(row["fused_floor_ratio"]) and math.isnan(row["fused_floor_median_ms"])
    else:
        assert row["fused_floor_ratio"] > 0 and row["fused_floor_median_ms"] > 0
    assert row["threads"] == 1 and row["timing_error"] is None
    off = T.time_pass(_inputs(samples=7), T.TimingSpec(min_run_time=0.01, warmup=0, fused_floor=False), threads=1)
    assert math.isnan(off["fused_floor_ratio"]) and off["floor_ratio"] > 0 and len(seen) == 3


def test_the_fused_floor_ratio_is_the_median_of_per_round_ratios(monkeypatch):
    from ssbench.bench import floors as F
    inputs = _inputs()
    fused = lambda: None                                                # noqa: E731  (an injected third call)
    monkeypatch.setattr(F, "fused_floor", lambda *a: fused)
    ms = {"p": [10, 12, 11], "f": [2, 2, 1], "u": [1, 4, 1]}            # fused ratios 10, 3, 11
    seen = []

    def timer(call, number):
        key = "p" if call is inputs.call else "u" if call is fused else "f"
        seen.append(key)
        return number * ms[key][seen.count(key) - 1] * 1e-3
    row = T.time_pass(inputs, T.TimingSpec(min_run_time=0.05, warmup=0, rounds=3), threads=1, timer=timer)
    assert seen == ["p", "f", "u"] * 3
    assert row["fused_floor_median_ms"] == pytest.approx(1) and row["fused_floor_ratio"] == pytest.approx(10)
    assert row["fused_floor_ratio_iqr"] == pytest.approx(4) and row["floor_ratio"] == pytest.approx(6)


def test_time_pass_takes_median_and_iqr_of_interleaved_per_round_ratios():
    inputs = _inputs()
    pass_ms, floor_ms = [10, 12, 11, 30, 10], [2, 2, 1, 3, 2]           # ratios 5, 6, 11, 10, 5
    seen = []

    def timer(call, number):                                           # an injected clock: no real timing
        is_pass = call is inputs.call
        seen.append("p" if is_pass else "f")
        ms = (pass_ms if is_pass else floor_ms)[seen.count(seen[-1]) - 1]
        return number * ms * 1e-3
    row = T.time_pass(inputs, T.TimingSpec(min_run_time=0.05, warmup=0, rounds=5, fused_floor=False), threads=1,
                      timer=timer)
    assert seen == ["p", "f"] * 5                                      # pass and floor back to back, 5 rounds
    assert row["time_blocks"] == 5
    assert row["time_median_ms"] == pytest.approx(11) and row["time_iqr_ms"] == pytest.approx(2)
    assert row["floor_median_ms"] == pytest.approx(2) and row["floor_iqr_ms"] == pytest.approx(0)
    assert row["floor_ratio"] == pytest.approx(6) and row["floor_ratio_iqr"] == pytest.approx(5)    # 10 - 5


def test_median_iqr_interpolates_and_rejects_empty():
    assert T.median_iqr([3.0]) == (3.0, 0.0)
    assert T.median_iqr([1.0, 2.0, 3.0, 4.0]) == pytest.approx((2.5, 1.5))
    with pytest.raises(ValueError, match="^values:"):
        T.median_iqr([])


def test_plan_rounds_cuts_slow_passes_to_the_budget_but_not_below_min_rounds():
    assert T.plan_rounds([0.001, 0.0001], 0.15, 15) == (15, [10, 100])
    assert T.plan_rounds([0.02, 0.001], 0.2, 15) == (12, [1, 13])        # 15 x 33 ms > 0.4 s: 12 rounds
    assert T.plan_rounds([1.0, 0.001], 0.2, 15) == (T.MIN_ROUNDS, [1, 13])
    assert T.plan_rounds([1.0], 0.2, 3) == (3, [1])                     # fewer rounds asked: those
    assert T.plan_rounds([0.001], 0.15, 15) == (15, [10])               # no floor: the pass alone


def test_warm_up_runs_until_the_time_and_count_and_returns_fastest_calls():
    now = [0.0]
    durations = {"a": iter([0.05, 0.03, 0.04, 0.03]), "b": iter([0.01, 0.02, 0.01, 0.01])}
    calls = {k: 0 for k in durations}

    def make(k):
        def call():
            calls[k] += 1
            now[0] += next(durations[k])
        return call
    best = T.warm_up([make("a"), make("b")], 0.1, at_least=1, clock=lambda: now[0])
    assert calls == {"a": 2, "b": 2} and best == pytest.approx([0.03, 0.01])   # 0.06 + 0.05 >= 0.1 s
    calls.update(a=0, b=0)
    durations.update(a=iter([0.0] * 3), b=iter([0.0] * 3))
    assert T.warm_up([make("a"), make("b")], 0.0, at_least=3, clock=lambda: now[0]) == [0.0, 0.0]
    assert calls == {"a": 3, "b": 3}


def test_nonfinite_output_is_not_timed():
    bad = torch.zeros(1, 1, 6, 8)
    bad[0, 0, 2, 3] = float("nan")
    row = T.time_pass(_inputs(output=bad), T.TimingSpec(min_run_time=0.01), threads=1)
    assert "1 NaN/Inf" in row["timing_error"] and math.isnan(row["time_median_ms"]) and row["time_blocks"] == 0


def test_floor_off_and_thread_count_restored():
    before = torch.get_num_threads()
    row = T.time_pass(_inputs(), T.TimingSpec(min_run_time=0.01, floor=False), threads=1)
    assert math.isnan(row["floor_ratio"]) and row["time_median_ms"] > 0
    assert torch.get_num_threads() == before


@pytest.mark.parametrize("kw, field", [({"min_run_time": 0}, "min_run_time"), ({"warmup": -1}, "warmup"),
                                       ({"floor": "yes"}, "floor"), ({"rounds": 2}, "rounds"),
                                       ({"rounds": True}, "rounds"), ({"fused_floor": 1}, "fused_floor"),
                                       ({"interleave": 1}, "interleave"), ({"processes": 0}, "processes")])
def test_spec_validation(kw, field):
    with pytest.raises(T.TimingSpecError, match=f"^{field}:") as e:        # a ValueError naming the field
        T.TimingSpec(**kw)
    assert isinstance(e.value, ValueError) and e.value.field == field
    assert e.value.reason.startswith(("must", "expected"))


def test_agree_is_within_the_iqr():
    a = {"time_median_ms": 10.0, "time_iqr_ms": 1.0, "floor_ratio": 4.0, "floor_ratio_iqr": 0.2}
    assert T.agree(a, dict(a, time_median_ms=10.9), field="time")
    assert not T.agree(a, dict(a, time_median_ms=11.5), field="time")
    assert T.agree(a, dict(a, time_median_ms=11.5), field="time", k=2.0)
    assert not T.agree(a, dict(a, floor_ratio=5.0))
    assert T.agree(a, dict(a, floor_ratio=5.0), rel=0.25)
    assert not T.agree(a, dict(a, floor_ratio=float("nan")), rel=10)
    with pytest.raises(ValueError, match="field"):
        T.agree(a, a, field="speed")


def test_ao_sample_counts_per_method():
    from ssbench.passes.ao.gtao import GTAOParams
    from ssbench.passes.ao.hbao import HBAOParams
    from ssbench.passes.ao.ssao import HemisphereSSAOParams
    from ssbench.passes.ao.crytek import CrytekSSAOParams
    assert E.ao_samples("hbao", HBAOParams(num_directions=8, num_steps=4)) == 32
    assert E.ao_samples("gtao", GTAOParams(quality="high")) == 2 * 3 * 3
    assert E.ao_samples("gtao", GTAOParams(quality="low", slice_count=4)) == 2 * 4 * 2
    assert E.ao_samples("ssao", HemisphereSSAOParams(kernel_size=24)) == 24
    assert E.ao_samples("crytek", CrytekSSAOParams(kernel_size=8)) == 8

    @dataclasses.dataclass(frozen=True)
    class Odd:
        taps: int = 3
    with pytest.raises(ValueError, match="samples_per_pixel"):
        E.ao_samples("odd", Odd())
    assert E.ao_samples("odd", Odd(), types.SimpleNamespace(samples_per_pixel=lambda p: p.taps * 2)) == 6


def test_ssr_sample_count_is_the_mean_steps_of_the_hit_buffer(monkeypatch):
    steps = torch.tensor([[[[0, 10], [20, 10]]]])                     # 40 depth reads over 4 pixels
    g = types.SimpleNamespace(select=lambda chans: "g", mask=torch.ones(1, 1, 2, 2, dtype=torch.bool),
                              view_z=torch.zeros(1, 1, 2, 2))
    ev = types.SimpleNamespace(result=types.SimpleNamespace(steps=steps, color=torch.zeros(1, 3, 2, 2)), gbuffer=g)
    inputs = E.ssr_bench(ev, "dda", {"max_steps": 32}, seed=0)
    assert inputs.samples == 10


@pytest.mark.slow
@pytest.mark.mitsuba
def test_repeated_timings_of_one_configuration_agree_statistically():
    """Two timings of the same configuration agree on the floor ratio within 2 IQR + 25 %.

    Each timing pools the rounds of this process and two fresh ones (the default ``processes: 3``, which runs the
    real child process here). Why not 1 IQR: even identically distributed rounds agree within 1 IQR only ~99 % of
    the time, and CI machines are shared. Timed in one process, 25 back-to-back pairs of this configuration (15
    rounds) were 76 % within 1 IQR, 96 % within 2 IQR, and never more than 20 % apart on the 2-core development
    machine (benchmarks/bench_sweep_repeats.py measures the shares through ``ssbench sweep``; they are not
    asserted here).
    """
    from ssbench.bench import sweep_from_dict
    from ssbench.bench.sweep import run_config
    s = sweep_from_dict({"effect": "ao", "scenes": ["crease"], "resolution": [64, 48], "rays": 4, "flip": False,
                         "oracle": False, "methods": {"hbao": {"num_directions": 4, "num_steps": 4}},
                         "timing": {"min_run_time": 0.1}})
    a, b = (run_config(s.configs[0], s.timing) for _ in range(2))
    assert a["error"] is None and a["timing_error"] is None and a["floor_samples"] == b["floor_samples"] == 16
    assert a["floor_ratio"] > 0 and b["floor_ratio"] > 0
    assert min(a["time_blocks"], b["time_blocks"]) >= 3 * T.MIN_ROUNDS and a["timing_processes"] == 3
    assert T.agree(a, b, field="floor_ratio", k=2.0, rel=0.25), (a["floor_ratio"], a["floor_ratio_iqr"],
                                                                b["floor_ratio"], b["floor_ratio_iqr"])


def test_timed_blocks_wait_for_the_device(monkeypatch):
    """CUDA launches are asynchronous: every timed block (and every warm-up call) ends with a synchronise, so the
    same code times a GPU correctly. Counted here with a stand-in device."""
    import torch

    from ssbench.bench import timing as T
    events = []
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "is_initialized", lambda: True)
    monkeypatch.setattr(torch.cuda, "synchronize", lambda *a, **k: events.append("sync"))
    T.timeit_calls(lambda: events.append("call"), 3)
    assert events == ["sync", "call", "call", "call", "sync"]              # before the block, and at its end
    events.clear()
    T.warm_up([lambda: events.append("a"), lambda: events.append("b")])
    assert events == ["sync", "a", "sync", "sync", "b", "sync"]
    monkeypatch.setattr(torch.cuda, "is_initialized", lambda: False)       # CPU runs: no synchronise at all
    events.clear()
    T.timeit_calls(lambda: events.append("call"), 2)
    assert events == ["call", "call"]
