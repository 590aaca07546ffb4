"""AO passes: time against the gather floor, and RMSE against cosine ground truth (a benchmark, not a test).

For each pass at its defaults this prints the median time (``torch.utils.benchmark`` blocked autorange, with
IQR) and the **gather floor**: the time of a pure ``torch.gather`` of as many texels as the pass fetches per
pixel, measured in the same run, so ``time / floor`` survives a noisy machine. Then, per scene, it tunes each
method's radius on a small grid against cosine ground truth (fixed ``R``) and prints the best RMSE.

Run: ``.venv/bin/python benchmarks/bench_ao.py [--width 640 --height 360 --scenes crease,cornell_box]``.
"""
from __future__ import annotations

import argparse
import dataclasses

import torch
import torch.utils.benchmark as tb

from ssbench.passes import AO_METHODS, ao_method
from ssbench.passes.common import fetch
from ssbench.reference import ambient_occlusion, gbuffer

RADIUS_PARAM = {"crytek": "kernel_radius", "ssao": "kernel_radius", "hbao": "radius", "gtao": "radius"}


def samples_per_pixel(method: str, params) -> int:
    """Texel fetches per pixel of a pass at ``params`` (its main loop; small constant extras ignored)."""
    if method in ("crytek", "ssao"):
        return params.kernel_size
    if method == "hbao":
        return params.num_directions * params.num_steps + 4          # + the 4 minDiff neighbours
    if method == "gtao":
        p = params
        slices = getattr(p, "slice_count", None) or {"low": 1, "medium": 2, "high": 3, "ultra": 9}[p.quality]
        steps = getattr(p, "steps_per_slice", None) or {"low": 2, "medium": 2, "high": 3, "ultra": 3}[p.quality]
        return 2 * slices * steps
    raise KeyError(method)


def gather_floor(view_z: torch.Tensor, k: int, generator: torch.Generator) -> tb.Measurement:
    B, _, H, W = view_z.shape
    col = torch.randint(0, W, (B, k, H, W), generator=generator)
    row = torch.randint(0, H, (B, k, H, W), generator=generator)
    return tb.Timer("fetch(z, col, row)", globals={"fetch": fetch, "z": view_z, "col": col, "row": row},
                    num_threads=torch.get_num_threads()).blocked_autorange(min_run_time=1.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--scenes", default="crease,cornell_box")
    ap.add_argument("--gt-radius", type=float, default=0.5)
    ap.add_argument("--rays", type=int, default=256)
    a = ap.parse_args()
    g0 = torch.Generator().manual_seed(0)
    print(f"torch threads {torch.get_num_threads()}, {a.width}x{a.height}")
    for name in a.scenes.split(","):
        g = gbuffer(name, a.width, a.height, channels=["view_z", "normal", "position", "mask"])
        gt = ambient_occlusion(name, g, a.gt_radius, rays=a.rays, weighting="cosine", seed=0)
        m = g.mask
        print(f"\n{name}: cosine GT R={a.gt_radius} ({a.rays} rays, {gt.seconds:.2f} s), mean stderr "
              f"{gt.stderr[m].mean():.4f}")
        print(f"  {'method':8s} {'median ms':>10s} {'IQR ms':>8s} {'floor ms':>9s} {'ratio':>6s} "
              f"{'rmse@def':>9s} {'best r':>7s} {'rmse@best':>9s}")
        for method in AO_METHODS:
            fn, Params, _ = ao_method(method)
            p = Params()
            t = tb.Timer("fn(g, p)", globals={"fn": fn, "g": g, "p": p},
                         num_threads=torch.get_num_threads()).blocked_autorange(min_run_time=1.0)
            fl = gather_floor(g.view_z, samples_per_pixel(method, p), g0)
            rmse = lambda ao: float(((ao - gt.ao)[m] ** 2).mean().sqrt())          # noqa: E731
            r_def = rmse(fn(g, p).ao)
            best = min(((rmse(fn(g, dataclasses.replace(p, **{RADIUS_PARAM[method]: r})).ao), r)
                        for r in (0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 1.0)))
            print(f"  {method:8s} {t.median * 1e3:10.1f} {t.iqr * 1e3:8.1f} {fl.median * 1e3:9.1f} "
                  f"{t.median / fl.median:6.1f} {r_def:9.4f} {best[1]:7.2f} {best[0]:9.4f}")


if __name__ == "__main__":
    main()
