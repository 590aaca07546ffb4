"""GTAO, one pixel at a time: XeGTAO's main pass (``XeGTAO_MainPass``) as a plain per-pixel loop.

This file exists only to teach. It follows Jimenez, Wu, Pesce and Jarabo, "Practical Realtime Strategies for
Accurate Indirect Occlusion" (SIGGRAPH 2016 course, Algorithm 1) in the form Intel's XeGTAO ships
(https://github.com/GameTechDev/XeGTAO, 2021), with XeGTAO's variable names: ``viewspaceZ``, ``pixCenterPos``,
``viewVec``, ``screenspaceRadius``, ``falloffMul``/``falloffAdd``, ``minS``, ``phi``, ``directionVec``,
``orthoDirectionVec``, ``axisVec``, ``projectedNormalVec``, ``signNorm``, ``cosNorm``, ``n``,
``lowHorizonCos0/1``, ``horizonCos0/1``, ``sampleOffset``, ``sampleDelta``, ``shc``, ``weight``, ``h0``,
``h1``, ``iarc0/1``, ``localVisibility``, ``visibility``. It reads the same noise as
:func:`ssbench.passes.ao.gtao.gtao` (:func:`~ssbench.passes.ao.gtao_parts.noise_buffer`) and makes the same departures
from XeGTAO (full-resolution nearest fetches instead of the depth MIP chain, off-screen samples ignored), so the
two agree to round-off (``tests/passes/ao/test_gtao.py``). The final spatial denoise, when asked for, is the
vectorised :func:`~ssbench.passes.ao.gtao_denoise.gtao_denoise`. Use the vectorised pass for anything but 16×12.
"""
from __future__ import annotations

import math
from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..common import AOResult
from ..ao.gtao import GTAOParams, check_inputs
from ..ao.gtao_parts import noise_buffer

CENTER_Z_BIAS = 0.99999          # XE_GTAO_FP32_DEPTHS: viewspaceZ *= 0.99999
SLOPE_FUDGE = 0.05               # projectedNormalVecLength lerped 5 % toward 1
R1 = 0.6180339887498948482       # golden-ratio step noise


