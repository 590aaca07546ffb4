"""From a DDA march's per-ray outputs to the :class:`~ssbench.passes.ssr.common.SSRResult` images (SSR article §2.2,
§1.4–1.5): the colour at the hit texel, the fades, and the debug buffers. Shared by the DDA
(:mod:`.dda`), the supercover DDA (:mod:`.dda_supercover`) and the supercover's teaching twin."""
from __future__ import annotations

from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..common import fetch_texels, length
from .common import HIT, NO_RAY, SSRResult, unflat
from .dda_state import MarchOutput

__all__ = ["assemble"]


def assemble(gbuffer: GBuffer, params, sel: torch.Tensor, P1: torch.Tensor, o: MarchOutput,
             visits: Optional[torch.Tensor]) -> SSRResult:
    """Per-ray march outputs ``o`` (:class:`~ssbench.passes.ssr.dda_state.MarchOutput`) of the rays ``sel`` → the
    :class:`SSRResult` images: colour at the hit texel, fades (``params``' edge/distance fields), ``debug``
    (``visits``, ``ray_end``) when ``visits`` is given. Shared by :func:`ssr_dda` and the supercover DDA."""
    cam, (B, _, H, W) = gbuffer.camera, gbuffer.view_z.shape
    dt, dev = gbuffer.view_z.dtype, gbuffer.view_z.device

    def image(values, fill, dtype=dt):                                            # per-ray (N, C) -> (B, C, H, W)
        return unflat(values, sel, fill, (B, H, W), dtype)

    is_hit = (o.term == HIT)[:, None]
    term, steps = image(o.term[:, None], NO_RAY, torch.int8), image(o.steps[:, None], 0, torch.int32)
    hit_pixel = image(torch.where(is_hit, o.P, -1.0), -1.0)
    hit_view = image(torch.where(is_hit, o.Q / o.k[:, None], 0.0), 0.0)
    hit = term == HIT                                                             # (B, 1, H, W)
    # the texel is floored in the march's own dtype: a hit at 8.999999999999998 must not round to 9 first
    texel = image(torch.where(is_hit, o.P, 0.0).floor(), 0.0, torch.float64)
    col, row = texel[:, 0].clamp(0, W - 1), texel[:, 1].clamp(0, H - 1)          # (float64: exact indices)
    lo, hi = texel.to(dt), torch.nextafter((texel + 1).to(dt), texel.to(dt))      # and hit_pixel stays in it
    hit_pixel = torch.where(hit, torch.minimum(torch.maximum(hit_pixel, lo), hi), hit_pixel)
    raw = torch.where(hit, fetch_texels(gbuffer.color.to(dt), col, row), 0.0)            # (B, 3, H, W)
    origin = cam.uv_to_view(cam.uv_grid(dt, dev).unsqueeze(0), gbuffer.view_z)
    fade = params.fade(hit_pixel, cam.pixel_centers(dt, dev)[None], W, H, length(hit_view - origin))
    fade = torch.where(hit, fade, 0.0)
    dbg = {"visits": visits.reshape(B, 1, H, W), "ray_end": image(P1, -1.0)} if visits is not None else {}
    return SSRResult(color=raw * fade, hit=hit, hit_pixel=hit_pixel, hit_view=hit_view, steps=steps,
                     termination=term, fade=fade, raw_color=raw, debug=dbg)
