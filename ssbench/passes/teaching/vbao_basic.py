"""Visibility-bitmask AO, one pixel at a time: the per-pixel loop of Therrien, Levesque and Gilet, "Screen Space
Indirect Lighting with Visibility Bitmask" (2023, https://arxiv.org/abs/2301.11376), with the names of the
authors' HLSL notes (``V``, ``sliceN``, ``projN``, ``N`` (here ``n``), ``frontDir``, ``backDir``,
``frontBackHorizon``, ``UpdateSectors``, ``countbits``), one function per step:

1. :func:`slice_frame` — the slice through ``V`` along the screen direction ``φ``: its tangent, the normal
   projected into it and that normal's angle ``n`` from ``V``;
2. :func:`sample_pixel` — where a sample of the slice lands (pixel-centre rounded);
3. :func:`front_back_angles` — the sample's front face and its back face ``thickness`` farther, as angles from
   ``V`` shifted to the normal-centred half circle ``[0, 1]``;
4. :func:`update_sectors` — the bits of the sectors that arc touches, OR-ed into the slice's bitfield;
5. :func:`slice_visibility` — the share of clear sectors (or their cosine shares).

It reads the same noise as :func:`ssbench.passes.ao.vbao.vbao` and makes the same choices, so the two agree
(``tests/passes/ao/test_vbao.py``). Use the vectorised pass for anything but a thumbnail.
"""
from __future__ import annotations

import math
from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..common import AOResult
from ..ao.gtao_parts import noise_buffer
from ..ao.vbao import VBAOParams, check_inputs

R1 = 0.6180339887498948482       # golden-ratio step noise
TINY = torch.finfo(torch.float64).tiny


def _unit(a):
    inv = 1.0 / max(math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]), TINY)
    return (a[0] * inv, a[1] * inv, a[2] * inv)


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def slice_frame(phi: float, V: tuple, normal: tuple) -> tuple:
    """Step 1: ``(direction, projN length, n)`` of the slice at screen angle ``phi``."""
    direction = (math.cos(phi), math.sin(phi))
    dv = direction[0] * V[0] + direction[1] * V[1]
    ortho = (direction[0] - dv * V[0], direction[1] - dv * V[1], -dv * V[2])      # the slice tangent
    axis = _unit((ortho[1] * V[2] - ortho[2] * V[1], ortho[2] * V[0] - ortho[0] * V[2],
                  ortho[0] * V[1] - ortho[1] * V[0]))                              # sliceN
    na = _dot(normal, axis)
    projN = tuple(normal[i] - axis[i] * na for i in range(3))
    projLen = math.sqrt(_dot(projN, projN))
    cosN = min(max(_dot(projN, V) / max(projLen, TINY), 0.0), 1.0)
    sign = (_dot(ortho, projN) > 0) - (_dot(ortho, projN) < 0)
    return direction, projLen, sign * math.acos(cosN)


def sample_pixel(col: int, row: int, direction: tuple, s: float, screenRadius: float, side: int) -> tuple:
    """Step 2: the texel a sample at distance ``s`` (a fraction of the radius) on ``side`` ±1 reads."""
    dx, dy = round_half_even(s * direction[0] * screenRadius), round_half_even(-s * direction[1] * screenRadius)
    return col + side * dx, row + side * dy


def round_half_even(x: float) -> float:
    """``torch.round``: halves to even."""
    return float(round(x))


def front_back_angles(frontDir: tuple, V: tuple, thickness: float, n: float, side: int) -> tuple:
    """Step 3: ``(min, max)`` of the front and back horizons in the normal-centred half circle ``[0, 1]``."""
    backDir = tuple(frontDir[i] - V[i] * thickness for i in range(3))
    horizon = []
    for d in (frontDir, backDir):
        c = min(max(_dot(d, V) / max(math.sqrt(_dot(d, d)), TINY), -1.0), 1.0)
        theta = side * math.acos(c)
        horizon.append(min(max((theta - n + math.pi / 2) / math.pi, 0.0), 1.0))
    return min(horizon), max(horizon)


