"""From a DDA march's per-ray outputs to the :class:`~ssbench.passes.ssr.common.SSRResult` images (SSR article §2.2,
§1.4–1.5): the colour at the hit texel, the fades, and the debug buffers. Shared by the DDA
(:mod:`.dda`), the supercover DDA (:mod:`.dda_supercover`) and the supercover's teaching twin."""
from __future__ import annotations

from typing import Optional

import torch

from ...gbuffer import GBuffer
from ...indices import flat_nonzero
from ..common import channel_rows, flat_texel, index_dtype, length
from .common import HIT, NO_RAY, SSRResult, split_rays, unflat
from .dda_state import MarchOutput

__all__ = ["assemble"]


def assemble(gbuffer: GBuffer, params, sel: torch.Tensor, P1: torch.Tensor, o: MarchOutput,
             visits: Optional[torch.Tensor]) -> SSRResult:
    """Per-ray march outputs ``o`` (:class:`~ssbench.passes.ssr.dda_state.MarchOutput`) of the rays ``sel`` → the
    :class:`SSRResult` images: colour at the hit texel, fades (``params``' edge/distance fields), ``debug``
    (``visits``, ``ray_end``) when ``visits`` is given. Shared by :func:`ssr_dda` and the supercover DDA.

    The hit pixel, its texel's colour and the fades are computed for the hit rays only (rows of the ``m`` hits,
    each value by the same operations as a whole image of them would take: the same bits) and scattered into
    images whose other pixels hold the miss values (−1, 0)."""
    cam, (B, _, H, W) = gbuffer.camera, gbuffer.view_z.shape
    dt, HW = gbuffer.view_z.dtype, H * W

    def image(values, fill, dtype=dt, rows=sel):                                  # per-ray (N, C) -> (B, C, H, W)
        return unflat(values, rows, fill, (B, H, W), dtype)

    term, steps = image(o.term[:, None], NO_RAY, torch.int8), image(o.steps[:, None], 0, torch.int32)
    hit = term == HIT                                                             # (B, 1, H, W)
    h = flat_nonzero(o.term == HIT)
    at = sel.index_select(0, h)                                                   # (m,) the hit rays' pixels
    P = o.P.index_select(0, h)                                                    # (m, 2) in the march's dtype
    hit_view = (o.Q.index_select(0, h) / o.k.index_select(0, h)[:, None]).to(dt)  # (m, 3)
    # the texel is floored in the march's own dtype: a hit at 8.999999999999998 must not round to 9 first
    texel = P.floor().to(torch.float64)
    col, row = texel[:, 0].clamp(0, W - 1), texel[:, 1].clamp(0, H - 1)          # (float64: exact indices)
    lo, hi = texel.to(dt), torch.nextafter((texel + 1).to(dt), texel.to(dt))      # and hit_pixel stays in it
    hit_pixel = torch.minimum(torch.maximum(P.to(dt), lo), hi)                    # (m, 2)
    index = flat_texel(col, row, (H, W), index_dtype(B * HW))
    px = split_rays(at, B, HW)[1]                                                 # the hit rays' pixels
    if B > 1:
        index = index + (at - px).to(index.dtype)                                 # the image's offset b·H·W
    raw = channel_rows(gbuffer.color.to(dt)).index_select(1, index).T            # (m, 3)
    z = gbuffer.view_z.reshape(-1).index_select(0, at)[None, None, :, None]
    centre = cam.pixel_centers_at(px, dt)                                         # (2, m) the rays' pixels
    uv = cam.pixel_to_uv(centre, dim=0)[None, :, :, None]                         # (uv_grid's values there)
    origin = cam.uv_to_view(uv, z)[0, :, :, 0].T                                  # (m, 3) rayOrg
    distance = length(hit_view - origin)                                          # (m, 1) |rayOrg − hitPoint|
    centre = centre.T                                                             # (m, 2)
    fade = params.fade(hit_pixel, centre, W, H, distance)                         # (m, 1)
    dbg = {"visits": visits.reshape(B, 1, H, W), "ray_end": image(P1, -1.0)} if visits is not None else {}
    raw_i, fade_i = image(raw, 0.0, rows=at), image(fade, 0.0, rows=at)
    return SSRResult(color=image(raw * fade, 0.0, rows=at), hit=hit, hit_pixel=image(hit_pixel, -1.0, rows=at),
                     hit_view=image(hit_view, 0.0, rows=at), steps=steps, termination=term, fade=fade_i,
                     raw_color=raw_i, debug=dbg)
