"""Do repeated timings of one configuration agree within their IQR? (a benchmark, not a test)

For each AO method at its defaults (and each SSR marcher with ``--ssr``) this times the pass ``--repeats`` times
with :func:`ssbench.bench.timing.time_pass` (blocked autorange, median and IQR, the gather floor in the same
run) and prints every ratio to the floor, then the share of pairs of repeats whose ``floor_ratio`` (and raw
``time``) agree within the IQR (:func:`ssbench.bench.timing.agree` with ``k=1``) and within 2 IQR.

Run: ``.venv/bin/python benchmarks/bench_sweep_timing.py [--width 320 --height 240 --repeats 5 --threads 1]``.
"""
from __future__ import annotations

import argparse
import itertools

from ssbench.bench import effects as E
from ssbench.bench.timing import TimingSpec, agree, time_pass


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scene", default="crease")
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--min-run-time", type=float, default=0.2)
    ap.add_argument("--ssr", action="store_true", help="also the SSR marchers (on reflective_floor)")
    a = ap.parse_args()
    spec = TimingSpec(min_run_time=a.min_run_time)
    jobs = [("ao", a.scene, m) for m in E.get_effect("ao").method_names()]
    if a.ssr:
        jobs += [("ssr", "reflective_floor", m) for m in E.get_effect("ssr").method_names()]
    print(f"{a.width}x{a.height}, {a.threads} thread(s), min_run_time {a.min_run_time}s, {a.repeats} repeats")
    print(f"  {'effect':6s} {'method':8s} {'samples':>7s} {'ms (median±IQR) per repeat':40s} {'ratio':>6s} "
          f"{'ratio≤1IQR':>10s} {'ratio≤2IQR':>10s} {'time≤1IQR':>9s}")
    for effect_name, scene, method in jobs:
        effect = E.get_effect(effect_name)
        kw = {"rays": 16, "flip": False} if effect_name == "ao" else {"spp": 4, "flip": False}
        ev = effect.run(scene, method, {}, width=a.width, height=a.height, seed=0, settings={"repeats": 1, **kw})
        inputs = effect.bench_inputs(ev, method, {}, 0)
        rows = [time_pass(inputs, spec, a.threads) for _ in range(a.repeats)]
        pairs = list(itertools.combinations(rows, 2))
        share = lambda **kw: sum(agree(x, y, **kw) for x, y in pairs) / max(1, len(pairs))   # noqa: E731
        times = " ".join(f"{r['time_median_ms']:.1f}±{r['time_iqr_ms']:.1f}" for r in rows)
        ratio = sorted(r["floor_ratio"] for r in rows)[len(rows) // 2]
        print(f"  {effect_name:6s} {method:8s} {inputs.samples:7d} {times[:40]:40s} {ratio:6.1f} "
              f"{share(k=1):10.0%} {share(k=2):10.0%} {share(field='time', k=1):9.0%}")


if __name__ == "__main__":
    main()
