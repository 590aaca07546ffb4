"""Implicit surfaces: the torch evaluator against the Dr.Jit one, and time per frame per method (not a test).

Part 1 — evaluations per second of one parsed expression (the catalog's torus, gyroid sheet and Barth sextic)
on ``--points`` (10⁶) random points in the object's bounds: torch in float32 and float64
(``Expression.__call__`` on a ``(n, 3)`` tensor) and Dr.Jit (``Expression.drjit`` on ``drjit.llvm.Float`` /
``Float64`` arrays after :func:`ssbench.reference.backend.mitsuba`, with ``dr.eval`` and ``dr.sync_thread``
inside the timed region, so tracing, kernel launch and the wait are all counted; the kernel is compiled in the
untimed warm-up and then served from Dr.Jit's cache). Each figure is the median of ``--repeats`` warm runs.

Part 2 — time per frame of each method at 320×240 on thin_shell (``ssbench.evaluate.run_implicit`` with no
reference; the median over ``--frames`` frames; the progressive method carries its state).

Part 3 — the certified reference (``ssbench.reference.implicit`` with ``exits=True``, as the evaluation traces it)
per frame with the torch engine and the Dr.Jit engine, alternated round by round in one process (median of
``--ref-rounds``); the Dr.Jit kernel's first compilation is timed apart (``first s``), and the two engines'
hit masks are compared.

Run: ``.venv/bin/python benchmarks/bench_implicit.py [--points 1000000 --repeats 7 --threads 2]``.
"""
from __future__ import annotations

import argparse
import statistics
import time

import torch

from ssbench.implicit.scene import load

SCENES = (("torus", "torus"), ("gyroid", "gyroid_sheet"), ("Barth sextic", "barth_sextic"))


def _median(call, repeats: int) -> float:
    call()                                                   # warm-up (Dr.Jit compiles its kernel here)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def evaluator_rates(points: int, repeats: int) -> list[tuple[str, int, dict]]:
    """``(label, n_ops, {backend: evaluations per second})`` per expression."""
    from ssbench.reference import backend
    backend.mitsuba()
    import drjit as dr
    import drjit.llvm as L
    out = []
    for label, name in SCENES:
        obj = load(name).objects.objects[0]
        expr = obj.expression
        lo, hi = (torch.tensor(b, dtype=torch.float64) for b in obj.bounds)
        p64 = lo + (hi - lo) * torch.rand(points, 3, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
        rates = {}
        for tag, dtype in (("torch f32", torch.float32), ("torch f64", torch.float64)):
            p = p64.to(dtype).contiguous()
            rates[tag] = points / _median(lambda: expr(p), repeats)
        for tag, F in (("drjit f32", L.Float), ("drjit f64", L.Float64)):
            xyz = [F(p64[:, k].contiguous().numpy()) for k in range(3)]
            dr.eval(*xyz)
            dr.sync_thread()

            def run():
                v = expr.drjit(*xyz)
                dr.eval(v)
                dr.sync_thread()
            rates[tag] = points / _median(run, repeats)
        out.append((label, expr.n_ops, rates))
    return out


def method_times(width: int, height: int, frames: int) -> list[dict]:
    """Rows of :func:`ssbench.evaluate.run_implicit` on thin_shell, one per method, without a reference."""
    from ssbench.evaluate import run_implicit
    from ssbench.passes import IMPLICIT_METHODS
    return [run_implicit("thin_shell", m, None, frames=frames, width=width, height=height, truth_frames="none",
                         lipschitz_samples=0).row for m in IMPLICIT_METHODS]


def reference_times(scenes, sizes, rounds: int) -> list[dict]:
    """Per scene and size: the reference's seconds per frame with each engine (median over alternated rounds)."""
    from ssbench.reference.implicit import implicit
    rows = []
    for name in scenes:
        sc = load(name)
        for w, h in sizes:
            cam, surf = sc.camera_at(0).with_resolution(w, h), sc.surface(0)

            def run(engine):
                t0 = time.perf_counter()
                ref = implicit(surf, cam, exits=True, use_cache=False, engine=engine)
                return time.perf_counter() - t0, ref
            first, _ = run("drjit")                                      # compiles the kernel (or loads it)
            times, refs = {"torch": [], "drjit": []}, {}
            for _ in range(rounds):
                for engine in times:
                    s, refs[engine] = run(engine)
                    times[engine].append(s)
            same = bool(torch.equal(refs["torch"].hit, refs["drjit"].hit))
            rows.append({"scene": name, "size": f"{w}x{h}", "first_s": first, "same_hits": same,
                         **{e: statistics.median(v) for e, v in times.items()}})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's choice)")
    ap.add_argument("--skip-evaluators", action="store_true")
    ap.add_argument("--ref-scenes", default="thin_shell,torus,gyroid_sheet,barth_sextic")
    ap.add_argument("--ref-sizes", default="96x72,320x240")
    ap.add_argument("--ref-rounds", type=int, default=3)
    a = ap.parse_args()
    if a.threads:
        torch.set_num_threads(a.threads)
    from ssbench.reference import backend
    info = backend.info()
    print(f"torch {torch.__version__} ({torch.get_num_threads()} threads) · Mitsuba {info['variant']} · drjit "
          f"{info['drjit']} ({info['drjit_threads']} threads)")
    if not a.skip_evaluators:
        cols = ("torch f32", "torch f64", "drjit f32", "drjit f64")
        print(f"\nevaluations per second (10^6/s), {a.points:,} points, median of {a.repeats} warm runs")
        print(f"  {'expression':14s} {'nodes':>5s} " + " ".join(f"{c:>10s}" for c in cols)
              + f" {'drjit/torch f32':>16s}")
        for label, n_ops, r in evaluator_rates(a.points, a.repeats):
            print(f"  {label:14s} {n_ops:5d} " + " ".join(f"{r[c] / 1e6:10.1f}" for c in cols)
                  + f" {r['drjit f32'] / r['torch f32']:15.1f}x")
    print(f"\ntime per frame on thin_shell at {a.width}x{a.height} (median of {a.frames} frames, no reference)")
    print(f"  {'method':12s} {'ms/frame':>9s} {'evals/px':>9s} {'Meval/s':>8s}")
    for r in method_times(a.width, a.height, a.frames):
        rate = r["evaluations_mean"] * r["width"] * r["height"] / r["seconds_per_frame"] / 1e6
        print(f"  {r['method']:12s} {r['seconds_per_frame'] * 1e3:9.1f} {r['evaluations_mean']:9.1f} {rate:8.1f}")
    sizes = [tuple(int(v) for v in s.split("x")) for s in a.ref_sizes.split(",") if s]
    print(f"\ncertified reference per frame (exits), torch vs Dr.Jit engine, median of {a.ref_rounds} "
          "alternated rounds")
    print(f"  {'scene':14s} {'size':>8s} {'torch s':>8s} {'drjit s':>8s} {'torch/drjit':>11s} {'first s':>8s} "
          f"{'same hits':>9s}")
    for r in reference_times([n for n in a.ref_scenes.split(",") if n], sizes, a.ref_rounds):
        print(f"  {r['scene']:14s} {r['size']:>8s} {r['torch']:8.3f} {r['drjit']:8.4f} "
              f"{r['torch'] / r['drjit']:10.0f}x {r['first_s']:8.2f} {str(r['same_hits']):>9s}")


if __name__ == "__main__":
    main()
