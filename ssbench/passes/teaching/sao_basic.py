"""Scalable Ambient Obscurance, one pixel at a time: the listing of McGuire, Mara and Luebke, "Scalable Ambient
Obscurance" (HPG 2012, https://research.nvidia.com/publication/2012-06_scalable-ambient-obscurance), with its names
(``ssC``, ``C``, ``n_C``, ``ssDiskRadius``, ``tapLocation``, ``getOffsetPosition``, ``sampleAO``,
``intensityDivR6``), one function per step:

1. :func:`minify` — one level of the depth pyramid from the level below (the rotated-grid texel of each 2×2);
2. :func:`reconstruct_cs_position` — ``C`` from a pixel and its depth;
3. :func:`face_normal` — ``n_C`` from the quad's depth derivatives (or the G-buffer's);
4. :func:`tap_location` — the spiral tap's direction and radius share;
5. :func:`get_offset_position` — the tap's pixel, its MIP level, the texel read there and ``Q``;
6. :func:`sample_ao` — one tap's obscurance ``max(r² − v·v, 0)³ · max((v·n − β)/(v·v + ε), 0)``;
7. :func:`quad_filter_pixel` — the free 2×2 filter of the result.

Pixels are ``(x, y)`` with ``y`` up, as ``gl_FragCoord``. It makes the choices of :func:`ssbench.passes.ao.sao.sao`,
so the two agree (``tests/passes/ao/test_sao.py``). Use the vectorised pass for anything but a thumbnail.
"""
from __future__ import annotations

import math

import torch

from ...gbuffer import GBuffer
from ..ao.sao import EPSILON, SAOParams
from ..ao.sao_parts import QUAD_DEPTH_STEP, pixels_per_meter
from ..common import AOResult


def minify(level: list, width: int, height: int) -> tuple[list, int, int]:
    """``(next_level, w, h)``: texel ``(x, y)`` of the next level is ``level[2y + (x & 1)][2x + (y & 1)]``."""
    w, h = max(1, width >> 1), max(1, height >> 1)
    out = [[level[min(2 * y + (x & 1), height - 1)][min(2 * x + (y & 1), width - 1)] for x in range(w)]
           for y in range(h)]
    return out, w, h


def reconstruct_cs_position(camera, x: float, y: float, z: float) -> tuple:
    """``reconstructCSPosition(S, z)``: the camera-space point of screen position ``S = (x, y)`` (pixel units,
    y up) at depth ``z``."""
    uv = torch.tensor([[x / camera.width], [y / camera.height]], dtype=torch.float64).view(1, 2, 1, 1)
    p = camera.uv_to_view(uv, torch.tensor(z, dtype=torch.float64).view(1, 1, 1, 1), dim=1)
    return tuple(float(v) for v in p.view(3))


def face_normal(C: dict, x: int, y: int, width: int, height: int) -> tuple:
    """``normalize(cross(dFdx(C), dFdy(C)))`` within the quad (pairs ``(2k, 2k + 1)``; an odd last pixel takes
    the backward difference); ``C`` maps ``(x, y)`` to positions."""
    def pair(i, n):
        e = i - (i & 1)
        return (e, e + 1) if e + 1 < n else (max(i - 1, 0), i)
    (x0, x1), (y0, y1) = pair(x, width), pair(y, height)
    dx = [a - b for a, b in zip(C[(x1, y)], C[(x0, y)])]
    dy = [a - b for a, b in zip(C[(x, y1)], C[(x, y0)])]
    n = (dx[1] * dy[2] - dx[2] * dy[1], dx[2] * dy[0] - dx[0] * dy[2], dx[0] * dy[1] - dx[1] * dy[0])
    norm = math.sqrt(sum(c * c for c in n))
    return tuple(c / norm for c in n) if 0 < norm < math.inf else (0.0, 0.0, 0.0)


def tap_location(i: int, num_samples: int, turns: int, spin: float) -> tuple:
    """``(unit_offset, alpha)``: ``α = (i + ½)/N``, angle ``α·(turns·6.28) + spin``."""
    alpha = (i + 0.5) * (1.0 / num_samples)
    angle = alpha * (turns * 6.28) + spin
    return (math.cos(angle), math.sin(angle)), alpha


