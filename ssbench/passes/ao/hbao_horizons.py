"""HBAO on a band of image rows (SSAO article §3.3): the depth-derived tangent frame (``minDiff``), the step
count and size (``calculateNumSteps``), the rotated directions, the first sample (``integrateOcclusion``) and the
horizon march (``calculateHorizonOcclusion``). :func:`ssbench.passes.ao.hbao.hbao` runs it band by band.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import torch

from ..common import fetch_uv
from ..compiled import is_set, kept_mask, kernel
from ..float_masks import float_masks, select

if TYPE_CHECKING:
    from .hbao import HBAOParams

__all__ = ["texel_view_z", "hbao_band", "rsqrt", "tan_to_sin", "tangent", "snap", "min_diff"]


def texel_view_z(cam, view_z: torch.Tensor, position_from: str) -> torch.Tensor:
    """The view z a sample reads from each texel, :math:`(B, 1, H, W)`: ``view_z`` itself, or with ``"depth"``
    the GL depth buffer's value turned back into view z (``viewPos``' ``perspectiveDepthToViewZ`` of the
    ``DepthSampler`` texel, SSAO article §3.3). A function of the texel alone, so computed once per texel rather
    than per sample that reads it: the same operations on the same values, the same bits.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.5, 8.0)
        >>> texel_view_z(cam, torch.full((1, 1, 3, 4), -2.0), "depth")[0, 0, 0, 0].item()   # the round trip
        -2.0
    """
    return cam.depth_to_view_z(cam.view_z_to_depth(view_z)) if position_from == "depth" else view_z


def rsqrt(x: torch.Tensor) -> torch.Tensor:
    """``rsqrt`` that stays finite at 0 (a zero-length ``T.xy`` gives slope 0 instead of NaN)."""
    return torch.rsqrt(x.clamp_min(torch.finfo(x.dtype).tiny))


def tan_to_sin(x: torch.Tensor) -> torch.Tensor:
    """``TanToSin``: ``x·rsqrt(x² + 1)``, written ``x / hypot(x, 1)`` so huge slopes do not overflow."""
    return x / torch.hypot(x, torch.ones_like(x))


def tangent(v: torch.Tensor) -> torch.Tensor:
    """``getTangent``: ``V.z·rsqrt(dot(V.xy, V.xy))`` of a ``(B, 3, ...)`` vector (GL view space, z up)."""
    return v[:, 2] * rsqrt(v[:, 0] ** 2 + v[:, 1] ** 2)


def snap(uv: torch.Tensor, res: torch.Tensor, inv_res: torch.Tensor) -> torch.Tensor:
    """``snapUVOffset``: ``round(uv·AORes)·InvAORes`` with the article's ``round(a) = floor(a + 0.5)``."""
    return torch.floor(uv * res + 0.5) * inv_res


def min_diff(P: torch.Tensor, Pa: torch.Tensor, Pb: torch.Tensor) -> torch.Tensor:
    """``minDiff``: the shorter of ``Pa − P`` and ``P − Pb`` (ties take ``P − Pb``)."""
    v1, v2 = Pa - P, P - Pb
    return torch.where((v1 * v1).sum(1, keepdim=True) < (v2 * v2).sum(1, keepdim=True), v1, v2)


