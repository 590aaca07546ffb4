"""DDA screen-space reflections, one pixel at a time: SSR article §2.2's ``traceScreenSpaceRay`` line by line.

This file exists only to teach. It is a slow per-pixel Python loop that keeps the shader's names (``rayOrg``,
``rayDir``, ``H0``, ``H1``, ``k0``, ``k1``, ``Q0``, ``Q1``, ``P0``, ``P1``, ``delta``, ``permute``, ``stepDir``,
``invdx``, ``dQ``, ``dk``, ``dP``, ``pixelStride``, ``rayZMin``, ``rayZMax``, ``prevZMaxEstimate``,
``sceneZMax``, ``hitPixel``, ``hitPoint``), with the fixes of :mod:`ssbench.passes.ssr.dda` marked ``# FIX``.
It draws the same jitter with the same generator call as :func:`~ssbench.passes.ssr.dda.ssr_dda`, so the two
agree (``tests/passes/ssr/test_dda.py``). Use the vectorised pass for anything but 16×12 images.
"""
from __future__ import annotations

import math
import sys
from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..common import make_generator
from ..ssr.common import BEHIND_CAMERA, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS, SSRResult
from ..ssr.dda import DDASSRParams, check_inputs, jitter_fractions
from ..ssr.dda_rays import project_to_pixel_matrix

TINY = sys.float_info.min                              # torch.finfo(float64).tiny


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def normalize(a):
    length = max(math.sqrt(dot(a, a)), TINY)
    return (a[0] / length, a[1] / length, a[2] / length)


def reflect(I, N):                                     # GLSL reflect(I, N) = I − 2·dot(N, I)·N
    d = 2.0 * dot(N, I)
    return (I[0] - d * N[0], I[1] - d * N[1], I[2] - d * N[2])


def saturate(x):
    return min(max(x, 0.0), 1.0)


