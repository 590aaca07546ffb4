"""Timing pooled over several fresh processes (``timing: {processes: N}``: each process has its own memory layout).

Why: rounds inside one process share that process — its memory layout (where the allocator and the kernel put
the G-buffer, the pass's temporaries and the floor's indices) and the machine's state while it runs (a noisy
neighbour, a clock regime). These shift all of the process's rounds alike, so no number of rounds samples
them: on the 2-core VM this was written on, a configuration's median floor ratio moved by sd ≈ 7 % between
processes while its median over one process's rounds would move by ≈ 4 %, and 77-95 % of pairs of runs agreed
within their IQR, depending on the hour. Benchmarking practice is to repeat whole invocations (Georges, Buytaert &
Eeckhout, "Statistically rigorous Java performance evaluation", OOPSLA 2007; Kalibera & Jones, "Rigorous
benchmarking in reasonable time", ISMM 2013): pooling the rounds of ``N`` processes puts the between-process
spread inside the IQR and averages it out of the median. Measured through ``ssbench sweep`` with
``benchmarks/bench_sweep_repeats.py`` (6 runs per setting, alternating), the share of pairs of runs whose
``floor_ratio`` agrees within 1 IQR went from 93 % (1 process) to 100 % (3) for 16 AO configurations at 160×120
(raw time: 68 % to 100 %; one run took 13 s, then 46 s), and from 93 % to 100 % for 6 SSR marchers (raw time:
90 % to 97 %).

How: :func:`time_group` times a group in this process (:func:`~ssbench.bench.interleave.interleaved_rounds`),
then runs ``python -m ssbench.bench.processes`` ``N - 1`` times, one after another (timing is never run in
parallel). Each child gets the configurations and the :class:`~ssbench.bench.timing.TimingSpec` as JSON on stdin,
evaluates them again exactly as the sweep did (the same Mitsuba variant, ground truth from the cache), times
them in interleaved rounds with its own order seed and prints its per-round seconds; the parent pools them per
configuration and summarizes them with :func:`~ssbench.bench.timing.round_fields`. A child that fails makes the
group's timing fail (``timing_error`` names the process and its last stderr lines); the evaluation rows are kept.
"""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import threading
import time
from typing import Any, Callable, Optional, Sequence

from . import timing as T
from .interleave import interleaved_rounds, summarize_rounds

__all__ = ["time_group", "config_to_json", "config_from_json", "run_child", "watch_parent", "MARK"]

#: prefix of the one stdout line a child prints its rounds on (other output is ignored)
MARK = "SSBENCH-ROUNDS "


def config_to_json(config) -> dict:
    """A :class:`~ssbench.bench.config.Config` as plain JSON data (``config_id`` included, for checking)."""
    out = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    return dict(out, params=dict(config.params), settings=dict(config.settings))


def config_from_json(d: dict):
    """The :class:`~ssbench.bench.config.Config` of :func:`config_to_json`; raises when its id differs."""
    from .config import Config
    d = dict(d)
    want = d.pop("config_id", None)
    config = Config(**d)
    if want is not None and config.config_id != want:
        raise ValueError(f"config: id {config.config_id} after the round trip, expected {want}")
    return config


def run_child(configs: Sequence, timing: T.TimingSpec, order_seed: int) -> list[dict]:
    """Time ``configs`` in a fresh ``python -m ssbench.bench.processes``; per configuration ``{"config_id",
    "rounds", "error"}`` (``rounds`` as :func:`~ssbench.bench.interleave.interleaved_rounds` gives them, or
    ``None`` with ``error`` saying why). Raises ``RuntimeError`` when the process fails."""
    from ..reference import backend
    payload = json.dumps({"configs": [config_to_json(c) for c in configs], "timing": dataclasses.asdict(timing),
                          "order_seed": int(order_seed), "backend": dataclasses.asdict(backend.choice())},
                         default=list)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
    proc = subprocess.run([sys.executable, "-m", "ssbench.bench.processes"], input=payload, text=True,
                          capture_output=True, env=env)
    lines = [line for line in proc.stdout.splitlines() if line.startswith(MARK)]
    if proc.returncode != 0 or not lines:
        tail = " | ".join(proc.stderr.strip().splitlines()[-3:]) or "no output"
        raise RuntimeError(f"timing process exited with status {proc.returncode}: {tail} (a fresh process sees "
                           f"only importable effects and methods; timing.processes: 1 times in this process only)")
    return json.loads(lines[-1][len(MARK):])


