"""SSR marchers: time against the gather floor, and failure classes at equal sample budgets (not a test).

Part 1 times each marcher at its defaults (``torch.utils.benchmark`` blocked autorange, median and IQR) next to
the **gather floor**: a pure ``torch.gather`` of as many depth texels as the pass actually read (its mean
``steps``) per pixel, measured in the same run. Part 2 compares the linear march and the DDA at equal budgets
of depth reads per ray (``iterations`` vs ``max_steps``: fixed strides and ``fit_stride_to_steps``, and the
supercover DDA, one pixel per read; same ``max_ray_distance``), per-pixel classes against the exact mirror
reflections (``ssbench.evaluate.ssr``). The last budget (``--budgets``, default 1024) is "unlimited" for these
sizes: it shows what each traversal misses or punches through when the budget is not the limit.

Run: ``.venv/bin/python benchmarks/bench_ssr.py [--scene reflective_floor --width 640 --height 360]``.
"""
from __future__ import annotations

import argparse

import torch
import torch.utils.benchmark as tb

from ssbench.evaluate import ssr as evaluate_ssr
from ssbench.passes import SSR_METHODS, ssr_method
from ssbench.passes.common import fetch
from ssbench.reference import gbuffer

CLASSES = ("correct", "missed", "false_hit", "punch_through", "off_screen_target", "occluded_target",
           "back_face_target", "true_miss")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scene", default="reflective_floor")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--budgets", default="16,32,64,1024")
    ap.add_argument("--distance", type=float, default=10.0)
    ap.add_argument("--reflective", default="specular", help="'specular' (mirror/smooth pixels) or 'all'")
    ap.add_argument("--skip-timing", action="store_true")
    a = ap.parse_args()
    g = gbuffer(a.scene, a.width, a.height, channels=["view_z", "normal", "position", "mask", "color"], spp=16)
    gen = torch.Generator().manual_seed(0)
    print(f"{a.scene} {a.width}x{a.height}, torch threads {torch.get_num_threads()}")
    print(f"  {'method':14s} {'median ms':>10s} {'IQR':>6s} {'reads/px':>9s} {'floor ms':>9s} {'ratio':>6s}")
    for name in () if a.skip_timing else SSR_METHODS:
        fn, Params, _ = ssr_method(name)
        p = Params()
        res = fn(g, p)
        k = max(1, round(float(res.steps.float().mean())))
        t = tb.Timer("fn(g, p)", globals={"fn": fn, "g": g, "p": p},
                     num_threads=torch.get_num_threads()).blocked_autorange(min_run_time=2.0)
        col = torch.randint(0, a.width, (1, k, a.height, a.width), generator=gen)
        row = torch.randint(0, a.height, (1, k, a.height, a.width), generator=gen)
        fl = tb.Timer("fetch(z, c, r)", globals={"fetch": fetch, "z": g.view_z, "c": col, "r": row},
                      num_threads=torch.get_num_threads()).blocked_autorange(min_run_time=1.0)
        print(f"  {name:14s} {t.median * 1e3:10.1f} {t.iqr * 1e3:6.1f} {k:9d} {fl.median * 1e3:9.1f} "
              f"{t.median / fl.median:6.1f}")

    print(f"\nequal budgets of depth reads per ray (max_ray_distance {a.distance}); class fractions of reflective px")
    print("  " + f"{'config':40s} {'ms':>7s} " + " ".join(f"{c[:9]:>9s}" for c in CLASSES))
    for budget in (int(b) for b in a.budgets.split(",")):
        configs = [("linear", {"iterations": budget, "max_ray_distance": a.distance})]
        configs += [("dda", {"max_steps": budget, "pixel_stride": s, "max_ray_distance": a.distance})
                    for s in (1.0, 2.0, 4.0, 8.0)]
        configs += [("dda", {"max_steps": budget, "fit_stride_to_steps": True, "max_ray_distance": a.distance})]
        configs += [("dda_supercover", {"max_steps": budget, "max_ray_distance": a.distance})]
        for method, params in configs:
            row = evaluate_ssr(a.scene, method, params, width=a.width, height=a.height, repeats=1, spp=16,
                               reflective=None if a.reflective == "all" else a.reflective)
            label = f"{method} " + ",".join(k if v is True else f"{k}={v:g}" for k, v in params.items()
                                            if k != "max_ray_distance")
            print(f"  {label:40s} {row['seconds'] * 1e3:7.1f} "
                  + " ".join(f"{row.get('frac_' + c, float('nan')):9.4f}" for c in CLASSES))


if __name__ == "__main__":
    main()
