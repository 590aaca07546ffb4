"""Throughput of the ray-traced AO ground truth (``ssbench.reference.ambient_occlusion``), in Mrays/s over all
pixels (width × height × rays / seconds, background pixels included), median of ``--repeats`` uncached runs
after one warm-up run (which compiles the Dr.Jit kernel).

Run: ``.venv/bin/python benchmarks/bench_ao_reference.py [--size 320x240 --rays 256 --threads 2]``.
A benchmark, not a test; ``make bench`` runs it.
"""
from __future__ import annotations

import argparse
import statistics
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--rays", type=int, default=256)
    ap.add_argument("--threads", type=int, default=2, help="Dr.Jit worker threads")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenes", default="sphere_on_plane,cornell_box")
    ap.add_argument("--weightings", default="cosine,obscurance,volume_hemisphere")
    a = ap.parse_args()
    from ssbench.reference import ambient_occlusion, backend, gbuffer
    backend.mitsuba()
    import drjit as dr
    dr.set_thread_count(a.threads)
    w, h = (int(v) for v in a.size.split("x"))
    print(f"AO ground truth at {w}x{h}, {a.rays} rays per pixel, {a.threads} Dr.Jit threads "
          f"({backend.choice().variant}); Mrays/s over all pixels, median of {a.repeats}")
    for scene in a.scenes.split(","):
        g = gbuffer(scene, w, h, ("view_z", "normal", "mask"))
        for weighting in a.weightings.split(","):
            ambient_occlusion(scene, g, 0.5, a.rays, weighting, 0, use_cache=False)        # warm-up: compile
            secs = []
            for _ in range(a.repeats):
                t0 = time.perf_counter()
                ambient_occlusion(scene, g, 0.5, a.rays, weighting, 0, use_cache=False)
                secs.append(time.perf_counter() - t0)
            s = statistics.median(secs)
            print(f"{scene:<18}{weighting:<20}{s:8.3f} s {w * h * a.rays / s / 1e6:8.1f} Mrays/s")


if __name__ == "__main__":
    main()
