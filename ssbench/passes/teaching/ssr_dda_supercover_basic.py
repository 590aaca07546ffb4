"""The supercover DDA, one ray at a time: Amanatides & Woo's grid walk with their names, for reading.

This file exists only to teach. The ray set-up (near-plane clipping, homogeneous pixel endpoints ``P0``/``P1``,
``Q``, ``k``, ``permute``, ``stepDir``) is the DDA's (``ssr.dda_rays.dda_rays`` at stride 1; the DDA's own teaching twin
spells it out); what follows is the walk of :mod:`ssbench.passes.ssr.dda_supercover` as a plain Python loop over
floats: ``X, Y`` the current pixel, ``tMaxX``/``tMaxY`` the line parameter of the next column / row edge,
``tDeltaX``/``tDeltaY`` the parameter per pixel, ``stepX``/``stepY`` the directions. The line parameter ``n`` is
in major-axis pixels from ``P0``. It agrees with the vectorised pass (``tests/passes/ssr/test_dda_supercover.py``).
"""
from __future__ import annotations

import math
import sys

import torch

from ...gbuffer import GBuffer
from ..ssr.common import BEHIND_CAMERA, HIT, MAX_DISTANCE, OFF_SCREEN, OUT_OF_STEPS, SSRResult
from ..ssr.dda import check_inputs
from ..ssr.dda_rays import dda_rays
from ..ssr.dda_assemble import assemble
from ..ssr.dda_state import MarchOutput
from ..ssr.dda_supercover import SupercoverDDASSRParams

TINY = sys.float_info.min                              # torch.finfo(float64).tiny


def ray_z(ray: dict, n: float) -> float:
    """Perspective-correct view z at line parameter ``n`` (``Q.z / k``), clamped to the segment's z range."""
    z = (ray["Qz"] + ray["dQz"] * n) / max(ray["k"] + ray["dk"] * n, TINY)
    return min(max(z, ray["zlo"]), ray["zhi"])


def walk(ray: dict, view_z, mask, params: SupercoverDDASSRParams, H: int, W: int):
    """March one ray; returns ``(termination, fetches, n_hit or None, X, Y)`` (``X, Y`` in the permuted frame)."""
    Px, Py, stepX, dPy = ray["Px"], ray["Py"], int(ray["stepDir"]), ray["dPy"]
    X, Y = math.floor(Px), math.floor(Py)                          # the origin pixel: never fetched
    stepY = (dPy > 0) - (dPy < 0)
    tMaxX = ((X + 1 if stepX > 0 else X) - Px) * stepX             # dP.x = stepDir: one major pixel per unit of n
    tMaxY = ((Y + 1 if dPy > 0 else Y) - Py) / dPy if dPy != 0 else math.inf
    tDeltaX, tDeltaY = 1.0, (1.0 / abs(dPy) if dPy != 0 else math.inf)
    nEnd = ray["end"] - Px * stepX                                 # P1
    width, height = (H, W) if ray["permute"] else (W, H)           # the permuted screen
    for fetches in range(params.max_steps):
        nA = min(tMaxX, tMaxY)                                     # the edge we cross into the next pixel
        if tMaxX <= tMaxY:
            X, tMaxX = X + stepX, tMaxX + tDeltaX
        if nA == tMaxY:                                            # (both at a lattice corner)
            Y, tMaxY = Y + stepY, tMaxY + tDeltaY
        nB = min(tMaxX, tMaxY, nEnd)                               # where the ray leaves this pixel (or ends)
        if nA >= nEnd:
            return (BEHIND_CAMERA if ray["clipped"] else MAX_DISTANCE), fetches, None, X, Y
        if not (0 <= X < width and 0 <= Y < height):
            return OFF_SCREEN, fetches, None, X, Y
        x, y = (Y, X) if ray["permute"] else (X, Y)                # texelFetch(hitPixel)
        sceneZMax, geometry = view_z[ray["b"]][y][x], mask[ray["b"]][y][x]
        zA, zB = ray_z(ray, nA), ray_z(ray, nB)
        rayZMin, rayZMax = min(zA, zB), max(zA, zB)
        if geometry and rayZMax >= sceneZMax - params.z_thickness and rayZMin <= sceneZMax:
            if zA <= sceneZMax:                                    # entered the pixel already behind the texel
                return HIT, fetches + 1, nA, X, Y
            den = ray["dQz"] - sceneZMax * ray["dk"]               # Q.z(n) = sceneZMax·k(n)
            n_star = (sceneZMax * ray["k"] - ray["Qz"]) / den if den != 0 else nA
            n_star = n_star if math.isfinite(n_star) else nA
            return HIT, fetches + 1, min(max(n_star, nA), nB), X, Y
    return OUT_OF_STEPS, params.max_steps, None, X, Y


def ssr_dda_supercover_basic(gbuffer: GBuffer,
                             params: SupercoverDDASSRParams = SupercoverDDASSRParams()) -> SSRResult:
    """Per-ray supercover DDA SSR; returns an :class:`SSRResult` like
    :func:`~ssbench.passes.ssr.dda_supercover.ssr_dda_supercover` (``debug`` empty).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 3, 4); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 3, 4), -2.0), normal=n,
        ...             mask=torch.ones(1, 1, 3, 4, dtype=torch.bool), color=torch.ones(1, 3, 3, 4))
        >>> ssr_dda_supercover_basic(g).termination.flatten().tolist()   # toward the camera: off screen
        [2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2]
    """
    dda = params.dda()
    check_inputs(gbuffer, dda)
    B, _, H, W = gbuffer.view_z.shape
    dt, dev = gbuffer.view_z.dtype, gbuffer.view_z.device
    s, sel, P0, P1 = dda_rays(gbuffer, dda, torch.zeros(B, 1, H, W, dtype=torch.float64))
    view_z, mask = gbuffer.view_z[:, 0].tolist(), gbuffer.mask[:, 0].tolist()
    N = sel.numel()
    o = MarchOutput.empty(N, dt, "cpu", OUT_OF_STEPS)
    for r in range(N):
        ray = s.ray(r)                                             # the DDA's set-up of this pixel, as floats
        term, fetches, n, X, Y = walk(ray, view_z, mask, params, H, W)
        o.term[r], o.steps[r] = term, fetches
        if n is not None:                                          # hitPoint = Q/k, the pixel clamped into (X, Y)
            x = min(max(ray["Px"] + ray["stepDir"] * n, X), math.nextafter(X + 1, X))
            y = min(max(ray["Py"] + ray["dPy"] * n, Y), math.nextafter(Y + 1, Y))
            o.P[r] = torch.tensor([y, x] if ray["permute"] else [x, y], dtype=dt)
            o.Q[r] = torch.tensor([ray["Q0x"] + ray["dQx"] * n, ray["Q0y"] + ray["dQy"] * n,
                                   ray["Qz"] + ray["dQz"] * n], dtype=dt)
            o.k[r] = ray["k"] + ray["dk"] * n
    o = MarchOutput(**{f: getattr(o, f).to(dev) for f in ("term", "steps", "P", "Q", "k")})
    return assemble(gbuffer, params, sel, P1, o, None)
