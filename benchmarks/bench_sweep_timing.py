"""Do repeated timings of one configuration agree within their IQR? Which timing protocol makes them? (a
benchmark, not a test)

For each AO method at its defaults (and each SSR marcher with ``--ssr``) this times the pass ``--repeats`` times
under each ``--protocol`` and prints, per protocol and method, the median ratio to the gather floor and the
share of pairs of repeats whose ``floor_ratio`` (and raw ``time``) agree within 1 IQR and 2 IQR
(:func:`ssbench.bench.timing.agree`), then the pooled shares and the mean cost of one timing (seconds).

A repeat is, by default, a timing in this process, back to back with the others of the same configuration;
with ``--processes`` every repeat is a fresh interpreter (as a user's second ``ssbench sweep`` would be) that
evaluates every configuration again and prints its rows as JSON lines.

Protocols (``+``-joined, e.g. ``rounds+warm+pin``):

* ``sweep``: :func:`ssbench.bench.timing.time_pass`, what a sweep does (steady heap, warm-up, interleaved
  rounds cut to the ``2 * min_run_time`` budget for slow passes but not below ``MIN_ROUNDS``);
* ``autorange``: the earlier protocol — ``--warmup`` calls of each, ``Timer.blocked_autorange(min_run_time)`` of
  the pass, then of the floor; ``floor_ratio_iqr`` propagated from the two IQRs;
* ``rounds``: one calibration call of each, then exactly ``--rounds`` rounds each timing a block of the pass and
  a block of the floor back to back (blocks of about ``min_run_time / rounds``); median and IQR of per-round
  ratios (no budget cut: slow passes cost ``rounds`` calls);
* ``interleaved``: what a sweep with ``timing: {interleave: N}`` does: every job of the repeat timed together in
  randomized interleaved rounds (:func:`ssbench.bench.interleave.time_interleaved`, order seeded by the repeat);
* ``+warm``: call the pass and the floor in turn for ``--warm-time`` seconds first (caches, clock);
* ``+pin``: pin the thread to the CPU it runs on while timing (``os.sched_setaffinity``), then restore it;
* ``+heap``: time inside :func:`ssbench.bench.timing.steady_heap` (glibc keeps freed heap; see there).

Under iid blocks, two medians of n samples differ by less than the larger of their IQRs with probability about
54 % (n = 2), 86 % (5), 94 % (7), 96 % (9), 98 % (11): a protocol with few blocks cannot reach 95 % at all.

Run: ``.venv/bin/python benchmarks/bench_sweep_timing.py [--width 320 --height 240 --repeats 5 --threads 1
--protocol sweep,autorange,rounds+heap --processes --json rows.json]``.
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import itertools
import json
import math
import os
import subprocess
import sys
import time

import torch
import torch.utils.benchmark as tb

from ssbench.bench import effects as E
from ssbench.bench import timing as T
from ssbench.bench.interleave import time_interleaved
from ssbench.bench.floors import torch_floor

BASES = ("sweep", "autorange", "rounds", "interleaved")
MODIFIERS = ("warm", "pin", "heap")


def parse_protocol(name: str) -> tuple[str, set]:
    """``"rounds+warm"`` → ``("rounds", {"warm"})``; errors name the argument."""
    base, *mods = name.split("+")
    if base not in BASES or any(m not in MODIFIERS for m in mods):
        raise SystemExit(f"--protocol: {name!r} is not BASE[+MOD...] with BASE in {BASES}, MOD in {MODIFIERS}")
    if base in ("sweep", "interleaved") and mods:
        raise SystemExit(f"--protocol: {base!r} takes no modifiers, got {name!r}")
    return base, set(mods)


@contextlib.contextmanager
def pinned():
    """Pin the calling thread to the CPU it runs on (``os.sched_setaffinity``), restoring its affinity after."""
    before = os.sched_getaffinity(0)
    with open("/proc/thread-self/stat") as f:
        cpu = int(f.read().rsplit(")", 1)[1].split()[36])                  # field 39, "processor"
    os.sched_setaffinity(0, {cpu if cpu in before else min(before)})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


Stats = collections.namedtuple("Stats", "median iqr blocks")      # seconds per call; blocks of the autorange


def autorange(call, a: argparse.Namespace) -> Stats:
    """The earlier protocol's measurement: ``Timer.blocked_autorange`` (after the caller's warm-up)."""
    m = tb.Timer("call()", globals={"call": call}, num_threads=a.threads).blocked_autorange(
        min_run_time=a.min_run_time)
    return Stats(float(m.median), float(m.iqr), len(m.times))


def time_protocol(inputs: E.BenchInputs, name: str, a: argparse.Namespace) -> dict:
    """One timing row of ``inputs`` under protocol ``name`` (plus ``cost_s``: its wall time)."""
    base, mods = parse_protocol(name)
    t0 = time.perf_counter()
    if base == "sweep":
        spec = T.TimingSpec(min_run_time=a.min_run_time, rounds=a.rounds, warmup=a.warmup)
        row = T.time_pass(inputs, spec, a.threads)
        return dict(row, cost_s=time.perf_counter() - t0)
    floor = torch_floor(inputs.texture, int(inputs.samples))
    prev = torch.get_num_threads()
    torch.set_num_threads(a.threads)
    try:
        with contextlib.ExitStack() as stack:
            if "pin" in mods:
                stack.enter_context(pinned())
            if "heap" in mods:
                stack.enter_context(T.steady_heap())
            warm = a.warm_time if "warm" in mods else 0.0
            if base == "autorange":                      # as it was: ``warmup`` calls of each (or ``+warm``)
                if warm or a.warmup:
                    T.warm_up([inputs.call, floor], warm, at_least=a.warmup)
                tp, tf = autorange(inputs.call, a), autorange(floor, a)
                row = {"time_median_ms": tp.median * 1e3, "time_iqr_ms": tp.iqr * 1e3, "time_blocks": tp.blocks,
                       "floor_median_ms": tf.median * 1e3, "floor_iqr_ms": tf.iqr * 1e3,
                       "floor_ratio": tp.median / tf.median,
                       "floor_ratio_iqr": tp.median / tf.median * math.hypot(tp.iqr / tp.median, tf.iqr / tf.median)}
            else:
                best = T.warm_up([inputs.call, floor], warm, at_least=a.warmup)
                numbers = [max(1, int(a.min_run_time / a.rounds / b)) for b in best]
                row = T.round_fields(T.run_rounds([inputs.call, floor], numbers, a.rounds))
    finally:
        torch.set_num_threads(prev)
    return dict(row, cost_s=time.perf_counter() - t0)


def jobs(a: argparse.Namespace) -> list[tuple[str, str, str]]:
    out = [("ao", a.scene, m) for m in E.get_effect("ao").method_names()]
    if a.ssr:
        out += [("ssr", "reflective_floor", m) for m in E.get_effect("ssr").method_names()]
    if a.only:
        out = [j for j in out if j[2] in a.only.split(",")]
    return out


def inputs_of(job: tuple[str, str, str], a: argparse.Namespace) -> E.BenchInputs:
    effect_name, scene, method = job
    effect = E.get_effect(effect_name)
    kw = {"rays": 16, "flip": False} if effect_name == "ao" else {"spp": 4, "flip": False}
    ev = effect.run(scene, method, {}, width=a.width, height=a.height, seed=0, settings={"repeats": 1, **kw})
    return effect.bench_inputs(ev, method, {}, 0)


def rotated(xs: list, k: int) -> list:
    return xs[k % len(xs):] + xs[:k % len(xs)]


def interleaved(all_inputs: dict, a: argparse.Namespace, repeat: int) -> list[dict]:
    """One repeat of the ``interleaved`` protocol: every job timed together (rows with ``cost_s``: its share)."""
    spec = T.TimingSpec(min_run_time=a.min_run_time, rounds=a.rounds, warmup=a.warmup)
    t0 = time.perf_counter()
    got = time_interleaved([(inp, a.threads, 0) for inp in all_inputs.values()], spec, order_seed=repeat)
    cost = (time.perf_counter() - t0) / max(1, len(got))
    return [{"job": list(job), "protocol": "interleaved", "samples": int(inp.samples), **row, "cost_s": cost}
            for (job, inp), row in zip(all_inputs.items(), got)]


def one_process(a: argparse.Namespace, protocols: list[str]) -> None:
    """``--child``: one repeat of every job under every protocol, as JSON lines on stdout."""
    alone = [p for p in protocols if p != "interleaved"]
    all_inputs = {}
    for job in jobs(a):
        inputs = all_inputs[job] = inputs_of(job, a)
        for name in rotated(alone, a.child) if alone else []:
            row = time_protocol(inputs, name, a)
            print(json.dumps({"job": list(job), "protocol": name, "samples": int(inputs.samples), **row}),
                  flush=True)
    if "interleaved" in protocols:
        for row in interleaved(all_inputs, a, a.child):
            print(json.dumps(row), flush=True)


def collect(a: argparse.Namespace, protocols: list[str]) -> list[dict]:
    """All rows: ``repeats`` fresh processes (``--processes``) or repeats in this one."""
    rows = []
    if a.processes:
        argv = [x for x in sys.argv[1:] if x != "--processes"]
        for r in range(a.repeats):
            out = subprocess.run([sys.executable, os.path.abspath(__file__), *argv, "--child", str(r)],
                                 check=True, capture_output=True, text=True).stdout
            rows += [dict(json.loads(line), repeat=r) for line in out.splitlines() if line.startswith("{")]
        return rows
    alone = [p for p in protocols if p != "interleaved"]
    all_inputs = {}
    for job in jobs(a):
        inputs = all_inputs[job] = inputs_of(job, a)
        for r in range(a.repeats) if alone else []:
            for name in rotated(alone, r):
                rows.append({"job": list(job), "protocol": name, "samples": int(inputs.samples), "repeat": r,
                             **time_protocol(inputs, name, a)})
    if "interleaved" in protocols:
        for r in range(a.repeats):
            rows += [dict(row, repeat=r) for row in interleaved(all_inputs, a, r)]
    return rows


def shares(rows: list[dict]) -> dict:
    """Shares of pairs of ``rows`` agreeing within 1 and 2 IQR, floor ratio and time."""
    pairs = list(itertools.combinations(rows, 2))
    s = lambda **kw: sum(T.agree(x, y, **kw) for x, y in pairs)                   # noqa: E731
    return {"pairs": len(pairs), "r1": s(k=1), "r2": s(k=2), "t1": s(field="time", k=1),
            "t2": s(field="time", k=2)}


def report(rows: list[dict], protocols: list[str]) -> None:
    print(f"  {'protocol':18s} {'method':15s} {'ms':>7s} {'ratio':>6s} {'±IQR':>5s} {'spread':>6s} {'r≤1IQR':>6s} "
          f"{'r≤2IQR':>6s} {'t≤1IQR':>6s} {'t≤2IQR':>6s} {'cost s':>6s}")
    for name in protocols:
        tot = {"pairs": 0, "r1": 0, "r2": 0, "t1": 0, "t2": 0}
        mine = [r for r in rows if r["protocol"] == name]
        for job in dict.fromkeys(tuple(r["job"]) for r in mine):
            rs = [r for r in mine if tuple(r["job"]) == job]
            s = shares(rs)
            tot = {k: tot[k] + s[k] for k in tot}
            ratios = [r["floor_ratio"] for r in rs]
            ms, _ = T.median_iqr([r["time_median_ms"] for r in rs])
            ratio, _ = T.median_iqr(ratios)
            riqr, _ = T.median_iqr([r["floor_ratio_iqr"] for r in rs])
            n = max(1, s["pairs"])
            print(f"  {name:18s} {job[0] + ' ' + job[2]:15s} {ms:7.2f} {ratio:6.2f} {riqr:5.2f} "
                  f"{max(ratios) - min(ratios):6.2f} {s['r1'] / n:6.0%} {s['r2'] / n:6.0%} {s['t1'] / n:6.0%} "
                  f"{s['t2'] / n:6.0%} {sum(r['cost_s'] for r in rs) / len(rs):6.3f}")
        n = max(1, tot["pairs"])
        cost = sum(r["cost_s"] for r in mine) / max(1, len(mine))
        print(f"  {name:18s} {'ALL':15s} {'':7s} {'':6s} {'':5s} {'':6s} {tot['r1'] / n:6.0%} {tot['r2'] / n:6.0%} "
              f"{tot['t1'] / n:6.0%} {tot['t2'] / n:6.0%} {cost:6.3f}   ({tot['pairs']} pairs)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="crease")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--min-run-time", type=float, default=0.2)
    ap.add_argument("--protocol", default="sweep", help="comma-separated protocols (see above)")
    ap.add_argument("--warmup", type=int, default=1, help="warm-up calls (the report uses 0)")
    ap.add_argument("--rounds", type=int, default=T.TimingSpec().rounds, help="rounds of the 'rounds' protocol")
    ap.add_argument("--warm-time", type=float, default=0.1, help="seconds of the '+warm' warm-up")
    ap.add_argument("--processes", action="store_true", help="every repeat in a fresh process")
    ap.add_argument("--ssr", action="store_true", help="also the SSR marchers (on reflective_floor)")
    ap.add_argument("--only", default="", help="comma-separated method names to keep")
    ap.add_argument("--json", default="", help="write every row to this file")
    ap.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args()
    protocols = a.protocol.split(",")
    for name in protocols:
        parse_protocol(name)
    torch.set_num_threads(a.threads)
    if a.child is not None:
        return one_process(a, protocols)
    load0 = open("/proc/loadavg").read().split()[:3]
    rows = collect(a, protocols)
    load1 = open("/proc/loadavg").read().split()[:3]
    print(f"{a.width}x{a.height}, {a.threads} thread(s), min_run_time {a.min_run_time}s, {a.repeats} repeats "
          f"{'in fresh processes' if a.processes else 'in one process'}, rounds {a.rounds}, warm {a.warm_time}s; "
          f"loadavg {' '.join(load0)} -> {' '.join(load1)}")
    report(rows, protocols)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"args": vars(a), "loadavg": [load0, load1], "rows": rows}, f,
                      default=str)


if __name__ == "__main__":
    main()