def gtao_basic(gbuffer: GBuffer, params: GTAOParams = GTAOParams(),
               generator: Optional[torch.Generator] = None) -> AOResult:
    """Per-pixel GTAO; returns :class:`AOResult` with ``ao`` :math:`(B, 1, H, W)` like :func:`gtao`.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 30.0, 4, 3, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 3, 4, dtype=torch.float64); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 3, 4), -2.0, dtype=torch.float64), normal=n,
        ...             mask=torch.ones(1, 1, 3, 4, dtype=torch.bool))
        >>> bool((gtao_basic(g, GTAOParams(denoise_passes=0)).ao > 0.99).all())   # a wall facing the camera
        True
    """
    check_inputs(gbuffer, params)
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    Aspect, Focal = cam.aspect, cam.focal
    EffectRadius = params.radius * params.radius_multiplier
    FalloffRange, TOC = params.falloff_range, params.thin_occluder_compensation
    SliceCount, StepsPerSlice = params.slices, params.steps
    tiny = torch.finfo(torch.float64).tiny
    noise = noise_buffer(params, B, H, W, generator).tolist()             # (B, 2, H, W): slice, sample noise
    mask = gbuffer.mask.tolist()
    depth = torch.where(gbuffer.mask, gbuffer.view_z, -cam.far).double().tolist()   # the depth texture
    normal = gbuffer.normal.double().tolist()

    def viewX(col):                                              # view x at z = −1 of pixel column ``col``
        return (2.0 * (col + 0.5) / W - 1.0) * Aspect / Focal

    def viewY(row):                                              # view y at z = −1 (v up, row 0 at the top)
        return (1.0 - 2.0 * (row + 0.5) / H) / Focal

    def dot(a, b):
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]

    def cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

    def normalize(a):
        inv = 1.0 / max(math.sqrt(dot(a, a)), tiny)
        return tuple(c * inv for c in a)

    def sign(x):
        return (x > 0) - (x < 0)

    def falloffWeight(dist):                                     # saturate(dist·falloffMul + falloffAdd)
        if FalloffRange == 0:
            return 1.0 if dist <= EffectRadius else 0.0
        falloffMul = -1.0 / (FalloffRange * EffectRadius)
        falloffAdd = (1.0 - FalloffRange) / FalloffRange + 1.0
        return min(max(dist * falloffMul + falloffAdd, 0.0), 1.0)

    def iarc(h, n):                                              # (cos n + 2h sin n − cos(2h − n)) / 4
        return (math.cos(n) + 2.0 * h * math.sin(n) - math.cos(2.0 * h - n)) / 4.0

    def sliceVisibility(b, row, col, pixCenterPos, viewVec, viewspaceNormal, screenspaceRadius, minS, slice_):
        noiseSlice, noiseSample = noise[b][0][row][col], noise[b][1][row][col]
        phi = (slice_ + noiseSlice) / SliceCount * math.pi
        cosPhi, sinPhi = math.cos(phi), math.sin(phi)
        directionVec = (cosPhi, sinPhi, 0.0)
        dv = dot(directionVec, viewVec)
        orthoDirectionVec = (cosPhi - dv * viewVec[0], sinPhi - dv * viewVec[1], -dv * viewVec[2])
        axisVec = normalize(cross(orthoDirectionVec, viewVec))
        na = dot(viewspaceNormal, axisVec)
        projectedNormalVec = tuple(viewspaceNormal[i] - axisVec[i] * na for i in range(3))
        projectedNormalVecLength = math.sqrt(dot(projectedNormalVec, projectedNormalVec))
        signNorm = sign(dot(orthoDirectionVec, projectedNormalVec))
        cosNorm = min(max(dot(projectedNormalVec, viewVec) / max(projectedNormalVecLength, tiny), 0.0), 1.0)
        n = signNorm * math.acos(cosNorm)
        lowHorizonCos0, lowHorizonCos1 = math.cos(n + math.pi / 2), math.cos(n - math.pi / 2)
        horizonCos0, horizonCos1 = lowHorizonCos0, lowHorizonCos1
        for step in range(StepsPerSlice):
            stepBaseNoise = (slice_ + step * StepsPerSlice) * R1
            stepNoise = (noiseSample + stepBaseNoise) % 1.0
            s = ((step + stepNoise) / StepsPerSlice) ** params.sample_distribution_power + minS
            sampleOffset = (round(s * cosPhi * screenspaceRadius), round(-s * sinPhi * screenspaceRadius))
            for side, sgn in ((0, 1), (1, -1)):                  # samplePos0 = centre + offset, samplePos1 = − offset
                sx, sy = col + sgn * sampleOffset[0], row + sgn * sampleOffset[1]
                if not (0 <= sx < W and 0 <= sy < H):
                    continue                                     # off screen: ignored
                sz = depth[b][0][sy][sx]
                sampleDelta = (viewX(sx) * -sz - pixCenterPos[0], viewY(sy) * -sz - pixCenterPos[1],
                               sz - pixCenterPos[2])
                sampleDist = max(math.sqrt(dot(sampleDelta, sampleDelta)), tiny)
                shc = dot(sampleDelta, viewVec) / sampleDist
                if TOC:                                          # thin occluder compensation: stretch z
                    sampleDist = math.sqrt(sampleDelta[0] ** 2 + sampleDelta[1] ** 2
                                           + (sampleDelta[2] * (1.0 + TOC)) ** 2)
                weight = falloffWeight(sampleDist)
                if side == 0:
                    horizonCos0 = max(horizonCos0, lowHorizonCos0 + weight * (shc - lowHorizonCos0))
                else:
                    horizonCos1 = max(horizonCos1, lowHorizonCos1 + weight * (shc - lowHorizonCos1))
        projectedNormalVecLength += SLOPE_FUDGE * (1.0 - projectedNormalVecLength)
        h0 = -math.acos(min(max(horizonCos1, -1.0), 1.0))
        h1 = math.acos(min(max(horizonCos0, -1.0), 1.0))
        iarc0, iarc1 = iarc(h0, n), iarc(h1, n)
        return projectedNormalVecLength * (iarc0 + iarc1)        # localVisibility

    ao = [[[[1.0] * W for _ in range(H)]] for _ in range(B)]
    for b in range(B):
        for row in range(H):
            for col in range(W):
                if not mask[b][0][row][col]:
                    continue                                     # background: unoccluded
                viewspaceZ = depth[b][0][row][col] * CENTER_Z_BIAS
                pixCenterPos = (viewX(col) * -viewspaceZ, viewY(row) * -viewspaceZ, viewspaceZ)
                viewVec = normalize(tuple(-c for c in pixCenterPos))
                viewspaceNormal = tuple(normal[b][i][row][col] for i in range(3))
                screenspaceRadius = EffectRadius * Focal * H / (2.0 * -viewspaceZ)   # in pixels
                minS = params.min_offset_pixels / screenspaceRadius
                visibility = min(max((10.0 - screenspaceRadius) / 100.0, 0.0), 1.0) * 0.5   # small-radius fade
                for slice_ in range(SliceCount):
                    visibility += sliceVisibility(b, row, col, pixCenterPos, viewVec, viewspaceNormal,
                                                  screenspaceRadius, minS, slice_)
                ao[b][0][row][col] = max(visibility / SliceCount, 0.0) ** params.final_value_power
    vis = torch.tensor(ao, dtype=gbuffer.view_z.dtype, device=gbuffer.view_z.device)
    if params.denoise_passes:
        from ..ao.gtao_denoise import gtao_denoise
        vis = gtao_denoise(torch.where(gbuffer.mask, vis, torch.ones_like(vis)), gbuffer.view_z, gbuffer.mask,
                           passes=params.denoise_passes)
    vis = vis.clamp(0.03, 1.0)
    return AOResult(ao=torch.where(gbuffer.mask, vis, torch.ones_like(vis)))
