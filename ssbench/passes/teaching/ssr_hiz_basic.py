"""Hi-Z screen-space reflections, one pixel at a time: FidelityFX SSSR's hierarchical ray march line by line.

This file exists only to teach. It is a slow per-pixel Python loop, one function per step of AMD's
``ffx_sssr.h`` (2020) with its names (``InitialAdvanceRay``, ``AdvanceRay``, ``current_mip``, ``current_t``,
``position``, ``surface_z``, ``skipped_tile``, ``boundary_planes``, ``floor_offset``), in pixel units over a
reversed-depth *max* pyramid (``ssbench.passes.ssr.hiz_pyramid``: FidelityFX's min pyramid of standard depth,
mirrored) and with the fixes of :mod:`ssbench.passes.ssr.hiz` marked ``# FIX``. It agrees with
:func:`~ssbench.passes.ssr.hiz.ssr_hiz` (``tests/passes/ssr/test_hiz.py``). :func:`trace_ray` returns one ray's
walk for the lesson. Use the vectorised pass for anything but tiny images.
"""
from __future__ import annotations

import math
from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..ssr.common import BEHIND_CAMERA, BEHIND_SURFACE, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS
from ..ssr.dda_assemble import assemble
from ..ssr.dda_state import MarchOutput
from ..ssr.hiz import HiZSSRParams, check_inputs
from ..ssr.hiz_march import BIG, EPSILON

INF = math.inf


def build_pyramid(rz):
    """Level 0 is ``rz`` (a list of rows); each next level keeps the largest (closest) of up to 2×2 cells."""
    levels = [rz]
    while len(levels[-1]) > 1 or len(levels[-1][0]) > 1:
        prev = levels[-1]
        h, w = (len(prev) + 1) // 2, (len(prev[0]) + 1) // 2
        levels.append([[max(prev[y][x] for y in (2 * cy, 2 * cy + 1) for x in (2 * cx, 2 * cx + 1)
                            if y < len(prev) and x < len(prev[0])) for cx in range(w)] for cy in range(h)])
    return levels


def inverse(d):
    """``inv_direction``: ``1/d``, or :data:`BIG` for an axis the ray does not move along."""
    return 1.0 / d if d != 0 else BIG


def boundary_t(o, d, cell, size):
    """``t`` where ``o + t·d`` leaves ``cell`` (``size`` px wide) through its far side, ``EPSILON`` past it."""
    floor_offset = 1.0 if d >= 0 else 0.0
    plane = (cell + floor_offset) * size + EPSILON * (1.0 if d > 0 else -1.0 if d < 0 else 0.0)
    return (plane - o) * inverse(d)


def InitialAdvanceRay(origin, direction):
    """Move from the pixel centre to just past the origin texel's border (no self-hit), at most to ``t = 1``."""
    t = min(boundary_t(origin[0], direction[0], math.floor(origin[0]), 1.0),
            boundary_t(origin[1], direction[1], math.floor(origin[1]), 1.0))
    return min(t, 1.0)


def AdvanceRay(origin, direction, current_t, current_mip, surface_z, cell):
    """One step at ``current_mip``: ``(current_t, skipped_tile, above_surface, side_t)``."""
    size = 2.0 ** current_mip
    t_x = boundary_t(origin[0], direction[0], cell[0], size)
    t_y = boundary_t(origin[1], direction[1], cell[1], size)
    t_z = (surface_z - origin[2]) * (1.0 / direction[2]) if direction[2] < 0 and surface_z > 0 else INF   # sky: never
    position_z = origin[2] + current_t * direction[2]
    above_surface = position_z > surface_z or surface_z <= 0   # in front of the cell's closest depth (0: sky)
    side_t = min(t_x, t_y)
    skipped_tile = above_surface and side_t < t_z
    if above_surface:
        current_t = min(side_t, t_z)
    return current_t, skipped_tile, above_surface, side_t


def thickness_at(z, params):
    return params.depth_buffer_thickness * (abs(z) if params.thickness_mode == "relative" else 1.0)


def validate_hit(view_z, back_z, normal, ray_z_view, ray_dir, params):
    """Within the thickness behind the texel (and facing the ray, with ``reject_backfaces``)?"""
    bottom = (back_z if params.use_back_face_depth else view_z) - thickness_at(view_z, params)
    ok = ray_z_view >= bottom
    if params.reject_backfaces and sum(ray_dir[c] * normal[c] for c in range(3)) > 0:
        ok = False
    return ok