def ssr_dda_basic(gbuffer: GBuffer, params: DDASSRParams = DDASSRParams(),
                  generator: Optional[torch.Generator] = None) -> SSRResult:
    """Per-pixel DDA SSR; returns an :class:`SSRResult` like :func:`ssr_dda` (``debug`` empty).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 3, 4); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 3, 4), -2.0), normal=n,
        ...             mask=torch.ones(1, 1, 3, 4, dtype=torch.bool), color=torch.ones(1, 3, 3, 4))
        >>> ssr_dda_basic(g).termination.flatten().tolist()      # rays toward the camera leave the screen
        [2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2]
    """
    check_inputs(gbuffer, params)
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    # uniforms
    CameraProjectionMatrix = project_to_pixel_matrix(cam).tolist()   # FIX: maps to pixels, not NDC (G3D)
    CameraNear, MaxRayDistance, Iterations = cam.near, params.max_ray_distance, params.max_steps
    PixelStride, PixelStrideZCutoff, zThickness = params.pixel_stride, params.pixel_stride_z_cutoff, params.z_thickness
    BinarySearchIterations = params.binary_search_iterations
    UvToViewParams = cam.uv_to_view_params()
    jitters = jitter_fractions(params, (B, 1, H, W), make_generator(params.seed, generator)).tolist()
    depth = gbuffer.view_z.double().tolist()             # linear view-z buffer (no depth round trip)
    mask, normal, colors = gbuffer.mask.tolist(), gbuffer.normal.double().tolist(), gbuffer.color.double().tolist()

    def project(c):                                      # CameraProjectionMatrix * vec4(c, 1.0)
        M = CameraProjectionMatrix
        return [M[r][0] * c[0] + M[r][1] * c[1] + M[r][2] * c[2] + M[r][3] for r in range(4)]

    def toZ(Qz, k, zMin, zMax):                          # FIX: clamp (G3D), k ≤ 0 past the end stays finite
        return min(max(Qz / max(k, TINY), zMin), zMax)

    backDepth = gbuffer.back_z.double().tolist() if params.use_back_face_depth else None
    secondDepth = gbuffer.second_z.double().tolist() if params.use_second_layer else None

    def texelFetch(b, hitPixel):                         # (sceneZMax, mask) at int2(hitPixel), or None off screen
        x, y = hitPixel
        if not (0.0 <= x < W and 0.0 <= y < H):
            return None
        return depth[b][0][math.floor(y)][math.floor(x)], mask[b][0][math.floor(y)][math.floor(x)]

    def traceScreenSpaceRay(b, rayOrg, rayDir, jitter):
        """Returns ``(termination, hitPixel, hitPoint, steps)``."""
        # Clip to the near plane (the FIX keeps the length in [0, MaxRayDistance] like clip_ray_length)
        clipped = (rayOrg[2] + rayDir[2] * MaxRayDistance) > -CameraNear
        rayLength = min(max((-CameraNear - rayOrg[2]) / (rayDir[2] if rayDir[2] != 0 else 1.0), 0.0),
                        MaxRayDistance) if clipped else MaxRayDistance
        rayEnd = tuple(rayOrg[i] + rayDir[i] * rayLength for i in range(3))
        # Project into homogeneous clip space (here: pixels)
        H0, H1 = project(rayOrg), project(rayEnd)
        k0, k1 = 1.0 / H0[3], 1.0 / H1[3]
        # The interpolated homogeneous version of the camera-space points
        Q0, Q1 = [c * k0 for c in rayOrg], [c * k1 for c in rayEnd]
        # Screen-space endpoints (already in pixels: no (P*0.5+0.5)*Resolution)
        P0, P1 = [H0[0] * k0, H0[1] * k0], [H1[0] * k1, H1[1] * k1]
        # If the line is degenerate, make it cover at least one pixel
        a = (P1[0] - P0[0], P1[1] - P0[1])
        if a[0] * a[0] + a[1] * a[1] < 0.0001:           # distanceSquared(P0, P1) < 0.0001
            P1 = [P1[0] + 0.01, P1[1] + 0.01]
        delta = [P1[0] - P0[0], P1[1] - P0[1]]
        # Permute so that the primary iteration is in x
        permute = False
        if abs(delta[0]) < abs(delta[1]):                # a more-vertical line
            permute = True
            delta, P0, P1 = delta[::-1], P0[::-1], P1[::-1]
        stepDir = math.copysign(1.0, delta[0]) if delta[0] != 0 else 0.0   # sign(delta.x)
        invdx = stepDir / delta[0]
        # Track the derivatives of Q and k
        dQ = [(Q1[i] - Q0[i]) * invdx for i in range(3)]
        dk = (k1 - k0) * invdx
        dP = [stepDir, delta[1] * invdx]
        # FIX (ours): where the segment leaves the viewport, as u = P.x·stepDir; the last footprint stops there
        Wm, Hm = (H, W) if permute else (W, H)
        slope = delta[1] * invdx                         # minor-axis pixels per major-axis pixel
        exitU = (Wm if stepDir > 0 else 0.0) * stepDir
        if slope != 0:
            exitU = min(exitU, P0[0] * stepDir + ((Hm if slope > 0 else 0.0) - P0[1]) / slope)
        # Pixel stride, smaller for distant origins. FIX: stride = PixelStride pixels at the camera
        strideScalar = 1.0 - min(1.0, -rayOrg[2] / PixelStrideZCutoff)
        pixelStride = 1.0 + strideScalar * (PixelStride - 1.0)
        if params.fit_stride_to_steps:                   # ours: Iterations samples span the whole clipped segment
            pixelStride = max(pixelStride, float(math.ceil(abs(delta[0]) / Iterations)))
        # FIX (PDF): dP *= pixelStride, not +=
        dP, dQ, dk = [c * pixelStride for c in dP], [c * pixelStride for c in dQ], dk * pixelStride
        P0 = [P0[i] + dP[i] * jitter for i in range(2)]
        Q0 = [Q0[i] + dQ[i] * jitter for i in range(3)]
        k0 = k0 + dk * jitter
        zMin, zMax = min(rayOrg[2], rayEnd[2]), max(rayOrg[2], rayEnd[2])
        # FIX: the first interval starts at the first sample's footprint edge, not at rayOrg.z (nor Q0.z)
        prevZMaxEstimate = toZ(Q0[2] + 0.5 * dQ[2], k0 + 0.5 * dk, zMin, zMax)
        P, Qz, k, count, steps = list(P0), Q0[2], k0, 0.0, 0
        end = P1[0] * stepDir
        stop = min(end, exitU)                           # P1 or the viewport edge, whichever comes first
        ended = BEHIND_CAMERA if clipped else MAX_DISTANCE
        intersect = False
        for i in range(Iterations):
            P, Qz, k, count = [P[0] + dP[0], P[1] + dP[1]], Qz + dQ[2], k + dk, count + 1.0   # pqk += dPQK
            half, last, u = 0.5, False, P[0] * stepDir
            if u > stop:                    # FIX: stop at P1 (G3D) or at the viewport edge (ours)
                f = min(max((stop - u) / pixelStride + 0.5, 0.0), 1.0)
                if f <= 0.0:                             # the previous footprint reached it: the ray ended
                    return (ended if u > end else OFF_SCREEN), None, None, steps
                # FIX (ours): a shortened last footprint [P − ½dP, stop], sampled at its centre
                back = 0.5 * (1.0 - f)
                P, Qz, k, count = [P[0] - dP[0] * back, P[1] - dP[1] * back], Qz - dQ[2] * back, k - dk * back, \
                    count - back
                half, last = 0.5 * f, True
            hitPixel = (P[1], P[0]) if permute else (P[0], P[1])
            scene = texelFetch(b, hitPixel)
            if scene is None:
                return OFF_SCREEN, None, None, steps
            steps += 1
            # the ray's z over this sample's footprint [P − ½dP, P + ½dP] (the last one ends at stop)
            rayZMin = prevZMaxEstimate
            rayZMax = toZ(dQ[2] * half + Qz, dk * half + k, zMin, zMax)
            prevZMaxEstimate = rayZMax
            if rayZMin > rayZMax:                        # swapGEQ
                rayZMin, rayZMax = rayZMax, rayZMin
            sceneZMax, geometry = scene
            # layered depth (kode80): the texel reaches down to its back face
            sceneZBack = backDepth[b][0][math.floor(hitPixel[1])][math.floor(hitPixel[0])] if backDepth else sceneZMax
            layer2 = False
            if secondDepth:                              # G3D traceScreenSpaceRay2: the layer behind, too
                z2 = secondDepth[b][0][math.floor(hitPixel[1])][math.floor(hitPixel[0])]
                layer2 = rayZMax >= z2 - zThickness and rayZMin <= z2
            if geometry and ((rayZMax >= sceneZBack - zThickness and rayZMin <= sceneZMax) or layer2):
                intersect = True
                break
            if last:                                     # reason as the full step's centre says
                return (ended if u > end else OFF_SCREEN), None, None, steps
        if not intersect:
            return OUT_OF_STEPS, None, None, steps       # FIX: running out of steps is not a hit
        if pixelStride > 1.0 and params.refinement != "none" and not (
                params.refinement == "binary" and BinarySearchIterations == 0):
            binary = params.refinement == "binary"
            coarse, best = (list(P), Qz, k, count), None
            # Back off (binary, FIX: half a stride, to the start of the footprint [P − ½dP, P + ½dP]; the article
            # backs off a whole stride; remarch: one stride, to the last miss); derivatives back to single pixels
            back = 0.5 if binary else 1.0
            P, Qz, k, count = [P[0] - dP[0] * back, P[1] - dP[1] * back], Qz - dQ[2] * back, k - dk * back, count - back
            invStride = 1.0 / pixelStride
            dP1, dQz1, dk1 = [dP[0] * invStride, dP[1] * invStride], dQ[2] * invStride, dk * invStride
            if binary:                                   # §1.3: walk ±stride, halving every time
                originalStride = pixelStride * 0.5
                stride = originalStride
                rounds = BinarySearchIterations
            else:                                        # G3D: single pixels up to 1.4·stride
                stride, rounds = 1.0, math.floor(1.4 * pixelStride)
            for j in range(1, rounds + 1):
                P, Qz, k = [P[0] + dP1[0] * stride, P[1] + dP1[1] * stride], Qz + dQz1 * stride, k + dk1 * stride
                count = count + stride * invStride
                scene = texelFetch(b, (P[1], P[0]) if permute else (P[0], P[1]))
                if scene is not None:
                    steps += 1
                if binary:                               # FIX: "ray at or behind this texel", no thickness
                    behind = scene is not None and scene[1] and toZ(Qz, k, zMin, zMax) <= scene[0]
                    originalStride *= 0.5
                    stride = -originalStride if behind else originalStride
                else:
                    zA = toZ(Qz - 0.5 * dQz1, k - 0.5 * dk1, zMin, zMax)
                    zB = toZ(Qz + 0.5 * dQz1, k + 0.5 * dk1, zMin, zMax)
                    behind = scene is not None and scene[1] and min(zA, zB) <= scene[0]
                if behind and (best is None or count <= best[3]):
                    best = (list(P), Qz, k, count)       # FIX: keep the nearest probe behind, not the last probe
                if behind and not binary:
                    break
            if best is None and binary:                  # the crossing is past the last probe: the far end,
                P, Qz, k = coarse[0], coarse[1], coarse[2]   # if the ray there is just in front of its texel
                far = ([P[0] + dP[0] * 0.5, P[1] + dP[1] * 0.5], Qz + dQ[2] * 0.5, k + dk * 0.5, coarse[3] + 0.5)
                scene = texelFetch(b, (far[0][1], far[0][0]) if permute else tuple(far[0]))
                if scene is not None:
                    steps += 1
                if scene is not None and scene[1] and toZ(far[1], far[2], zMin, zMax) <= scene[0] + zThickness:
                    best = far
            P, Qz, k, count = best if best is not None else coarse   # else a thin feature: keep the coarse hit
        hitPixel = (P[1], P[0]) if permute else (P[0], P[1])
        # FIX: Q.xy advanced by the same count as Q.z (the article uses count = i, one step short)
        Q = (Q0[0] + dQ[0] * count, Q0[1] + dQ[1] * count, Qz)
        hitPoint = (Q[0] / k, Q[1] / k, Q[2] / k)
        return HIT, hitPixel, hitPoint, steps

    term = [[[[NO_RAY] * W for _ in range(H)]] for _ in range(B)]
    steps = [[[[0] * W for _ in range(H)]] for _ in range(B)]
    hit_pixel = [[[[-1.0] * W for _ in range(H)] for _ in range(2)] for _ in range(B)]
    hit_view = [[[[0.0] * W for _ in range(H)] for _ in range(3)] for _ in range(B)]
    raw = [[[[0.0] * W for _ in range(H)] for _ in range(3)] for _ in range(B)]
    fade = [[[[0.0] * W for _ in range(H)]] for _ in range(B)]
    for b in range(B):
        for j in range(H):
            for i in range(W):
                if not mask[b][0][j][i] or depth[b][0][j][i] > -cam.near:
                    continue                             # background, or nearer than the near plane: no ray
                vUv = ((i + 0.5) / W, 1.0 - (j + 0.5) / H)
                viewZ = depth[b][0][j][i]
                rayOrg = ((UvToViewParams[0] * vUv[0] + UvToViewParams[2]) * viewZ,
                          (UvToViewParams[1] * vUv[1] + UvToViewParams[3]) * viewZ, viewZ)
                viewNormal = tuple(normal[b][c][j][i] for c in range(3))
                rayDir = normalize(reflect(normalize(rayOrg), viewNormal))
                t, hitPixel, hitPoint, n = traceScreenSpaceRay(b, rayOrg, rayDir, jitters[b][0][j][i])
                term[b][0][j][i], steps[b][0][j][i] = t, n
                if t != HIT:
                    continue
                col, row = min(max(math.floor(hitPixel[0]), 0), W - 1), min(max(math.floor(hitPixel[1]), 0), H - 1)
                for c in range(3):
                    hit_view[b][c][j][i] = hitPoint[c]
                    raw[b][c][j][i] = colors[b][c][row][col]
                hit_pixel[b][0][j][i], hit_pixel[b][1][j][i] = hitPixel
                # §1.4 edge fade: vignette at vUv (this pixel) or circular at hitPixel; §1.5 distance fade
                if params.edge_fade_mode == "circular":
                    uv = (hitPixel[0] / W, 1.0 - hitPixel[1] / H)
                    uvFactor = (2.0 * math.sqrt((uv[0] - 0.5) ** 2 + (uv[1] - 0.5) ** 2)) ** 2
                    edge = max(0.0, 1.0 - uvFactor)
                else:
                    edgeuv = (vUv[0] * (1.0 - vUv[1]), vUv[1] * (1.0 - vUv[0]))     # vUv·(1 − vUv.yx)
                    edge = saturate(pow(abs(edgeuv[0] * edgeuv[1] * params.edge_distance), params.edge_exponent))
                d = math.sqrt(sum((rayOrg[c] - hitPoint[c]) ** 2 for c in range(3)))    # length(rayOrg − hitPoint)
                fade[b][0][j][i] = edge * saturate(1.0 - pow(d / params.fade_distance, params.fade_exponent))

    dt, dev = gbuffer.view_z.dtype, gbuffer.view_z.device
    f = lambda x, dtype=dt: torch.tensor(x, dtype=dtype, device=dev)                   # noqa: E731
    fade_t, raw_t, term_t = f(fade), f(raw), f(term, torch.int8)
    return SSRResult(color=raw_t * fade_t, hit=term_t == HIT, hit_pixel=f(hit_pixel), hit_view=f(hit_view),
                     steps=f(steps, torch.int32), termination=term_t, fade=fade_t, raw_color=raw_t)
