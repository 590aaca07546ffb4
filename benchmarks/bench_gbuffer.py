"""G-buffer render time at 640x360 (a benchmark, not a test): first call (JIT compile) and warm median.

Run: ``make bench`` or ``.venv/bin/python benchmarks/bench_gbuffer.py [--scene NAME] [--repeat N]``.
The disk cache is bypassed so every call renders.
"""
from __future__ import annotations

import argparse
import statistics
import time

import torch

from ssbench.reference import backend, color, gbuffer
from ssbench.reference.gbuffer import DEFAULT_CHANNELS


def timeit(fn, repeat: int) -> tuple[float, float, list[float]]:
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return first, statistics.median(times), times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scene", default="sphere_on_plane")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--repeat", type=int, default=10)
    a = ap.parse_args()
    info = backend.info()
    print(f"variant {info['variant']} (libLLVM {info['libllvm_major']}), mitsuba {info['mitsuba']}, "
          f"drjit threads {info['drjit_threads']}, torch threads {torch.get_num_threads()}")
    cases = {
        "gbuffer (default channels)": lambda: gbuffer(a.scene, a.width, a.height, use_cache=False),
        "gbuffer + back_z": lambda: gbuffer(a.scene, a.width, a.height, DEFAULT_CHANNELS + ("back_z",),
                                            use_cache=False),
        "view_z only": lambda: gbuffer(a.scene, a.width, a.height, ["view_z"], use_cache=False),
        "color 16 spp": lambda: color(a.scene, a.width, a.height, spp=16, use_cache=False),
    }
    print(f"{a.scene} at {a.width}x{a.height}, {a.repeat} warm repeats")
    for name, fn in cases.items():
        first, med, times = timeit(fn, a.repeat)
        print(f"  {name:28s} first {first * 1e3:8.1f} ms   warm median {med * 1e3:8.1f} ms "
              f"(min {min(times) * 1e3:.1f}, max {max(times) * 1e3:.1f})")


if __name__ == "__main__":
    main()