def second_layer(second_z, ray_z_view, params):
    """``(hit, in_front)`` against the second depth layer: within its thickness, or still in front of it."""
    if second_z is None:
        return False, False
    return second_z - thickness_at(second_z, params) <= ray_z_view <= second_z, ray_z_view > second_z


def trace_ray(levels, texel, origin, direction, ray_dir, clipped, params, near, path=None):
    """``FFX_SSSR_HierarchicalRaymarch`` for one ray: ``(termination, steps, position)``; ``path`` (a list)
    collects ``(current_mip, cell, current_t, above_surface, skipped_tile)`` per read."""
    H, W = len(levels[0]), len(levels[0][0])
    top = min(params.max_mip, len(levels) - 1)
    ended = BEHIND_CAMERA if clipped else MAX_DISTANCE
    current_t, current_mip = InitialAdvanceRay(origin, direction), 0
    if current_t >= 1.0:
        return ended, 0, None
    for i in range(params.max_traversal_intersections):
        position = [origin[c] + current_t * direction[c] for c in range(3)]
        if not (0 <= position[0] < W and 0 <= position[1] < H):
            return OFF_SCREEN, i, None
        size = 2.0 ** current_mip
        cell = (math.floor(position[0] / size), math.floor(position[1] / size))
        surface_z = levels[current_mip][cell[1]][cell[0]]
        current_t, skipped_tile, above, side_t = AdvanceRay(origin, direction, current_t, current_mip, surface_z, cell)
        if path is not None:
            path.append((current_mip, cell, current_t, above, skipped_tile))
        current_mip = min(current_mip + 1, top) if skipped_tile else current_mip - 1
        if current_mip < 0:                                    # behind a level-0 texel: a candidate
            view_z, back_z, normal, second_z = texel(cell[0], cell[1])
            ray_z_view = -near / position[2]
            first = validate_hit(view_z, back_z, normal, ray_z_view, ray_dir, params)
            hit2, in_front2 = second_layer(second_z, ray_z_view, params)
            if first or hit2:
                return HIT, i + 1, position
            if in_front2 and direction[2] < 0 and second_z > -INF:   # the second layer, reached inside this texel?
                t2 = (near / -second_z - origin[2]) * (1.0 / direction[2])
                if t2 <= side_t:
                    return HIT, i + 1, [origin[c] + t2 * direction[c] for c in range(3)]
            if not (params.trace_behind or in_front2):         # FidelityFX: the ray ends behind the surface
                return BEHIND_SURFACE, i + 1, None
            current_t, current_mip = side_t, 0                 # HDRP / second layer: cross this texel, go on
        if current_t >= 1.0:
            return ended, i + 1, None
    return OUT_OF_STEPS, params.max_traversal_intersections, None   # FIX: never a hit (FidelityFX: valid_hit)


def setup_ray(cam, W, H, view_z, normal, i, j, max_ray_distance):
    """The ray of pixel ``(i, j)`` (view z ``view_z``, unit ``normal``): ``(origin, direction, d, clipped, P1)``
    with ``origin`` the pixel centre in ``(px, py, rz)``, ``direction`` the clipped segment per unit ``t``, ``d``
    the unit view-space mirror direction and ``P1`` the segment's end in pixels."""
    near = cam.near
    a0, a1, b0, b1 = cam.uv_to_view_params()
    u, v = (i + 0.5) / W, 1.0 - (j + 0.5) / H
    o = ((a0 * u + b0) * view_z, (a1 * v + b1) * view_z, view_z)                      # rayOrg
    length = math.sqrt(sum(c * c for c in o))
    inc = [c / length for c in o]
    dn = sum(inc[c] * normal[c] for c in range(3))
    d = [inc[c] - 2.0 * dn * normal[c] for c in range(3)]                              # reflect(I, N)
    dl = math.sqrt(sum(c * c for c in d))
    d = [c / dl for c in d]
    clipped = o[2] + d[2] * max_ray_distance > -near                                   # FIX: clip before projecting
    L = min(max((-near - o[2]) / d[2], 0.0), max_ray_distance) if clipped else max_ray_distance
    e = [o[c] + d[c] * L for c in range(3)]
    M = cam.projection_matrix().tolist()
    clip = [sum(M[r][c] * e[c] for c in range(3)) + M[r][3] for r in (0, 1, 3)]
    P1 = ((clip[0] / clip[2] + 1.0) * 0.5 * W, (1.0 - (clip[1] / clip[2] + 1.0) * 0.5) * H)
    origin = (i + 0.5, j + 0.5, near / -o[2])
    direction = (P1[0] - origin[0], P1[1] - origin[1], near / -e[2] - origin[2])
    return origin, direction, d, clipped, P1


