"""Visibility-bitmask AO on a band of image rows: per slice, the projected normal (as GTAO), then every sample's
occluded arc between its front face and its back face (the front pushed ``thickness`` away from the camera)
marked in a bitfield of sectors, and the slice's visibility from the bits left clear (Therrien, Levesque and
Gilet 2023, "Screen Space Indirect Lighting with Visibility Bitmask", §3, and the authors' HLSL notes).
:func:`ssbench.passes.ao.vbao.vbao` runs it band by band.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import torch

from ..compiled import kernel
from .gtao_parts import dot3, slice_frame, unit3
from .slice_samples import pixel_rays, slice_offsets

if TYPE_CHECKING:
    from .vbao import VBAOParams

__all__ = ["vbao_rows", "popcount", "sector_bits", "as_unsigned", "cosine_arc", "R1"]

R1 = 0.6180339887498948482     #: golden-ratio step noise (as GTAO)


def popcount(x: torch.Tensor) -> torch.Tensor:
    """Set bits of each int64 ``x`` below bit 32 (SWAR, no lookup).

    Example:
        >>> popcount(torch.tensor([0, 1, 0b1011, 2 ** 32 - 1])).tolist()
        [0, 1, 3, 32]
    """
    x = x - ((x >> 1) & 0x55555555)
    x = (x & 0x33333333) + ((x >> 2) & 0x33333333)
    x = (x + (x >> 4)) & 0x0F0F0F0F
    return ((x * 0x01010101) & 0xFFFFFFFF) >> 24


def sector_bits(lo: torch.Tensor, hi: torch.Tensor, sectors: int) -> torch.Tensor:
    """``UpdateSectors``: the bits of the sectors an arc ``[lo, hi] ⊂ [0, 1]`` of the slice covers — from
    ``floor(lo·N)``, ``ceil((hi − lo)·N)`` of them (the paper's and Blender's formula: a sample needs only touch a
    sector's width to occlude one), within the ``N ≤ 32`` sectors. The count follows the arc's width, not its end, so
    an arc straddling a sector edge can leave its last touched sector clear.

    The bits are the shader's one ``uint`` held in int32 (sector 31 is the sign bit; :func:`as_unsigned` reads them
    as a number): on the CPU int32 operations vectorise where int64 ones do not (AVX2 has no 64-bit multiply and
    no 64-bit float conversion), so the pass's bit arithmetic ran 2× faster. A shift by 32 gives 0, as ATen
    shifts, and ``(1 << 32) − 1`` all 32 bits.

    Example:
        >>> bin(int(sector_bits(torch.tensor(0.25), torch.tensor(0.5), 8)))
        '0b1100'
        >>> int(sector_bits(torch.tensor(0.0), torch.tensor(1.0), 32)), int(as_unsigned(torch.tensor(-1)))
        (-1, 4294967295)
    """
    start = torch.floor(lo * sectors).to(torch.int32).clamp(0, sectors)
    count = torch.ceil((hi - lo) * sectors).to(torch.int32).clamp(0, sectors)
    bits = ((1 << count) - 1) << start
    return bits if sectors == 32 else bits & ((1 << sectors) - 1)


def as_unsigned(bits: torch.Tensor) -> torch.Tensor:
    """The int32 sector bits of :func:`sector_bits` as the unsigned 32-bit numbers they stand for, in int64."""
    return bits.long() & 0xFFFFFFFF


def cosine_arc(theta: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """``F(θ) = ∫₀^θ cos(t − n)·|sin t| dt``: GTAO's slice integral as a function of one bound, so a sector
    ``[θa, θb]`` carries ``F(θb) − F(θa)`` of the cosine-weighted slice (``a(h)`` of
    :func:`~ssbench.passes.ao.gtao_parts.slice_visibility`, signed by the side of the view vector)."""
    return torch.sign(theta) * (torch.cos(n) + 2.0 * theta * torch.sin(n) - torch.cos(2.0 * theta - n)) / 4.0


@kernel
def vbao_rows(cam, tex: torch.Tensor, row: torch.Tensor, normal: torch.Tensor, mask: torch.Tensor,
              noise: torch.Tensor, params: "VBAOParams", debug: bool, bent_normals: bool = False) -> tuple:
    """``(vis, debug, bent)`` of a band of rows: ``vis`` :math:`(B, 1, h, W)` the slice mean of the visibility;
    with ``debug`` the per-slice ``(bits, slice visibility)`` :math:`(B, S, h, W)`; with ``bent_normals`` the
    unnormalised bent normal ``(x, y, z)``: every clear sector's centre direction in its slice, weighted by its
    cosine share and ``|proj n|`` (as GTAO's Algorithm 2 weights its visible arc), summed over slices.

    ``tex`` :math:`(B, C, H, W)` is what the samples read of the sanitised depth texture of the whole image, its
    last channel the view z (:func:`~ssbench.passes.ao.slice_samples.sample_texture`); ``row`` :math:`(h,)` the
    band's rows; ``normal``, ``mask``, ``noise`` the band's :math:`(B, ·, h, W)` slices."""
    # ---- the pixel: position, view vector V, screen radius (3-vectors are (x, y, z) tuples of (B, 1, h, W)) ----
    B, _, H, W = tex.shape
    dtype, dev, S, K, NS = tex.dtype, tex.device, params.slices, params.steps, params.sector_count
    row = row.view(1, 1, -1, 1)
    zc = torch.index_select(tex[:, -1:], 2, row.view(-1).long())
    col = torch.arange(W, dtype=dtype, device=dev).view(1, 1, 1, W)
    ray_x, ray_y = pixel_rays(cam, col, row, H, W)                                   # view x, y at z = -1
    P = (ray_x * -zc, ray_y * -zc, zc)
    v = unit3(tuple(-c for c in P))                                                  # V: toward the camera
    N = tuple(torch.where(mask, normal[:, i:i + 1], v[i]) for i in range(3))
    r_px = params.radius * cam.focal * H / (2.0 * -zc)                               # radius in pixels
    min_s = params.min_offset_pixels / r_px
    tiny = torch.finfo(dtype).tiny
    j = torch.arange(K, dtype=dtype, device=dev).view(1, K, 1, 1)
    ones = torch.ones(K, dtype=dtype, device=dev)
    side = torch.cat([ones, -ones]).view(1, -1, 1, 1)                                # +1 one side, -1 the other
    vis = torch.zeros_like(zc)
    dbg_bits, dbg_vis = [], []
    bent = [torch.zeros_like(zc) for _ in range(3)] if bent_normals else None

    for k in range(S):
        # ---- the slice: direction, projected normal and its angle n from V (as GTAO) ----
        phi = (k + noise[:, :1]) / S * math.pi
        cos_phi, sin_phi = torch.cos(phi), torch.sin(phi)
        o, proj_len, n = slice_frame(cos_phi, sin_phi, v, N)
        # ---- the samples: K per side at pixel-centre-rounded offsets (off screen: ignored) ----
        step_noise = torch.frac(noise[:, 1:] + (k + j * K) * R1)
        s = ((j + step_noise) / K) ** params.sample_distribution_power + min_s
        off_x, off_y = torch.round(s * cos_phi * r_px), torch.round(-s * sin_phi * r_px)  # screen y down
        front, on = slice_offsets(cam, tex, col, row, off_x, off_y, P)              # frontDir (B, 2K, h, W)
        back = tuple(front[i] - v[i] * params.thickness for i in range(3))          # backDir: `thickness` behind
        dist = dot3(front, front).sqrt()
        t_front = side * torch.acos((dot3(front, v) / dist.clamp_min(tiny)).clamp(-1.0, 1.0))
        t_back = side * torch.acos((dot3(back, v) / dot3(back, back).sqrt().clamp_min(tiny)).clamp(-1.0, 1.0))
        # ---- angles → positions in the normal-centred half circle [0, 1], then the sectors they cover ----
        x_front = ((t_front - n + math.pi / 2) / math.pi).clamp(0.0, 1.0)
        x_back = ((t_back - n + math.pi / 2) / math.pi).clamp(0.0, 1.0)
        bits = sector_bits(torch.minimum(x_front, x_back), torch.maximum(x_front, x_back), NS)
        bits = torch.where((on != 0) & (dist > tiny), bits, torch.zeros_like(bits))       # on: bool or 0/1
        occluded = bits                                         # OR over the samples, halving: log2(2K) ops
        while occluded.shape[1] > 1:
            half = occluded.shape[1] // 2
            occluded = torch.cat([occluded[:, :half] | occluded[:, half:2 * half], occluded[:, 2 * half:]], 1) \
                if occluded.shape[1] % 2 else occluded[:, :half] | occluded[:, half:]
        # ---- the slice's visibility from the clear sectors (and their directions for the bent normal) ----
        if params.weighting == "cosine" or bent is not None:                       # each clear sector's cosine share
            edges = [cosine_arc(n - math.pi / 2 + math.pi * i / NS, n) for i in range(NS + 1)]
            shares = [torch.where((occluded >> i) & 1 == 1, 0.0, edges[i + 1] - edges[i]) for i in range(NS)]
        if params.weighting == "uniform":                                           # the paper: 1 − count/N
            local = 1.0 - popcount(as_unsigned(occluded)).to(dtype) / NS
        else:
            local = torch.zeros_like(vis)
            for share in shares:
                local = local + share
            local = proj_len * local
        vis = vis + local
        if bent is not None:                          # clear sectors' centre directions, cosine-share weighted
            o_hat = unit3(o)
            for i, share in enumerate(shares):
                theta = n - math.pi / 2 + math.pi * (i + 0.5) / NS
                w, s_t, c_t = share * proj_len, torch.sin(theta), torch.cos(theta)
                bent = [bent[j] + w * (s_t * o_hat[j] + c_t * v[j]) for j in range(3)]
        if debug:
            dbg_bits.append(as_unsigned(occluded))
            dbg_vis.append(local)
    return vis / S, ((torch.cat(dbg_bits, 1), torch.cat(dbg_vis, 1)) if debug else None), bent