def update_sectors(bitfield: int, lo: float, hi: float, sectors: int) -> int:
    """Step 4, ``UpdateSectors``: OR in the ``ceil((hi − lo)·N)`` sectors from ``floor(lo·N)``."""
    start = min(max(math.floor(lo * sectors), 0), sectors)
    count = min(max(math.ceil((hi - lo) * sectors), 0), sectors)
    return bitfield | ((((1 << count) - 1) << start) & ((1 << sectors) - 1))


def slice_visibility(bitfield: int, sectors: int, weighting: str, n: float, projLen: float) -> float:
    """Step 5: ``1 − countbits/N`` (the paper), or the clear sectors' shares of the cosine slice integral."""
    if weighting == "uniform":
        return 1.0 - bin(bitfield).count("1") / sectors

    def arc(t):                                       # ∫₀^t cos(u − n)|sin u| du
        sign = (t > 0) - (t < 0)
        return sign * (math.cos(n) + 2.0 * t * math.sin(n) - math.cos(2.0 * t - n)) / 4.0
    total = 0.0
    for i in range(sectors):
        if not (bitfield >> i) & 1:
            total += arc(n - math.pi / 2 + math.pi * (i + 1) / sectors) - arc(n - math.pi / 2 + math.pi * i / sectors)
    return projLen * total


def vbao_basic(gbuffer: GBuffer, params: VBAOParams = VBAOParams(),
               generator: Optional[torch.Generator] = None) -> AOResult:
    """Per-pixel visibility-bitmask AO; returns :class:`AOResult` with ``ao`` :math:`(B, 1, H, W)` like
    :func:`~ssbench.passes.ao.vbao.vbao`."""
    check_inputs(gbuffer, params)
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    S, K, NS = params.slices, params.steps, params.sector_count
    noise = noise_buffer(params, B, H, W, generator).tolist()
    mask = gbuffer.mask.tolist()
    depth = torch.where(gbuffer.mask, gbuffer.view_z, -cam.far).double().tolist()
    normal = gbuffer.normal.double().tolist()
    viewX = lambda c: (2.0 * (c + 0.5) / W - 1.0) * cam.aspect / cam.focal        # noqa: E731  view x at z = −1
    viewY = lambda r: (1.0 - 2.0 * (r + 0.5) / H) / cam.focal                      # noqa: E731
    ao = [[[[1.0] * W for _ in range(H)]] for _ in range(B)]
    for b in range(B):
        for y in range(H):
            for x in range(W):
                if not mask[b][0][y][x]:
                    continue
                z = depth[b][0][y][x]
                P = (viewX(x) * -z, viewY(y) * -z, z)
                V = _unit((-P[0], -P[1], -P[2]))
                N = tuple(normal[b][i][y][x] for i in range(3))
                screenRadius = params.radius * cam.focal * H / (2.0 * -z)
                minS = params.min_offset_pixels / screenRadius
                visibility = 0.0
                for k in range(S):
                    phi = (k + noise[b][0][y][x]) / S * math.pi
                    direction, projLen, n = slice_frame(phi, V, N)
                    bitfield = 0
                    for side in (1, -1):
                        for j in range(K):
                            stepNoise = math.modf(noise[b][1][y][x] + (k + j * K) * R1)[0]
                            s = ((j + stepNoise) / K) ** params.sample_distribution_power + minS
                            sx, sy = sample_pixel(x, y, direction, s, screenRadius, side)
                            if not (0 <= sx < W and 0 <= sy < H):
                                continue                                     # off screen: ignored
                            zs = depth[b][0][int(sy)][int(sx)]
                            frontDir = (viewX(sx) * -zs - P[0], viewY(sy) * -zs - P[1], zs - P[2])
                            if math.sqrt(_dot(frontDir, frontDir)) <= TINY:
                                continue
                            lo, hi = front_back_angles(frontDir, V, params.thickness, n, side)
                            bitfield = update_sectors(bitfield, lo, hi, NS)
                    visibility += slice_visibility(bitfield, NS, params.weighting, n, projLen)
                ao[b][0][y][x] = min(max(visibility / S, 0.0), 1.0)
    return AOResult(ao=torch.tensor(ao, dtype=gbuffer.view_z.dtype))
