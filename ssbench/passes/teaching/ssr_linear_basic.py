"""Linear SSR, one pixel at a time: the SSR article's shader (§1) transliterated line by line.

This file exists only to teach. It is a slow per-pixel Python loop whose functions and variables carry the
shader's names (``getDepth``, ``getViewZ``, ``getViewPosition``, ``rayIntersectsDepth``, ``rayOrg``,
``rayDir``, ``rayLength``, ``rayEnd``, ``Q0``, ``Q1``, ``delta``, ``deltaStep``, ``hitPixel``, ``intersect``,
``originalStride``, ``stride``, ``uvFactor``, ``edgeuv``...). It follows :func:`ssbench.passes.ssr.linear.ssr_linear`
in the places where that pass departs from the shader (termination codes, the bisection's bracket and kept
probe, the jitter; see its module docstring) and draws the same jitter with the same generator call, so the
two agree to round-off (``tests/passes/ssr/test_linear.py``). Use the vectorised pass for anything but 16×12
images.
"""
from __future__ import annotations

import math
from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..ssr.common import BEHIND_CAMERA, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS, SSRResult
from ..ssr.linear import MAX_BINARY_SEARCH_ITERATIONS, LinearSSRParams, check_inputs
from ..ssr.linear_rays import jitter_noise


