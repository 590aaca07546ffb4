"""SSR marchers at equal depth-read budgets (``ssbench.analysis.equal_reads``): classes per method × budget.

Every SSR method that declares ``READ_BUDGET`` runs with ``N`` reads per ray at the shared equal settings (ray
length and thickness scaled to the scene); the table gives the share of reflective pixels that are correct,
missed, false hits and punch-through against the exact mirror hit. A benchmark, not a test:
``.venv/bin/python benchmarks/bench_ssr_reads.py [--scenes reflective_floor,fence,glossy_ramp --size 320x240
--budgets 8,32,128 --layers front,back_faces,second_layer --json rows.json]`` (``--layers``: the depth models).
"""
from __future__ import annotations

import argparse
import json

import torch

from ssbench.analysis.equal_reads import READ_BUDGETS, equal_read_rows, equal_read_table
from ssbench.evaluate import SSR_GT_CHANNELS
from ssbench.evaluate._ssr import reflections_module
from ssbench.reference import gbuffer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", default="reflective_floor,fence,glossy_ramp")
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--budgets", default=",".join(map(str, READ_BUDGETS)))
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--layers", default="front",
                    help="comma-separated depth models: front (the depth buffer), back_faces (each texel a slab down to "
                         "its back face), second_layer (also the surface behind the first)")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    a = ap.parse_args()
    torch.set_num_threads(1)
    w, h = (int(v) for v in a.size.split("x"))
    chans = ("view_z", "normal", "mask", "color", "metallic", "roughness", "back_z", "second_z") + tuple(SSR_GT_CHANNELS)
    rows = []
    for scene in a.scenes.split(","):
        g = gbuffer(scene, w, h, channels=tuple(dict.fromkeys(chans)), spp=a.spp, use_cache=True)
        truth = reflections_module()(scene, g, spp=a.spp, seed=0, use_cache=True)
        budgets = [int(b) for b in a.budgets.split(",")]
        for layers in a.layers.split(","):
            rows += equal_read_rows(scene, g, truth, budgets=budgets, layers=layers)
    print(f"{a.size}, reads = mean depth reads per reflective pixel; classes as shares of reflective pixels")
    print(equal_read_table(rows))
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump([{k: v for k, v in r.items() if not isinstance(v, torch.Tensor)} for r in rows], f, indent=1,
                      default=str)


if __name__ == "__main__":
    main()
