"""XeGTAO's main pass on a band of image rows: per slice, the projected normal, the two-sided horizon search and
the analytic slice integral (Jimenez et al. 2016, "Practical Realtime Strategies for Accurate Indirect Occlusion",
Algorithms 1 and 2; Intel's XeGTAO, ``XeGTAO_MainPass``). :func:`ssbench.passes.ao.gtao.gtao` runs it band by band
and applies the final power, denoise and clip; it is the pass's compilable kernel (:mod:`ssbench.passes.compiled`).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import torch

from ..compiled import kernel
from .gtao_parts import dot3, slice_frame, slice_visibility, unit3
from .slice_samples import pixel_rays, slice_offsets

if TYPE_CHECKING:
    from .gtao import GTAOParams

__all__ = ["gtao_rows", "CENTER_Z_BIAS", "SLOPE_FUDGE", "R1"]

CENTER_Z_BIAS = 0.99999        #: XE_GTAO_FP32_DEPTHS: move the centre toward the camera
SLOPE_FUDGE = 0.05             #: |proj n| lerped 5 % toward 1 ("slight overdarkening on high slopes")
R1 = 0.6180339887498948482     #: golden-ratio step noise


@kernel
def gtao_rows(cam, tex: torch.Tensor, row: torch.Tensor, normal: torch.Tensor, mask: torch.Tensor,
              noise: torch.Tensor, params: "GTAOParams", debug: bool, bent_normals: bool) -> tuple:
    """XeGTAO's main pass on a band of rows (Jimenez et al. 2016, Algorithm 1; XeGTAO ``XeGTAO_MainPass``):
    ``(vis, bent, debug)`` before the final power, with every block (B, 2K, h, W); the pass's compilable
    kernel (:mod:`ssbench.passes.compiled`).

    ``tex`` :math:`(B, C, H, W)` is what the samples read of the sanitised depth texture of the whole image, its
    last channel the view z (:func:`~ssbench.passes.ao.slice_samples.sample_texture`; the horizon search reads any row);
    ``row`` :math:`(h,)` the band's row indices; ``normal``, ``mask``, ``noise`` the band's
    :math:`(B, ·, h, W)` slices."""
    # ---- Centre pixel: position, view vector, screen radius (vectors are (x, y, z) tuples of (B, 1, h, W)) ----
    B, _, H, W = tex.shape
    dtype, dev, S, K = tex.dtype, tex.device, params.slices, params.steps
    row = row.view(1, 1, -1, 1)
    zc = torch.index_select(tex[:, -1:], 2, row.view(-1).long()) * CENTER_Z_BIAS
    col = torch.arange(W, dtype=dtype, device=dev).view(1, 1, 1, W)
    ray_x, ray_y = pixel_rays(cam, col, row, H, W)                                   # view x, y at z = -1
    P = (ray_x * -zc, ray_y * -zc, zc)
    v = unit3(tuple(-c for c in P))                                                  # toward the camera
    N = tuple(torch.where(mask, normal[:, i:i + 1], v[i]) for i in range(3))
    R = params.radius * params.radius_multiplier                                     # effect radius
    r_px = R * cam.focal * H / (2.0 * -zc)                                           # (B, 1, h, W) pixels
    min_s = params.min_offset_pixels / r_px
    fr, toc, tiny = params.falloff_range, params.thin_occluder_compensation, torch.finfo(dtype).tiny
    j = torch.arange(K, dtype=dtype, device=dev).view(1, K, 1, 1)
    vis = torch.clamp((10.0 - r_px) / 100.0, 0.0, 1.0) * 0.5                        # small-radius fade
    bent = [0.0, 0.0, 0.0] if bent_normals else None
    dbg_h, dbg_n, dbg_v = [], [], []

    for k in range(S):
        # ---- Slice: direction, projected normal (Algorithm 1, lines 5-15) ----
        phi = (k + noise[:, :1]) / S * math.pi                                       # (B, 1, h, W)
        cos_phi, sin_phi = torch.cos(phi), torch.sin(phi)
        o, proj_len, n = slice_frame(cos_phi, sin_phi, v, N)
        low0, low1 = torch.cos(n + math.pi / 2), torch.cos(n - math.pi / 2)        # lowHorizonCos0/1
        # ---- Horizon search: K steps x 2 sides at once, samples on dim 1 (lines 17-26) ----
        step_noise = torch.frac(noise[:, 1:] + (k + j * K) * R1)                   # (B, K, h, W)
        s = ((j + step_noise) / K) ** params.sample_distribution_power + min_s
        off_x, off_y = torch.round(s * cos_phi * r_px), torch.round(-s * sin_phi * r_px)  # screen y down
        delta, on = slice_offsets(cam, tex, col, row, off_x, off_y, P)   # (B, 2K, h, W); off screen: weight 0
        dist = dot3(delta, delta).sqrt().clamp_min(tiny)
        shc = dot3(delta, v) / dist                                                  # sample horizon cos
        if toc:
            dist = (delta[0] ** 2 + delta[1] ** 2 + (delta[2] * (1.0 + toc)) ** 2).sqrt()
        w = ((dist * (-1.0 / (fr * R)) + ((1.0 - fr) / fr + 1.0)).clamp(0.0, 1.0) if fr > 0
             else (dist <= R).to(dtype)) * on
        hc0 = torch.maximum(low0, (low0 + w[:, :K] * (shc[:, :K] - low0)).amax(1, keepdim=True))
        hc1 = torch.maximum(low1, (low1 + w[:, K:] * (shc[:, K:] - low1)).amax(1, keepdim=True))
        # ---- Integrate the slice (line ~27) ----
        proj_len = proj_len + SLOPE_FUDGE * (1.0 - proj_len)
        h0, h1 = -torch.acos(hc1.clamp(-1.0, 1.0)), torch.acos(hc0.clamp(-1.0, 1.0))
        local = proj_len * slice_visibility(h0, h1, n)
        vis = vis + local
        if bent is not None:                                                         # Algorithm 2
            t0 = (6 * torch.sin(h0 - n) - torch.sin(3 * h0 - n) + 6 * torch.sin(h1 - n) - torch.sin(3 * h1 - n)
                  + 16 * torch.sin(n) - 3 * (torch.sin(h0 + n) + torch.sin(h1 + n))) / 12
            t1 = (-torch.cos(3 * h0 - n) - torch.cos(3 * h1 - n) + 8 * torch.cos(n)
                  - 3 * (torch.cos(h0 + n) + torch.cos(h1 + n))) / 12
            o_hat = unit3(o)
            bent = [bent[i] + proj_len * (t0 * o_hat[i] + t1 * v[i]) for i in range(3)]
        if debug:
            dbg_h.append(torch.stack([hc0, hc1], 2))                                 # (B, 1, 2, H, W)
            dbg_n.append(n)
            dbg_v.append(local)

    debug_out = (torch.cat(dbg_h, 1), torch.cat(dbg_n, 1), torch.cat(dbg_v, 1), r_px) if debug else None
    return vis, bent, debug_out