def time_group(items: Sequence[tuple[Any, int, int]], configs: Sequence, timing: T.TimingSpec, *,
               order_seed: int = 0, child: Callable[[Sequence, T.TimingSpec, int], list[dict]] = run_child,
               timer: Callable[[Callable[[], Any], int], float] = T.timeit_calls) -> list[dict]:
    """Timing fields of ``items`` (as :func:`~ssbench.bench.interleave.time_interleaved` takes them; ``configs``
    are their configurations), pooled over this process and ``timing.processes - 1`` children.

    Child ``p`` uses order seed ``order_seed + p``. ``timing_processes`` is the number of processes pooled;
    ``child`` and ``timer`` are replaceable in tests.
    """
    rows, pooled = interleaved_rounds(items, timing, order_seed=order_seed, timer=timer)
    for p in range(1, timing.processes):
        got = child(configs, timing, order_seed + p)
        if [g.get("config_id") for g in got] != [c.config_id for c in configs]:
            raise RuntimeError(f"timing process {p + 1} of {timing.processes} answered for other configurations")
        for i, (row, theirs) in enumerate(zip(rows, got)):
            mine = pooled[i]
            if mine is None:                             # untimed here, or by an earlier child
                continue
            if theirs.get("rounds") is None or len(theirs["rounds"]) != len(mine):
                row["timing_error"] = (f"not timed: process {p + 1} of {timing.processes} could not time it: "
                                       f"{theirs.get('error') or 'no rounds'}")
                pooled[i] = None
                continue
            for k, seconds in enumerate(theirs["rounds"]):
                mine[k] += [float(s) for s in seconds]
    return summarize_rounds(rows, pooled, timing.processes)


def watch_parent(parent: int, *, interval: float = 0.5, getppid: Callable[[], int] = os.getppid,
                 leave: Callable[[int], Any] = os._exit,
                 sleep: Callable[[float], Any] = time.sleep) -> threading.Thread:
    """Start a daemon thread that ends this process (``leave(3)``) once its parent ``parent`` is gone (the child is
    re-parented): a sweep killed mid-group must not leave a child timing on, slowing whatever runs next."""
    def watch() -> None:
        while getppid() == parent:
            sleep(interval)
        leave(3)
    t = threading.Thread(target=watch, name="ssbench-watch-parent", daemon=True)
    t.start()
    return t


def _child_main(stream) -> list[dict]:
    """What a child prints: evaluate the configurations, time them, return their rounds."""
    from ..reference import backend
    from .sweep import evaluate_config
    req = json.load(stream)
    backend.adopt(backend.BackendChoice(**dict(req["backend"], reason="chosen by the sweep's process")))
    timing = T.TimingSpec(**req["timing"])
    configs = [config_from_json(d) for d in req["configs"]]
    done = [evaluate_config(c, timing) for c in configs]
    live = [k for k, d in enumerate(done) if d[1] is not None]
    _, rounds = interleaved_rounds([(done[k][1], done[k][2], configs[k].seed) for k in live], timing,
                                   order_seed=int(req["order_seed"]))
    out: list[dict] = [{"config_id": c.config_id, "rounds": None,
                        "error": done[k][0].get("timing_error") or done[k][0].get("error") or "not timed"}
                       for k, c in enumerate(configs)]
    for k, r in zip(live, rounds):
        out[k].update(rounds=r, error=None if r is not None else "output has NaN/Inf on valid pixels")
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    if argv:
        print("usage: python -m ssbench.bench.processes < request.json  (run by ssbench sweep)", file=sys.stderr)
        return 2
    watch_parent(os.getppid())
    print(MARK + json.dumps(_child_main(sys.stdin)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