def ssr_linear_basic(gbuffer: GBuffer, params: LinearSSRParams = LinearSSRParams(),
                     generator: Optional[torch.Generator] = None) -> SSRResult:
    """Per-pixel linear SSR; returns :class:`SSRResult` like :func:`~ssbench.passes.ssr.linear.ssr_linear`.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
        >>> z = torch.full((1, 1, 3, 4), -2.0)
        >>> n = torch.zeros(1, 3, 3, 4); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=z, normal=n, mask=torch.ones_like(z, dtype=torch.bool), color=n)
        >>> ssr_linear_basic(g).termination.flatten().tolist()     # 2 = off screen: rays come back outward
        [2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2]
    """
    check_inputs(gbuffer, params)
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    CameraNear, CameraFar = cam.near, cam.far
    CameraProjectionMatrix = cam.projection_matrix().tolist()                  # row-major: M[row][col]
    CameraInverseProjectionMatrix = cam.inverse_projection_matrix().tolist()
    # uniforms
    MaxRayDistance, Iterations, Thickness = params.max_ray_distance, params.iterations, params.thickness
    MAX_ITERATIONS, BinarySearchIterations = params.max_iterations, params.binary_search_iterations
    EdgeDistance, EdgeExponent = params.edge_distance, params.edge_exponent
    FadeDistance, FadeExponent, Jitter = params.fade_distance, params.fade_exponent, params.jitter
    xi = jitter_noise(params, generator, (B, 1, H, W))
    xi = xi.tolist() if xi is not None else None
    from_depth, backface = params.position_from == "depth", params.use_back_face_depth
    # textures (B, C, H, W) as nested lists
    DepthSampler = (cam.view_z_to_depth(gbuffer.view_z) if from_depth else gbuffer.view_z).tolist()
    mask, ViewZ = gbuffer.mask.tolist(), gbuffer.view_z.tolist()
    NormalSampler, ColorSampler = gbuffer.normal.tolist(), gbuffer.color.tolist()
    BackDepthSampler = (torch.where(gbuffer.mask, gbuffer.back_z, gbuffer.view_z).tolist() if backface else None)
    PositionSampler = gbuffer.position.tolist() if params.position_from == "position" else None

    def texture2D(tex, b, uv):                                       # NEAREST, CLAMP_TO_EDGE, row 0 at the top
        col = min(max(math.floor(uv[0] * W), 0), W - 1)
        row = min(max(math.floor((1.0 - uv[1]) * H), 0), H - 1)
        return [tex[b][c][row][col] for c in range(len(tex[b]))]

    def getDepth(b, uv):
        return texture2D(DepthSampler, b, uv)[0]

    def getViewZ(depth):                                             # perspectiveDepthToViewZ
        if not from_depth:
            return depth
        return (CameraNear * CameraFar) / ((CameraFar - CameraNear) * depth - CameraFar)

    def getViewPosition(uv, depth, viewZ):                           # SSAO getViewPosition (SSAO article §2.2)
        clipW = -viewZ                                               # CameraProjectionMatrix[2][3]·viewZ + [3][3]
        clipPosition = [(uv[0] * 2 - 1) * clipW, (uv[1] * 2 - 1) * clipW, (depth * 2 - 1) * clipW, clipW]
        M = CameraInverseProjectionMatrix
        return [sum(M[i][k] * clipPosition[k] for k in range(4)) for i in range(3)]

    def normalize(v):
        length = math.sqrt(sum(x * x for x in v))
        return [x / max(length, 2.2250738585072014e-308) for x in v]

    def reflect(I, N):                                               # I − 2·dot(N, I)·N
        d = sum(N[k] * I[k] for k in range(3))
        return [I[k] - 2.0 * d * N[k] for k in range(3)]

    def project(Q):                                                  # clip = P·(Q, 1); P = clip.xy / clip.w
        M = CameraProjectionMatrix
        clip = [sum(M[i][k] * x for k, x in enumerate(Q + [1.0])) for i in range(4)]
        P = [clip[0] / clip[3], clip[1] / clip[3]]
        return [P[0] * 0.5 + 0.5, P[1] * 0.5 + 0.5]                  # hitPixel (uv)

    def rayIntersectsDepth(b, z, uv):
        if not texture2D(mask, b, uv)[0]:                            # cleared background: nothing to hit
            return False                                             # (three.js: if (-vZ >= cameraFar) continue)
        sceneZMax = getViewZ(getDepth(b, uv))
        dist = z - sceneZMax
        if backface:                                                 # rayIntersectsDepthBF: [back − T, front)
            backZ = texture2D(BackDepthSampler, b, uv)[0]
            return dist < 0.0 and z > backZ - Thickness
        return dist < 0.0 and dist > -Thickness

    def saturate(x):
        return min(max(x, 0.0), 1.0)

    color = [[[[0.0] * W for _ in range(H)] for _ in range(3)] for _ in range(B)]
    raw_color = [[[[0.0] * W for _ in range(H)] for _ in range(3)] for _ in range(B)]
    hit_pixel = [[[[-1.0] * W for _ in range(H)] for _ in range(2)] for _ in range(B)]
    hit_view = [[[[0.0] * W for _ in range(H)] for _ in range(3)] for _ in range(B)]
    fade = [[[[1.0] * W for _ in range(H)]] for _ in range(B)]
    steps = [[[[0] * W for _ in range(H)]] for _ in range(B)]
    termination = [[[[NO_RAY] * W for _ in range(H)]] for _ in range(B)]
    for b in range(B):
        for row in range(H):
            for col in range(W):
                if not mask[b][0][row][col] or ViewZ[b][0][row][col] > -CameraNear:
                    continue                                         # background, or nearer than near: no ray
                vUv = [(col + 0.5) / W, 1.0 - (row + 0.5) / H]
                # ---- §1.1 reflection vector ----
                if PositionSampler is not None:
                    viewPosition = [PositionSampler[b][k][row][col] for k in range(3)]
                else:
                    depth = getDepth(b, vUv)
                    viewZ = getViewZ(depth)
                    if from_depth:
                        viewPosition = getViewPosition(vUv, depth, viewZ)
                    else:                                            # uvToView(vUv, viewZ)
                        a0, a1, b0, b1 = cam.uv_to_view_params()
                        viewPosition = [(a0 * vUv[0] + b0) * viewZ, (a1 * vUv[1] + b1) * viewZ, viewZ]
                viewNormal = [NormalSampler[b][k][row][col] for k in range(3)]
                rayOrg = viewPosition
                rayDir = normalize(reflect(normalize(rayOrg), viewNormal))
                # ---- §1.2 clip to the near plane, equal steps ----
                if rayOrg[2] + rayDir[2] * MaxRayDistance > -CameraNear:
                    rayLength = min(max((-CameraNear - rayOrg[2]) / rayDir[2], 0.0), MaxRayDistance)
                else:
                    rayLength = MaxRayDistance
                rayEnd = [rayOrg[k] + rayDir[k] * rayLength for k in range(3)]
                Q0, Q1 = rayOrg, rayEnd
                delta = [Q1[k] - Q0[k] for k in range(3)]
                deltaStep = [delta[k] / Iterations for k in range(3)]
                j0 = 0.0 if xi is None else Jitter * xi[b][0][row][col]  # start jitter, in steps
                Q = [Q0[k] - deltaStep[k] * j0 for k in range(3)] if xi is not None else list(Q0)
                intersect, offScreen, count, hitIndex = False, False, 0, -1
                for i in range(MAX_ITERATIONS):
                    if float(i) >= Iterations:
                        break
                    if intersect:
                        break
                    Q = [Q[k] + deltaStep[k] for k in range(3)]      # Q += deltaStep
                    hitPixel = project(Q)
                    count += 1
                    if not (0.0 <= hitPixel[0] <= 1.0 and 0.0 <= hitPixel[1] <= 1.0):
                        offScreen = True                             # left the screen: stop
                        break
                    intersect = rayIntersectsDepth(b, Q[2], hitPixel)
                    hitIndex = i
                # ---- §1.3 binary search: bisect the last step, keep the last probe that hit ----
                nBS = min(BinarySearchIterations, MAX_BINARY_SEARCH_ITERATIONS)
                if BinarySearchIterations > 0 and intersect:
                    hitQ = Q
                    if hitIndex == 0:                                # Q −= deltaStep, never behind rayOrg
                        Q = list(rayOrg)
                        deltaStep = [hitQ[k] - rayOrg[k] for k in range(3)]
                    else:
                        Q = [Q[k] - deltaStep[k] for k in range(3)]
                    originalStride = 0.5
                    stride = originalStride
                    for j in range(nBS):
                        Q = [Q[k] + deltaStep[k] * stride for k in range(3)]
                        hitPixel = project(Q)
                        probe = rayIntersectsDepth(b, Q[2], hitPixel)
                        if probe:
                            hitQ = Q
                        originalStride *= 0.5
                        stride = -originalStride if probe else originalStride
                    Q = hitQ
                    count += nBS
                steps[b][0][row][col] = count
                if intersect:
                    termination[b][0][row][col] = HIT
                elif offScreen:
                    termination[b][0][row][col] = OFF_SCREEN
                elif Iterations > MAX_ITERATIONS:
                    termination[b][0][row][col] = OUT_OF_STEPS
                else:
                    termination[b][0][row][col] = BEHIND_CAMERA if rayLength < MaxRayDistance else MAX_DISTANCE
                if not intersect:
                    continue
                # ---- colour and fades (§1.4, §1.5) ----
                hitPixel = project(Q)
                hitPoint = Q
                c = texture2D(ColorSampler, b, hitPixel)
                if params.edge_fade_mode == "circular":
                    uvFactor = 2.0 * math.sqrt((hitPixel[0] - 0.5) ** 2 + (hitPixel[1] - 0.5) ** 2)
                    uvFactor *= uvFactor
                    edge = max(0.0, 1.0 - uvFactor)
                else:
                    edgeuv = [vUv[0] * (1.0 - vUv[1]), vUv[1] * (1.0 - vUv[0])]
                    edge = edgeuv[0] * edgeuv[1] * EdgeDistance
                    edge = saturate(pow(abs(edge), EdgeExponent))
                d = math.sqrt(sum((rayOrg[k] - hitPoint[k]) ** 2 for k in range(3)))
                alpha = saturate(1.0 - pow(d / FadeDistance, FadeExponent)) * edge
                fade[b][0][row][col] = alpha
                for k in range(3):
                    raw_color[b][k][row][col] = c[k]
                    color[b][k][row][col] = c[k] * alpha
                    hit_view[b][k][row][col] = hitPoint[k]
                hit_pixel[b][0][row][col] = hitPixel[0] * W                # uv -> pixel (py down)
                hit_pixel[b][1][row][col] = (1.0 - hitPixel[1]) * H
    dt, dev = gbuffer.view_z.dtype, gbuffer.view_z.device
    term = torch.tensor(termination, dtype=torch.int8, device=dev)
    return SSRResult(color=torch.tensor(color, dtype=dt, device=dev), hit=term == HIT,
                     hit_pixel=torch.tensor(hit_pixel, dtype=dt, device=dev),
                     hit_view=torch.tensor(hit_view, dtype=dt, device=dev),
                     steps=torch.tensor(steps, dtype=torch.int32, device=dev), termination=term,
                     fade=torch.tensor(fade, dtype=dt, device=dev),
                     raw_color=torch.tensor(raw_color, dtype=dt, device=dev))
