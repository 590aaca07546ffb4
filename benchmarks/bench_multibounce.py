"""Multi-bounce AO against its path-traced truth (``ssbench.reference.multibounce``): every AO method at its
defaults with radius 0.5, its AO turned multi-bounce by Jimenez et al.'s fit with the G-buffer's albedo
(``ssbench.metrics.ao_multibounce``), on four catalog scenes at 160×120 with 256 paths per pixel.

Prints, per scene, the truth's RMS standard error, then the RMSE against the multi-bounce truth of: the exact
single-bounce AO (what ignoring interreflection costs), the fit applied to that exact AO (what the fit itself
costs), and each method with the fit (what a renderer that follows the course ships). Run: ``python
benchmarks/bench_multibounce.py`` (a few minutes on 2 cores; the truth is cached after the first run).
"""
from __future__ import annotations

import dataclasses

import torch


def main() -> None:
    from ssbench.evaluate._ao import radius_param
    from ssbench.metrics.ao_multibounce import jimenez_multibounce, multibounce_error
    from ssbench.passes import AO_METHODS, ao_method
    from ssbench.reference import gbuffer
    from ssbench.reference.multibounce import multibounce_ao
    from ssbench.scenes import load
    torch.set_num_threads(1)
    methods = list(AO_METHODS)
    print(f"{'scene':<16}{'truth SE':>9}{'1 bounce':>10}{'fit(exact)':>11}" + "".join(f"{m:>11}" for m in methods))
    for name in ("crease", "cornell_box", "stairs", "furnished_room"):
        sc = load(name)
        g = gbuffer(sc, 160, 120)
        mb = multibounce_ao(sc, g, 0.5, rays=256, seed=0)
        err = lambda pred: multibounce_error(pred, mb.ao, g.mask, mb.stderr)             # noqa: E731
        cells = [err(mb.single.expand(-1, 3, -1, -1)), err(jimenez_multibounce(mb.single, mb.albedo))]
        for m in methods:
            fn, params_cls, _ = ao_method(m)
            p = params_cls()
            key = radius_param(params_cls)
            if key:
                p = dataclasses.replace(p, **{key: 0.5})
            ao = fn(g.to(dtype=torch.float32), p).ao.double()
            cells.append(err(jimenez_multibounce(ao, g.albedo.double())))
        print(f"{name:<16}{cells[0]['truth_stderr']:>9.4f}" + "".join(f"{c['rmse']:>{10 if i == 0 else 11}.4f}"
                                                                     for i, c in enumerate(cells)))


if __name__ == "__main__":
    main()