@kernel
def hbao_band(cam, uv0: torch.Tensor, mask: torch.Tensor, rand: torch.Tensor, z_tex: torch.Tensor,
              params: "HBAOParams", debug: bool) -> tuple[torch.Tensor, dict]:
    """HBAO on a band of rows (SSAO article §3.3); the pass's compilable kernel (:mod:`ssbench.passes.compiled`).
    Eager, the march stops early once no pixel of the band has steps left; compiled, it runs every step (a
    data-dependent exit would break the graph), and the steps the exit skips are masked anyway: the same result.

    Args:
        uv0: :math:`(B, 2, h, W)` ``vUv`` of the band's pixels; mask: :math:`(B, 1, h, W)`;
        rand: :math:`(1, 3, h, W)` the noise texel ``(cos, sin, jitter)`` of each pixel;
        z_tex: :math:`(B, 1, H, W)` the view z of every texel of the depth buffer the samples read
            (:func:`texel_view_z`).

    Returns:
        ``(ao, debug)``: :math:`(B, 1, h, W)` and the band's debug buffers (empty unless ``debug``).
    """
    H, W = z_tex.shape[-2], z_tex.shape[-1]
    D, dtype, dev = params.num_directions, z_tex.dtype, z_tex.device

    def viewPos(uv: torch.Tensor) -> torch.Tensor:             # (B, 2, *S) -> (B, 3, *S), nearest + clamp
        return cam.uv_to_view(uv, fetch_uv(z_tex, uv), dim=1)

    AORes = torch.tensor([W, H], dtype=dtype, device=dev).view(1, 2, 1, 1)     # (1, 2, 1, 1)
    InvAORes = 1.0 / AORes
    R = params.radius if torch.is_tensor(params.radius) else float(params.radius)   # a tensor keeps autograd
    R2 = R * R
    FocalLength = cam.focal * H / W
    ex = torch.tensor([1.0, 0.0], dtype=dtype, device=dev).view(1, 2, 1, 1) * InvAORes
    ey = torch.tensor([0.0, 1.0], dtype=dtype, device=dev).view(1, 2, 1, 1) * InvAORes
    angle = (2.0 * math.pi / D) * torch.arange(D, dtype=dtype, device=dev).view(1, D, 1, 1)
    res, inv = AORes.unsqueeze(2), InvAORes.unsqueeze(2)

    P = viewPos(uv0)                                                         # (B, 3, h, W)
    a0, a1, b0, b1 = cam.uv_to_view_params()

    def offset_to(uv: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``tangent(S − P)`` and ``|S − P|²`` of the sample ``S`` at ``uv`` :math:`(B, 2, D, h, W)`, on
        components: ``viewPos(uv) − P``'s bits, and with no sum over a channel dimension, which compiled to a
        stored buffer per step; ``|S − P|²`` is :func:`~ssbench.rays.component_dot`'s sum in its order, sharing
        ``dx² + dy²`` with the tangent."""
        z = fetch_uv(z_tex, uv)[:, 0]
        dx = (a0 * uv[:, 0] + b0) * z - P[:, 0:1]
        dy = (a1 * uv[:, 1] + b1) * z - P[:, 1:2]
        dz = z - P[:, 2:3]
        xy2 = dx * dx + dy * dy                    # dx² + dy² once: pow(x, 2) is x·x, and the dot sums in this order
        return dz * rsqrt(xy2), xy2 + dz * dz

    # ---- projected radius (diskRadiusInUV, radiusInPixels) ----
    radiusInPixels = 0.5 * R * FocalLength / -P[:, 2:3] * W                  # (B, 1, h, W)
    active = mask & (radiusInPixels > 1.0)

    # ---- tangent basis from the 4 neighbours (minDiff) ----
    Pr, Pl, Pt, Pb = viewPos(uv0 + ex), viewPos(uv0 - ex), viewPos(uv0 + ey), viewPos(uv0 - ey)
    dPdu = min_diff(P, Pr, Pl).unsqueeze(2)                                 # (B, 3, 1, h, W)
    dPdv = (min_diff(P, Pt, Pb) * (H / W)).unsqueeze(2)

    # ---- calculateNumSteps (the noise's jitter rounds a clamped step count) ----
    numSteps = torch.clamp(radiusInPixels, max=float(params.num_steps))
    stepSizeInPixels = radiusInPixels / (numSteps + 1.0)
    maxNumSteps = params.max_radius_pixels / stepSizeInPixels
    clamp = maxNumSteps < numSteps
    numSteps = torch.where(clamp, torch.floor(maxNumSteps + rand[:, 2:3]).clamp_min(1.0), numSteps)
    stepSizeInPixels = torch.where(clamp, params.max_radius_pixels / numSteps, stepSizeInPixels)
    stepSizeInUV = (stepSizeInPixels * InvAORes).unsqueeze(2)                # (B, 2, 1, h, W)

    # ---- directions: rotateDirections(vec2(cos(angle), sin(angle)), rand.xy) ----
    c, s = rand[:, 0:1], rand[:, 1:2]                                        # (1, 1, h, W)
    dir = torch.stack([torch.cos(angle) * c - torch.sin(angle) * s,
                       torch.cos(angle) * s + torch.sin(angle) * c], 1)     # (1, 2, D, h, W)
    dUv = dir * stepSizeInUV                                                 # (B, 2, D, h, W)
    texelDeltaUV = dir * inv
    randstep = rand[:, 2:3].unsqueeze(2)                                     # (1, 1, 1, h, W)
    uv0d = uv0.unsqueeze(2)

    # ---- calculateHorizonOcclusion, all directions at once ----
    uv = uv0d + snap(randstep * dUv, res, inv)                              # (B, 2, D, h, W)
    deltaUV = snap(dUv, res, inv)
    T = deltaUV[:, 0:1] * dPdu + deltaUV[:, 1:2] * dPdv                     # (B, 3, D, h, W)
    tanH = tangent(T) + params.tan_angle_bias                               # (B, D, h, W)
    # integrateOcclusion: a first sample between uv0 and uv0 + deltaUV, against the tangent of its own offset
    snapped_duv = snap(randstep * deltaUV + texelDeltaUV, res, inv)
    T1 = snapped_duv[:, 0:1] * dPdu + snapped_duv[:, 1:2] * dPdv
    tanT = tangent(T1) + params.tan_angle_bias
    tanS, d2 = offset_to(uv0d + snapped_duv)
    hit = kept_mask(active & (d2 < R2) & (tanS > tanT))     # compiled: 0/1 floats, not a bool buffer
    ao = torch.where(is_set(hit), (1.0 - d2 / R2) * (tan_to_sin(tanS) - tan_to_sin(tanT)).clamp(0.0, 1.0), 0.0)
    tanH = torch.where(is_set(hit), torch.maximum(tanH, tanS), tanH)
    numStepsLeft = numSteps - 1.0                                            # --numSteps
    sinH = tan_to_sin(tanH)
    samples = torch.ones_like(numSteps)
    # eager without gradients (a bitwise select has none; a radius or bias may want them): float masks
    masks_as_floats = float_masks(tanH) and not torch.is_grad_enabled()
    for j in range(1, params.num_steps):                                     # the march: j < numSteps
        live = active & (j < numStepsLeft)                                   # (B, 1, h, W)
        if not torch.compiler.is_compiling() and live.device.type != "meta" and not bool(live.any()):  # meta: shapes
            break
        live_f = live.to(dtype)
        samples = samples + live_f
        uv = uv + deltaUV
        tanS, d2 = offset_to(uv)                                             # (B, D, h, W)
        sinS = tan_to_sin(tanS)
        if masks_as_floats:                     # eager: the same steps with 0/1 float masks, the same bits
            hit = torch.lt(d2, R2, out=torch.empty_like(d2)).mul_(live_f)
            hit.mul_(torch.gt(tanS, tanH, out=torch.empty_like(d2)))
            # a hit's gain is finite (d2 < R2, so |dz| < R and tanS is); elsewhere 0·gain must be 0, not NaN
            gain = ((1.0 - d2 / R2) * (sinS - sinH).clamp(0.0, 1.0)).nan_to_num_(0.0, 0.0, 0.0)
            ao = torch.addcmul(ao, hit, gain)                                # ao + 1·gain, or ao + (±0) = ao
            tanH, sinH = select(hit, tanS, tanH), select(hit, sinS, sinH)
            continue
        hit = kept_mask(live & (d2 < R2) & (tanS > tanH))
        ao = ao + torch.where(is_set(hit), (1.0 - d2 / R2) * (sinS - sinH).clamp(0.0, 1.0), 0.0)
        tanH, sinH = torch.where(is_set(hit), tanS, tanH), torch.where(is_set(hit), sinS, sinH)

    out = (1.0 - ao.sum(1, keepdim=True) / D * params.ao_strength).clamp(0.0, 1.0)
    out = torch.where(active, out, torch.ones_like(out))
    dbg = {}
    if debug:
        dbg = {"num_steps": torch.where(active, numSteps, 0.0), "samples": torch.where(active, samples, 0.0),
               "horizons": torch.where(active, torch.atan(tanH), 0.0), "radius_pixels": radiusInPixels}
    return out, dbg
