"""Do repeated ``ssbench sweep`` runs agree within their IQR? (a benchmark, not a test)

Runs one sweep ``--repeats`` times for each ``timing.processes`` value of ``--processes``, every run a fresh
``ssbench sweep --no-resume`` into its own folder, the values alternating run by run (A B A B ...) so that the
machine's hour weighs on each alike. Then prints, per value, the share of pairs of runs whose rows agree on
``floor_ratio`` (and raw ``time``) within 1 and 2 IQR (:func:`ssbench.bench.timing.agree`), the spread of a
configuration's ratio between runs and the wall time of one run.

The default sweep (``--sweep ao``) is every AO method at two costs on two scenes at 160×120 with the default
timing block (15 rounds, ``min_run_time`` 0.2 s, groups of 8); ``--sweep ssr`` the three SSR marchers at two
step counts; or give a sweep file (its ``timing`` block's ``processes`` is replaced).

Run: ``.venv/bin/python benchmarks/bench_sweep_repeats.py [--sweep ao|ssr|FILE] [--repeats 5]
[--processes 1,3] [--json rows.json]``.
"""
from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import yaml

from ssbench.bench import timing as T

SWEEPS = {
    "ao": """
name: repeats_ao
effect: ao
scenes: [crease, sphere_on_plane]
resolution: [160, 120]
rays: 16
flip: false
oracle: false
timing: {}
methods:
  crytek: {kernel_size: [8, 16]}
  ssao: {kernel_size: [8, 16]}
  hbao: {num_directions: [4, 8]}
  gtao: {quality: [low, high]}
""",
    "ssr": """
name: repeats_ssr
effect: ssr
scenes: [reflective_floor]
resolution: [160, 120]
spp: 1
flip: false
timing: {}
methods:
  linear: {iterations: [16, 64]}
  dda: {max_steps: [32, 128]}
  dda_supercover: {max_steps: [32, 128]}
""",
}


def sweep_doc(source: str) -> dict:
    text = SWEEPS[source] if source in SWEEPS else open(source).read()
    return yaml.safe_load(text)


def run_once(doc: dict, processes: int, folder: str) -> tuple[list[dict], float]:
    """Rows of one fresh ``ssbench sweep`` run of ``doc`` with ``timing.processes`` set, and its wall time."""
    doc = dict(doc, timing=dict(doc.get("timing") or {}, processes=processes))
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, "sweep.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(doc, f)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "ssbench", "sweep", path, "--out", os.path.join(folder, "out"),
                    "--no-resume", "--quiet"], check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    with open(os.path.join(folder, "out", "rows.jsonl")) as f:
        return [json.loads(line) for line in f], wall


def summarize(runs: list[list[dict]]) -> dict:
    """Agreement shares over every pair of runs, per configuration pooled, and the between-run spread."""
    by_id: dict[str, list[dict]] = {}
    for rows in runs:
        for r in rows:
            by_id.setdefault(r["config_id"], []).append(r)
    n = r1 = r2 = t1 = t2 = 0
    spread, iqr = [], []
    for rs in by_id.values():
        for a, b in itertools.combinations(rs, 2):
            n += 1
            r1 += T.agree(a, b, k=1)
            r2 += T.agree(a, b, k=2)
            t1 += T.agree(a, b, field="time", k=1)
            t2 += T.agree(a, b, field="time", k=2)
        logs = np.log([r["floor_ratio"] for r in rs])
        spread.append(float(np.std(logs, ddof=1)))
        iqr += [r["floor_ratio_iqr"] / r["floor_ratio"] for r in rs]
    n, pairs = max(1, n), n
    return {"pairs": pairs, "ratio_1iqr": r1 / n, "ratio_2iqr": r2 / n, "time_1iqr": t1 / n, "time_2iqr": t2 / n,
            "ratio_sd_between_runs": float(np.median(spread)), "ratio_iqr_rel": float(np.median(iqr))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sweep", default="ao", help="ao, ssr or a sweep file")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--processes", default="1,3", help="comma-separated timing.processes values")
    ap.add_argument("--json", default="", help="write every row to this file")
    a = ap.parse_args()
    values = [int(v) for v in a.processes.split(",")]
    doc = sweep_doc(a.sweep)
    runs: dict[int, list] = {v: [] for v in values}
    walls: dict[int, list] = {v: [] for v in values}
    load0 = open("/proc/loadavg").read().split()[:3]
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.repeats):
            for v in values if r % 2 == 0 else values[::-1]:
                rows, wall = run_once(doc, v, os.path.join(tmp, f"p{v}_r{r}"))
                runs[v].append(rows)
                walls[v].append(wall)
                print(f"  run {r} processes={v}: {len(rows)} rows in {wall:.0f} s", flush=True)
    load1 = open("/proc/loadavg").read().split()[:3]
    print(f"sweep {doc['name']}, {a.repeats} runs per value; loadavg {' '.join(load0)} -> {' '.join(load1)}")
    print(f"  {'processes':>9s} {'pairs':>5s} {'r≤1IQR':>6s} {'r≤2IQR':>6s} {'t≤1IQR':>6s} {'t≤2IQR':>6s} "
          f"{'sd runs':>7s} {'IQR/r':>6s} {'run s':>6s}")
    for v in values:
        s = summarize(runs[v])
        print(f"  {v:9d} {s['pairs']:5d} {s['ratio_1iqr']:6.0%} {s['ratio_2iqr']:6.0%} {s['time_1iqr']:6.0%} "
              f"{s['time_2iqr']:6.0%} {s['ratio_sd_between_runs']:7.1%} {s['ratio_iqr_rel']:6.1%} "
              f"{np.median(walls[v]):6.0f}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"args": vars(a), "loadavg": [load0, load1], "runs": {str(v): runs[v] for v in values}}, f,
                      default=str)


if __name__ == "__main__":
    main()
