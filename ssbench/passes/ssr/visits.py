"""Visit maps (SSR article Fig. 11): which depth texels a ray's march fetches vs the pixels its segment crosses.

:func:`crossed_pixels` is an independent float64 Amanatides–Woo traversal of one segment; :func:`visit_map` runs
one ray of :func:`~ssbench.passes.ssr.dda.ssr_dda` (one fetch per major-axis line) or of
:func:`~ssbench.passes.ssr.dda_supercover.ssr_dda_supercover` (every crossed pixel once) with a visit counter.
(The linear march's visit map is ``ssr_linear(..., debug=True).debug["visits"]``.)
"""
from __future__ import annotations

import math
from typing import Optional, Union

import torch

from ...gbuffer import GBuffer
from . import dda as D
from .dda_rays import dda_rays
from . import dda_supercover as S
from .dda_supercover_walk import supercover_march
from ..common import make_generator

__all__ = ["crossed_pixels", "visit_map"]


def crossed_pixels(p0, p1, height: int, width: int) -> torch.Tensor:
    """:math:`(H, W)` bool: the pixels the segment ``p0 → p1`` (pixel coordinates) passes through.

    Amanatides–Woo cell traversal in float64, independent of the DDA; through a lattice corner it steps diagonally.
    """
    out = torch.zeros(height, width, dtype=torch.bool)
    (x0, y0), (x1, y1) = (float(v) for v in p0), (float(v) for v in p1)
    x, y, dx, dy = math.floor(x0), math.floor(y0), x1 - x0, y1 - y0
    sx, sy = (1 if dx > 0 else -1), (1 if dy > 0 else -1)
    tx = ((x + (sx > 0)) - x0) / dx if dx else math.inf                           # t of the next column edge
    ty = ((y + (sy > 0)) - y0) / dy if dy else math.inf                           # t of the next row edge
    ddx, ddy = (abs(1.0 / dx) if dx else math.inf), (abs(1.0 / dy) if dy else math.inf)
    while True:
        if 0 <= x < width and 0 <= y < height:
            out[y, x] = True
        if min(tx, ty) > 1.0:
            return out
        stepx, stepy = tx <= ty, ty <= tx
        x, tx = (x + sx, tx + ddx) if stepx else (x, tx)
        y, ty = (y + sy, ty + ddy) if stepy else (y, ty)


def visit_map(gbuffer: GBuffer, params: Union[D.DDASSRParams, S.SupercoverDDASSRParams] = D.DDASSRParams(),
              pixel=(0, 0), *, generator: Optional[torch.Generator] = None) -> dict:
    """SSR article Fig. 11 for the ray of ``pixel = (x, y)`` (batch item 0, on ``mask``): fetched vs crossed texels.

    ``params`` picks the march: :class:`~ssbench.passes.ssr.dda.DDASSRParams` (the article's DDA, jitter as in
    ``ssr_dda``) or :class:`~ssbench.passes.ssr.dda_supercover.SupercoverDDASSRParams` (the supercover walk).

    Returns ``{"visits": (H, W) int32 fetches, "crossed": (H, W) bool`` (:func:`crossed_pixels` of ``P0 → P1``,
    origin pixel included though never sampled), ``"p0", "p1"`` (pixels), ``"termination"}``.
    """
    supercover = isinstance(params, S.SupercoverDDASSRParams)
    dda = params.dda() if supercover else params
    D.check_inputs(gbuffer, dda)
    B, _, H, W = gbuffer.view_z.shape
    x, y = pixel
    if not (0 <= x < W and 0 <= y < H) or not bool(gbuffer.mask[0, 0, y, x]):
        raise ValueError(f"pixel: must be a mask pixel inside the {W}x{H} image, got {pixel!r}")
    jitter = D.jitter_fractions(dda, (B, 1, H, W), make_generator(dda.seed, generator))
    s, sel, P0, P1 = dda_rays(gbuffer, dda, jitter)
    r = int((sel == y * W + x).nonzero()[0, 0])
    one = s.select(torch.tensor([r], device=s.i.device))
    one.i, visits = one.i * 0, torch.zeros(B * H * W, dtype=torch.int32, device=gbuffer.view_z.device)
    tex = D.depth_texels(gbuffer, dda)
    o = supercover_march(one, tex, params.z_thickness, params.max_steps, H, W, visits) if supercover else \
        D.dda_march(one, tex, params, H, W, visits)
    return {"visits": visits[:H * W].reshape(H, W).cpu(), "crossed": crossed_pixels(P0[r], P1[r], H, W),
            "p0": P0[r].tolist(), "p1": P1[r].tolist(), "termination": int(o.term[0])}
