"""Timing pooled over processes: the rounds of ``N`` processes pooled per configuration, children with their own
order seeds; a failing child fails the group's timing (rows kept); configurations survive the JSON trip.
(The real child process runs in tests/bench/test_kill_resume_dask.py, on real AO.)"""
import json
import math
import subprocess

import pytest

from ssbench.bench import processes as P
from ssbench.bench import timing as T

from .test_interleave import _inputs, _recording_timer
from .test_sweep import _toy


def _child_answering(rounds_of, asked=None):
    """A fake child: ``rounds_of(k, config)`` gives configuration k's rounds (``None``: could not time it)."""
    def child(configs, timing, order_seed):
        if asked is not None:
            asked.append((order_seed, timing.processes))
        return [{"config_id": c.config_id, "rounds": rounds_of(k, c), "error": "boom"} for k, c in enumerate(configs)]
    return child


def _group(toy, processes, child):
    configs = list(_toy().configs[:2])
    inputs = [_inputs(1.0), _inputs(2.0)]
    timer, _ = _recording_timer(inputs, [2.0, 3.0])                  # pass i: (2 + i) ms, floor 1 ms
    spec = T.TimingSpec(min_run_time=0.05, fused_floor=False, rounds=3, processes=processes)
    return P.time_group([(x, 1, 0) for x in inputs], configs, spec, order_seed=10, child=child, timer=timer)


def test_the_rounds_of_every_process_are_pooled(toy):
    asked = []
    rows = _group(toy, 3, _child_answering(lambda k, c: [[0.004 + k * 1e-3] * 3, [0.0005] * 3], asked))
    assert asked == [(11, 3), (12, 3)]                                 # one child after another, own order seeds
    for k, row in enumerate(rows):
        want = T.round_fields([[(2.0 + k) * 1e-3] * 3 + [0.004 + k * 1e-3] * 6, [1e-3] * 3 + [0.0005] * 6])
        assert want["time_blocks"] == 9 and row["timing_processes"] == 3 and row["timing_error"] is None
        assert {f: row[f] for f in want} == pytest.approx(want)
        assert row["floor_ratio"] == pytest.approx(8.0 + 2 * k)        # the pooled median: the children's rounds


def test_one_process_is_the_in_process_timing(toy):
    rows = _group(toy, 1, _child_answering(lambda k, c: pytest.fail("no child for processes: 1")))
    assert [r["time_blocks"] for r in rows] == [3, 3] and [r["timing_processes"] for r in rows] == [1, 1]
    assert [r["floor_ratio"] for r in rows] == pytest.approx([2.0, 3.0])


def test_a_configuration_a_child_cannot_time_is_not_timed(toy):
    rows = _group(toy, 2, _child_answering(lambda k, c: None if k == 1 else [[0.002] * 3, [0.001] * 3]))
    assert rows[0]["time_blocks"] == 6 and rows[0]["timing_error"] is None
    assert math.isnan(rows[1]["floor_ratio"]) and rows[1]["time_blocks"] == rows[1]["timing_processes"] == 0
    assert rows[1]["timing_error"] == "not timed: process 2 of 2 could not time it: boom"


def test_a_configuration_an_earlier_child_could_not_time_stays_untimed(toy):
    answers = iter([None, [[0.002] * 3, [0.001] * 3]])                 # process 2 fails it, process 3 would not
    rows = _group(toy, 3, _child_answering(lambda k, c: next(answers) if k == 1 else [[0.002] * 3, [0.001] * 3]))
    assert rows[0]["time_blocks"] == 9 and rows[0]["timing_processes"] == 3
    assert math.isnan(rows[1]["floor_ratio"]) and rows[1]["timing_processes"] == 0
    assert rows[1]["timing_error"] == "not timed: process 2 of 3 could not time it: boom"


def test_a_child_answering_for_other_configurations_fails_the_group(toy):
    wrong = _child_answering(lambda k, c: [[0.002] * 3, [0.001] * 3])
    with pytest.raises(RuntimeError, match="process 2 of 2 answered for other configurations"):
        _group(toy, 2, lambda configs, timing, seed: wrong(configs[::-1], timing, seed))


def test_a_failing_child_process_raises_with_its_stderr(toy, monkeypatch):
    seen = {}

    def fake_run(cmd, **kw):
        seen.update(cmd=cmd, request=json.loads(kw["input"]))
        return subprocess.CompletedProcess(cmd, 1, stdout="noise\n", stderr="Traceback\n  ...\nValueError: bad x\n")

    from ssbench.reference import backend
    monkeypatch.setattr(backend, "choice", lambda: backend.BackendChoice("scalar_rgb", None, "stub"))
    monkeypatch.setattr(P.subprocess, "run", fake_run)               # (no other subprocess runs meanwhile)
    config = _toy().configs[0]
    with pytest.raises(RuntimeError, match=r"status 1: Traceback \|   \.\.\. \| ValueError: bad x"):
        P.run_child([config], T.TimingSpec(processes=2), 5)
    assert seen["cmd"][-2:] == ["-m", "ssbench.bench.processes"]
    assert seen["request"]["order_seed"] == 5 and seen["request"]["timing"]["processes"] == 2
    assert P.config_from_json(seen["request"]["configs"][0]).config_id == config.config_id
    assert seen["request"]["backend"]["variant"] == "scalar_rgb"      # the child adopts the parent's variant


def test_configurations_survive_the_json_trip_and_a_changed_one_is_refused(toy):
    for config in _toy(timing={"processes": 2}).configs:
        back = P.config_from_json(json.loads(json.dumps(P.config_to_json(config))))
        assert back == config and back.config_id == config.config_id
    d = P.config_to_json(_toy().configs[0])
    with pytest.raises(ValueError, match="^config: id"):
        P.config_from_json(dict(d, seed=d["seed"] + 1))


def test_a_child_leaves_once_its_parent_is_gone():
    parents, left, slept = iter([100, 100, 1]), [], []
    P.watch_parent(100, interval=0.25, getppid=lambda: next(parents), leave=left.append,
                   sleep=slept.append).join(timeout=5)
    assert left == [3] and slept == [0.25, 0.25]                      # re-parented on the third look


def test_the_child_entry_point_refuses_arguments(capsys):
    assert P.main(["x"]) == 2 and "usage" in capsys.readouterr().err


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_processes_must_be_a_positive_integer(bad):
    assert T.TimingSpec().processes == 3 and T.TimingSpec(processes=1).processes == 1
    with pytest.raises(ValueError, match="^processes:"):
        T.TimingSpec(processes=bad)
