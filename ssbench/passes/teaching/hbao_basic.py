"""HBAO, one pixel at a time: the SSAO article's shader (§3.3) transliterated line by line.

This file exists only to teach. It is a slow per-pixel Python loop whose functions and variables carry the
shader's names (``viewPos``, ``uvToView``, ``minDiff``, ``calculateNumSteps``, ``rotateDirections``,
``snapUVOffset``, ``getBiasedTangent``, ``TanToSin``, ``integrateOcclusion``, ``horizonOcclusion``, ``P``,
``Pr``, ``dPdu``, ``deltaUV``, ``numSteps``, ``stepSizeUV``...). It draws the same noise texture with the same
generator call as :func:`ssbench.passes.ao.hbao.hbao`, so the two agree to round-off (``tests/passes/ao/test_hbao.py``).
Use the vectorised pass for anything but 16×12 images.
"""
from __future__ import annotations

import math
from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..common import AOResult, make_generator
from ..ao.hbao import HBAOParams, check_inputs, noise_texture


def hbao_basic(gbuffer: GBuffer, params: HBAOParams = HBAOParams(),
               generator: Optional[torch.Generator] = None) -> AOResult:
    """Per-pixel HBAO; returns :class:`AOResult` with ``ao`` :math:`(B, 1, H, W)` like :func:`hbao`.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 3, 4), -2.0), mask=torch.ones(1, 1, 3, 4, dtype=torch.bool))
        >>> hbao_basic(g, HBAOParams(radius=1.0)).ao.flatten().tolist()
        [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    """
    check_inputs(gbuffer, params)
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    near, far = cam.near, cam.far
    # uniforms (the article's JS side): UvToViewParams, FocalLength, AORes, R, TanAngleBias, ...
    UvToViewParams = cam.uv_to_view_params()                       # (uvToVA0, uvToVA1, uvToVB0, uvToVB1)
    FocalLength = cam.focal * H / W                                # focal1 = 1/tan(fov/2)·(Height/Width)
    AORes, InvAORes = (W, H), (1.0 / W, 1.0 / H)
    R = params.radius
    R2 = R * R
    NegInvR2 = -1.0 / R2
    TanAngleBias, AOStrength, MaxRadiusPixels = params.tan_angle_bias, params.ao_strength, params.max_radius_pixels
    NUM_DIRECTIONS, NUM_STEPS = params.num_directions, params.num_steps
    noise = noise_texture(params, make_generator(params.seed, generator)).tolist()   # (3, N, N): cos, sin, jitter
    from_depth = params.position_from == "depth"
    tex = (gbuffer.depth if from_depth else gbuffer.view_z).double().tolist()  # DepthSampler (B, 1, H, W)
    mask = gbuffer.mask.tolist()

    def perspectiveDepthToViewZ(invClipZ):                         # three.js packing.glsl
        return (near * far) / ((far - near) * invClipZ - far)

    def uvToView(uv, viewZ):                                       # §3.3
        x = UvToViewParams[0] * uv[0] + UvToViewParams[2]
        y = UvToViewParams[1] * uv[1] + UvToViewParams[3]
        return (x * viewZ, y * viewZ, viewZ)

    def texture2D(b, uv):                                          # NEAREST, CLAMP_TO_EDGE, row 0 at the top
        col = min(max(math.floor(uv[0] * W), 0), W - 1)
        row = min(max(math.floor((1.0 - uv[1]) * H), 0), H - 1)
        return tex[b][0][row][col]

    def viewPos(b, uv):                                            # §3.3
        depth = texture2D(b, uv)
        viewZ = perspectiveDepthToViewZ(depth) if from_depth else depth
        return uvToView(uv, viewZ)

    def sub(a, c):
        return (a[0] - c[0], a[1] - c[1], a[2] - c[2])

    def lengthSqr(v):
        return v[0] * v[0] + v[1] * v[1] + v[2] * v[2]

    def rsqrt(x):                                                  # finite at 0, as the vectorised pass
        return 1.0 / math.sqrt(max(x, 2.2250738585072014e-308))

    def minDiff(P, Pr, Pl):
        v1, v2 = sub(Pr, P), sub(P, Pl)
        return v1 if lengthSqr(v1) < lengthSqr(v2) else v2

    def falloffFactor(d2):                                         # W(r) = 1 − r², r = |S − P| / R  (§3.1)
        return d2 * NegInvR2 + 1.0

    def snapUVOffset(uv):                                          # round(uv·AORes)·InvAORes, round = floor(+0.5)
        return (math.floor(uv[0] * AORes[0] + 0.5) * InvAORes[0], math.floor(uv[1] * AORes[1] + 0.5) * InvAORes[1])

    def TanToSin(x):                                               # sin = tan / sqrt(1 + tan²)
        return x / math.hypot(x, 1.0)

    def getTangent(T):
        return T[2] * rsqrt(T[0] * T[0] + T[1] * T[1])

    def getBiasedTangent(T):                                       # ignore occluders near the tangent (Figs. 16-17)
        return getTangent(T) + TanAngleBias

    def saturate(x):
        return min(max(x, 0.0), 1.0)

    def rotateDirections(Dir, CosSin):
        return (Dir[0] * CosSin[0] - Dir[1] * CosSin[1], Dir[0] * CosSin[1] + Dir[1] * CosSin[0])

    def calculateNumSteps(radiusInPixels, rand):                   # returns (stepSizeInUV, numSteps)
        numSteps = min(float(NUM_STEPS), radiusInPixels)           # avoid oversampling
        stepSizeInPixels = radiusInPixels / (numSteps + 1.0)       # farthest sample not fully attenuated
        maxNumSteps = MaxRadiusPixels / stepSizeInPixels
        if maxNumSteps < numSteps:                                 # clamp to the max footprint, dithered
            numSteps = math.floor(maxNumSteps + rand)
            numSteps = max(numSteps, 1.0)
            stepSizeInPixels = MaxRadiusPixels / numSteps
        return (stepSizeInPixels * InvAORes[0], stepSizeInPixels * InvAORes[1]), numSteps

    def tangentVector(duv, dPdu, dPdv):
        return tuple(duv[0] * dPdu[k] + duv[1] * dPdv[k] for k in range(3))

    def integrateOcclusion(b, uv0, snapped_duv, P, dPdu, dPdv, tanH):   # returns (ao, tanH)
        ao = 0.0
        T = tangentVector(snapped_duv, dPdu, dPdv)                 # tangent vector for snapped_duv
        tanT = getBiasedTangent(T)
        sinT = TanToSin(tanT)
        S = viewPos(b, (uv0[0] + snapped_duv[0], uv0[1] + snapped_duv[1]))
        diff = sub(S, P)
        tanS = getTangent(diff)
        sinS = TanToSin(tanS)
        d2 = lengthSqr(diff)
        if d2 < R2 and tanS > tanT:
            ao = falloffFactor(d2) * saturate(sinS - sinT)         # AO between the tangent plane and the sample
            tanH = max(tanH, tanS)                                 # update the horizon angle
        return ao, tanH

    def horizonOcclusion(b, dUv, texelDeltaUV, uv0, P, numSteps, randstep, dPdu, dPdv):   # returns (ao, tanH)
        s = snapUVOffset((randstep * dUv[0], randstep * dUv[1]))
        uv = (uv0[0] + s[0], uv0[1] + s[1])
        deltaUV = snapUVOffset(dUv)
        T = tangentVector(deltaUV, dPdu, dPdv)
        tanH = getBiasedTangent(T)
        # SAMPLE_FIRST_STEP: a first sample between uv0 and uv0 + deltaUV
        snapped_duv = snapUVOffset((randstep * deltaUV[0] + texelDeltaUV[0], randstep * deltaUV[1] + texelDeltaUV[1]))
        ao, tanH = integrateOcclusion(b, uv0, snapped_duv, P, dPdu, dPdv, tanH)
        numSteps -= 1.0
        sinH = TanToSin(tanH)
        for j in range(1, NUM_STEPS):                              # MAX_STEPS = NUM_STEPS
            if float(j) >= numSteps:
                break
            uv = (uv[0] + deltaUV[0], uv[1] + deltaUV[1])
            S = viewPos(b, uv)
            diff = sub(S, P)
            tanS = getTangent(diff)
            d2 = lengthSqr(diff)
            if d2 < R2 and tanS > tanH:
                sinS = TanToSin(tanS)                              # AO between the horizon and the sample
                ao += falloffFactor(d2) * saturate(sinS - sinH)
                tanH, sinH = tanS, sinS                            # update the current horizon angle
        return ao, tanH

    out = [[[[1.0] * W for _ in range(H)]] for _ in range(B)]
    alpha = 2.0 * math.pi / NUM_DIRECTIONS
    for b in range(B):
        for row in range(H):
            for col in range(W):
                if not mask[b][0][row][col]:
                    continue                                       # background: AO 1
                uv = ((col + 0.5) / W, 1.0 - (row + 0.5) / H)      # vUv at the pixel centre (v up)
                P = viewPos(b, uv)
                diskRadiusInUV = 0.5 * R * FocalLength / -P[2]     # projected disk of radius R
                radiusInPixels = diskRadiusInUV * AORes[0]
                if not radiusInPixels > 1.0:
                    continue
                Pr = viewPos(b, (uv[0] + InvAORes[0], uv[1]))      # nearest neighbours on the tangent plane
                Pl = viewPos(b, (uv[0] - InvAORes[0], uv[1]))
                Pt = viewPos(b, (uv[0], uv[1] + InvAORes[1]))
                Pb = viewPos(b, (uv[0], uv[1] - InvAORes[1]))
                dPdu = minDiff(P, Pr, Pl)                          # screen-aligned tangent basis
                dPdv = tuple(x * (AORes[1] * InvAORes[0]) for x in minDiff(P, Pt, Pb))
                n = params.noise_size
                rand = (noise[0][row % n][col % n], noise[1][row % n][col % n], noise[2][row % n][col % n])
                stepSize, numSteps = calculateNumSteps(radiusInPixels, rand[2])
                ao = 0.0
                for d in range(NUM_DIRECTIONS):
                    angle = alpha * float(d)                       # apply noise to the direction
                    dir = rotateDirections((math.cos(angle), math.sin(angle)), rand[:2])
                    deltaUV = (dir[0] * stepSize[0], dir[1] * stepSize[1])
                    texelDeltaUV = (dir[0] * InvAORes[0], dir[1] * InvAORes[1])
                    ao += horizonOcclusion(b, deltaUV, texelDeltaUV, uv, P, numSteps, rand[2], dPdu, dPdv)[0]
                ao = 1.0 - ao / float(NUM_DIRECTIONS) * AOStrength  # average and produce the final AO
                out[b][0][row][col] = saturate(ao)
    return AOResult(ao=torch.tensor(out, dtype=gbuffer.view_z.dtype, device=gbuffer.view_z.device))
