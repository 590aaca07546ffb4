"""Run every screen-space pass once on a device (CUDA by default) and once on the CPU, and print how long each
took and how far the two results are apart: the check to run whenever a GPU is at hand (``make gpu-check``).

Each pass gets the same G-buffer (a catalog scene rendered once by the reference backend on the CPU, moved to
the device) and the same seed; times are medians of ``--repeats`` calls after one warm-up, with the device
synchronised inside each timed call. Agreement is the largest absolute difference of the pass's main output
(AO, or the reflection colour) between the devices. Exit status 1 when the device is missing or any pass fails.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time


def _timed(fn, repeats: int):
    from ssbench.bench.timing import sync_device
    out = fn()                                                        # warm-up (and the result compared)
    times = []
    for _ in range(repeats):
        sync_device()
        t0 = time.perf_counter()
        fn()
        sync_device()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def check(scene: str, width: int, height: int, device: str, repeats: int) -> list[dict]:
    """One row per AO and SSR method: ``{effect, method, cpu_ms, device_ms, max_abs_diff, error}``."""
    import torch

    from ssbench import reference
    from ssbench.passes import AO_METHODS, SSR_METHODS, ao_method, ssr_method
    g = reference.gbuffer(scene, width, height, channels=("view_z", "normal", "mask", "color", "position", "roughness"))
    g_dev = g.to(device=device)
    rows = []
    for effect, names, resolve, field in (("ao", AO_METHODS, ao_method, "ao"), ("ssr", SSR_METHODS, ssr_method,
                                                                                  "color")):
        for name in names:
            fn, params_cls, _ = resolve(name)
            p = params_cls()
            try:
                cpu, t_cpu = _timed(lambda: fn(g, p, generator=torch.Generator().manual_seed(0)), repeats)
                dev, t_dev = _timed(lambda: fn(g_dev, p, generator=torch.Generator().manual_seed(0)), repeats)
                diff = float((getattr(cpu, field).double() - getattr(dev, field).double().cpu()).abs().max())
                rows.append({"effect": effect, "method": name, "cpu_ms": 1e3 * t_cpu, "device_ms": 1e3 * t_dev,
                             "max_abs_diff": diff, "error": ""})
            except Exception as e:                                    # noqa: BLE001 - reported, exit status 1
                rows.append({"effect": effect, "method": name, "cpu_ms": float("nan"), "device_ms": float("nan"),
                             "max_abs_diff": float("nan"), "error": f"{type(e).__name__}: {e}"})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--device", default="cuda", help="device to check against the CPU (default cuda)")
    ap.add_argument("--scene", default="cornell_box")
    ap.add_argument("--size", default="640x360", help="WxH (default 640x360)")
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args(argv)
    import torch
    if a.device.startswith("cuda") and not torch.cuda.is_available():
        print(f"gpu_check: error: no CUDA device (torch {torch.__version__}, built for CUDA "
              f"{torch.version.cuda})", file=sys.stderr)
        return 1
    w, h = (int(v) for v in a.size.lower().split("x"))
    rows = check(a.scene, w, h, a.device, a.repeats)
    name = torch.cuda.get_device_name(0) if a.device.startswith("cuda") else a.device
    print(f"{a.scene} {w}x{h}, {a.repeats} repeats, torch {torch.__version__}, "
          f"{torch.get_num_threads()} CPU threads, device {name}")
    print(f"{'effect':6} {'method':15} {'cpu ms':>10} {'device ms':>10} {'speed-up':>9} {'max |diff|':>11}")
    for r in rows:
        if r["error"]:
            print(f"{r['effect']:6} {r['method']:15} error: {r['error']}")
            continue
        print(f"{r['effect']:6} {r['method']:15} {r['cpu_ms']:10.2f} {r['device_ms']:10.2f} "
              f"{r['cpu_ms'] / r['device_ms']:9.1f} {r['max_abs_diff']:11.2e}")
    return 1 if any(r["error"] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
