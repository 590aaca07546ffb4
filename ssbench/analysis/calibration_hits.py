"""Calibration of the hit classes (see :mod:`ssbench.analysis.calibration` for the idea and :class:`Response`).

* :func:`ssr_response` — SSR classes against the knobs that cause them (SSR article, mebiusbox,
  「スクリーンスペース・リフレクション (SSR)」, 2022,
  https://zenn.dev/mebiusbox/articles/43ecf1bb12831c): the linear march's
  ``thickness`` (too thick invents *false* hits, too thin *misses*, Figs. 4–6) and the DDA's ``pixel_stride``
  without refinement (a coarse stride lands on the right surface pixels off: *misplaced* hits);
* :func:`punch_through_response` — implicit ray casting (progressive-tracing article, 「陰的に定義された曲面の漸進的レイトレーシング」,
  2016, https://www.shadertoy.com/view/XsdSR7): the fixed-step march's step count on the thin shell, where
  steps longer than the shell jump through it.
"""
from __future__ import annotations

from typing import Sequence

from .calibration import Response

__all__ = ["ssr_response", "punch_through_response"]


def _zeros(xs) -> tuple:
    return tuple(0.0 for _ in xs)


def ssr_response(scene: str = "fence", thicknesses: Sequence[float] = (0.02, 0.1, 0.5, 2.0, 10.0),
                 strides: Sequence[float] = (1.0, 2.0, 4.0, 8.0, 16.0), *, width: int = 160, height: int = 120,
                 spp: int = 4, use_cache: bool = True) -> list[Response]:
    """Class shares of the reflective pixels over the linear march's ``thickness`` (false hits rise, misses
    fall) and the DDA's ``pixel_stride`` with ``refinement="none"`` (misplaced hits rise)."""
    from .. import reference
    from ..evaluate import run_ssr
    from ..evaluate._ssr import reflections_module
    g = reference.gbuffer(scene, width, height, channels=("view_z", "normal", "mask", "color", "position",
                                                          "shape_id", "metallic", "roughness"),
                          spp=spp, use_cache=use_cache)
    truth = reflections_module()(scene, g, spp=spp, seed=0, use_cache=use_cache)
    common = dict(width=width, height=height, spp=spp, repeats=1, warmup=False, gbuffer=g, truth=truth,
                  flip=False, use_cache=use_cache)
    lin = [run_ssr(scene, "linear", {"thickness": t, "jitter": 0.0}, **common).row for t in thicknesses]
    dda = [run_ssr(scene, "dda", {"pixel_stride": s, "refinement": "none", "jitter": 0.0}, **common).row
           for s in strides]
    note = f"{width}×{height}, exact mirror reflections, hit tolerance 1.5 px"
    out = [Response("frac_false_hit", "thickness", scene, "linear: false hits (wrong surface)", tuple(thicknesses),
                    tuple(r["frac_false_hit"] for r in lin), _zeros(thicknesses), "rises", 1, note),
           Response("frac_missed", "thickness", scene, "linear: missed hits", tuple(thicknesses),
                    tuple(r["frac_missed"] for r in lin), _zeros(thicknesses), "falls", 1, note),
           Response("frac_misplaced_hit", "pixel_stride", scene, "DDA without refinement: misplaced hits",
                    tuple(strides), tuple(r["frac_misplaced_hit"] for r in dda), _zeros(strides), "rises", 1, note)]
    return out


def punch_through_response(scene: str = "thin_shell", steps: Sequence[int] = (8, 16, 32, 64, 128), *,
                           width: int = 96, height: int = 72, use_cache: bool = True) -> list[Response]:
    """``punch_through_rate`` (share of the truth's hits the march passes through) of the fixed-step march over
    its step count: longer steps than the shell's thickness jump through it."""
    from ..evaluate import run_implicit
    ys = [run_implicit(scene, "fixed", {"steps": n}, width=width, height=height, lipschitz_samples=0,
                       use_cache=use_cache).row["punch_through_rate"] for n in steps]
    return [Response("punch_through_rate", "steps", scene, "fixed-step march", tuple(steps), tuple(ys),
                     _zeros(steps), "falls", 1, f"{width}×{height}, one frame, certified interval truth")]