def trace_pixel(gbuffer: GBuffer, params: HiZSSRParams = HiZSSRParams(), pixel=(0, 0)) -> dict:
    """One ray of batch item 0, for the lesson: ``{"termination", "steps", "position", "path", "levels",
    "origin", "direction", "p1"}``; ``path`` as :func:`trace_ray` collects it, ``levels`` the pyramid."""
    check_inputs(gbuffer, params)
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    i, j = pixel
    if not (0 <= i < W and 0 <= j < H) or not bool(gbuffer.mask[0, 0, j, i]):
        raise ValueError(f"pixel: must be a mask pixel inside the {W}x{H} image, got {pixel!r}")
    z, mask = gbuffer.view_z[0, 0].double().tolist(), gbuffer.mask[0, 0].tolist()
    normal = gbuffer.normal[0].double()
    back = gbuffer.back_z[0, 0].double().tolist() if params.use_back_face_depth else None
    second = gbuffer.second_z[0, 0].double().tolist() if params.use_second_layer else None
    levels = build_pyramid([[cam.near / -z[y][x] if mask[y][x] else 0.0 for x in range(W)] for y in range(H)])
    origin, direction, d, clipped, P1 = setup_ray(cam, W, H, z[j][i], normal[:, j, i].tolist(), i, j,
                                                  params.max_ray_distance)
    path = []
    term, steps, pos = trace_ray(levels, lambda x, y: (z[y][x], back[y][x] if back else None,
                                                      normal[:, y, x].tolist(), second[y][x] if second else None),
                                 origin, direction, d, clipped, params, cam.near, path)
    return {"termination": term, "steps": steps, "position": pos, "path": path, "levels": levels,
            "origin": origin, "direction": direction, "p1": P1}


def ssr_hiz_basic(gbuffer: GBuffer, params: HiZSSRParams = HiZSSRParams(),
                  generator: Optional[torch.Generator] = None):
    """Per-pixel Hi-Z SSR; the same :class:`~ssbench.passes.ssr.common.SSRResult` as :func:`ssr_hiz`."""
    check_inputs(gbuffer, params)
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    near = cam.near
    z = gbuffer.view_z.double().tolist()
    mask, normal = gbuffer.mask.tolist(), gbuffer.normal.double().tolist()
    back = gbuffer.back_z.double().tolist() if params.use_back_face_depth else None
    second = gbuffer.second_z.double().tolist() if params.use_second_layer else None
    a0, a1, b0, b1 = cam.uv_to_view_params()
    rows, outs, ends = [], [], []
    for b in range(B):
        rz = [[near / -z[b][0][y][x] if mask[b][0][y][x] else 0.0 for x in range(W)] for y in range(H)]
        levels = build_pyramid(rz)

        def texel(x, y, b=b):
            return (z[b][0][y][x], (back[b][0][y][x] if back else None), [normal[b][c][y][x] for c in range(3)],
                    second[b][0][y][x] if second else None)

        for j in range(H):
            for i in range(W):
                if not mask[b][0][j][i] or z[b][0][j][i] > -near:
                    continue
                n = [normal[b][c][j][i] for c in range(3)]
                origin, direction, d, clipped, P1 = setup_ray(cam, W, H, z[b][0][j][i], n, i, j,
                                                              params.max_ray_distance)
                term, steps, pos = trace_ray(levels, texel, origin, direction, d, clipped, params, near)
                out = MarchOutput.empty(1, torch.float64, "cpu", term)
                out.steps[0] = steps
                if pos is not None:
                    zv = -near / pos[2]
                    uu, vv = pos[0] / W, 1.0 - pos[1] / H
                    out.P[0] = torch.tensor(pos[:2], dtype=torch.float64)
                    out.Q[0] = torch.tensor([(a0 * uu + b0) * zv, (a1 * vv + b1) * zv, zv], dtype=torch.float64)
                rows.append(b * H * W + j * W + i)
                outs.append(out)
                ends.append(P1)
    dt = gbuffer.view_z.dtype
    if not outs:
        outs, ends = [MarchOutput.empty(0, dt, "cpu", NO_RAY)], []
    o = MarchOutput(**{f: torch.cat([getattr(x, f) for x in outs]).to(dt if f in "PQk" else getattr(outs[0], f).dtype)
                       for f in ("term", "steps", "P", "Q", "k")})
    P1 = torch.tensor(ends, dtype=dt).reshape(-1, 2)
    return assemble(gbuffer, params, torch.tensor(rows, dtype=torch.long), P1, o, None)