def get_offset_position(camera, mips: list, ssC: tuple, unit: tuple, ssR: float, p: SAOParams) -> tuple:
    """``(Q, mip_level)``: the tap ``ssP = ssC + int(ssR·unit)``, read at level ``clamp(⌊log₂ ssR⌋ −
    LOG_MAX_OFFSET, 0, MAX_MIP_LEVEL)`` at texel ``ssP >> level`` clamped to that level."""
    level = 0
    if p.use_mips and ssR > 0:
        level = min(max(math.floor(math.log2(ssR)) - p.log_max_offset, 0), p.max_mip_level)
    ssP = (ssC[0] + int(ssR * unit[0]), ssC[1] + int(ssR * unit[1]))
    data, w, h = mips[level]
    tx, ty = min(max(ssP[0] >> level, 0), w - 1), min(max(ssP[1] >> level, 0), h - 1)
    return reconstruct_cs_position(camera, ssP[0] + 0.5, ssP[1] + 0.5, data[ty][tx]), level


def sample_ao(C: tuple, n_C: tuple, Q: tuple, p: SAOParams) -> float:
    """``sampleAO``'s tap value for ``v = Q − C``."""
    v = [q - c for q, c in zip(Q, C)]
    vv = sum(a * a for a in v)
    vn = sum(a * b for a, b in zip(v, n_C))
    f = max(p.radius * p.radius - vv, 0.0)
    if not f > 0:
        return 0.0                                     # out of reach
    return f * f * f * max((vn - p.bias) / (EPSILON + vv), 0.0)


def quad_filter_pixel(A: dict, z: dict, x: int, y: int, width: int, height: int) -> float:
    """``A −= dFdx(A)·((x & 1) − ½)`` where ``|dFdx(z)| < 0.02`` (pixels paired ``(2k, 2k + 1)``; an unpaired
    last pixel unchanged), then the same along y on the x-filtered values."""
    def along_x(xx, yy):
        e = xx - (xx & 1)
        if e + 1 >= width or abs(z[(e + 1, yy)] - z[(e, yy)]) >= QUAD_DEPTH_STEP:
            return A[(xx, yy)]
        return A[(xx, yy)] - (A[(e + 1, yy)] - A[(e, yy)]) * ((xx & 1) - 0.5)
    e = y - (y & 1)
    if e + 1 >= height or abs(z[(x, e + 1)] - z[(x, e)]) >= QUAD_DEPTH_STEP:
        return along_x(x, y)
    return along_x(x, y) - (along_x(x, e + 1) - along_x(x, e)) * ((y & 1) - 0.5)


def sao_basic(gbuffer: GBuffer, params: SAOParams = SAOParams()) -> AOResult:
    """:func:`ssbench.passes.ao.sao.sao` by per-pixel loops (batch 1), float64."""
    cam, p = gbuffer.camera, params
    H, W = cam.height, cam.width
    vz, mask = gbuffer.view_z[0, 0].double(), gbuffer.mask[0, 0]
    zimg = torch.where(mask, vz, torch.full_like(vz, -cam.far))
    z = {(x, y): float(zimg[H - 1 - y, x]) for y in range(H) for x in range(W)}
    level0 = [[z[(x, y)] for x in range(W)] for y in range(H)]
    mips = [(level0, W, H)]
    for _ in range(p.max_mip_level if p.use_mips else 0):
        mips.append(minify(*mips[-1]))
    C = {(x, y): reconstruct_cs_position(cam, x + 0.5, y + 0.5, z[(x, y)]) for y in range(H) for x in range(W)}
    A = {}
    for y in range(H):
        for x in range(W):
            if p.normals == "depth":
                n_C = face_normal(C, x, y, W, H)
            else:
                n_C = tuple(float(v) for v in gbuffer.normal[0, :, H - 1 - y, x].double())
            spin = float(((3 * x) ^ (y + x * y)) * 10)
            ssDiskRadius = -pixels_per_meter(cam) * p.radius / z[(x, y)]
            total = 0.0
            for i in range(p.num_samples):
                unit, alpha = tap_location(i, p.num_samples, p.num_spiral_turns, spin)
                Q, _ = get_offset_position(cam, mips, (x, y), unit, alpha * ssDiskRadius, p)
                total += sample_ao(C[(x, y)], n_C, Q, p)
            A[(x, y)] = max(0.0, 1.0 - total * (p.intensity / (p.radius * p.radius) ** 3) * (5.0 / p.num_samples))
    out = torch.ones(1, 1, H, W, dtype=torch.float64)
    for y in range(H):
        for x in range(W):
            a = quad_filter_pixel(A, z, x, y, W, H) if p.quad_filter else A[(x, y)]
            if bool(mask[H - 1 - y, x]):
                out[0, 0, H - 1 - y, x] = min(a, 1.0)
    return AOResult(ao=out)
