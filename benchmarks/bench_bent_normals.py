"""Bent normals against their ray-traced truth: GTAO (defaults at radius 0.5, and ultra quality with a hard cut at
the radius), visibility-bitmask AO (cosine shares, thickness 0.25) and the shading normal as the do-nothing
baseline, on four catalog scenes at 160×120 with 256 rays.

Prints, per scene, the truth's RMS angular error bar and each estimate's mean / 95th-percentile angle error in
degrees (``ssbench.metrics.ao_bent``; pixels with at least one unoccluded ray). Run: ``python
benchmarks/bench_bent_normals.py`` (about a minute on 2 cores, ground truth cached after the first run).
"""
from __future__ import annotations

import torch


def main() -> None:
    from ssbench.metrics.ao_bent import bent_normal_error
    from ssbench.passes.ao.gtao import GTAOParams, gtao
    from ssbench.passes.ao.vbao import VBAOParams, vbao
    from ssbench.reference import gbuffer
    from ssbench.reference.bent_normal import bent_normals
    from ssbench.scenes import load
    torch.set_num_threads(1)
    estimates = {"GTAO defaults": (gtao, GTAOParams(radius=0.5)),
                 "GTAO ultra, hard cut": (gtao, GTAOParams(radius=0.5, quality="ultra", falloff_range=0.0,
                                                           radius_multiplier=1.0)),
                 "VBAO cosine": (vbao, VBAOParams(radius=0.5, weighting="cosine"))}
    print(f"{'scene':<16}{'truth RMS °':>12}{'shading normal':>18}" + "".join(f"{k:>24}" for k in estimates))
    for name in ("crease", "sphere_on_plane", "cornell_box", "stairs"):
        sc = load(name)
        g = gbuffer(sc, 160, 120, channels=["view_z", "normal", "mask", "position"])
        ref = bent_normals(sc, g, 0.5, rays=256, seed=0)
        cells = [bent_normal_error(g.normal, ref.normal, g.mask, ref.stderr_deg)]
        cells += [bent_normal_error(fn(g, p, bent_normals=True).bent_normal, ref.normal, g.mask, ref.stderr_deg)
                  for fn, p in estimates.values()]
        print(f"{name:<16}{cells[0]['truth_stderr_deg']:>12.2f}"
              + "".join(f"{c['mean_deg']:>{18 if i == 0 else 24}.2f}/{c['p95_deg']:.2f}" for i, c in enumerate(cells)))


if __name__ == "__main__":
    main()
