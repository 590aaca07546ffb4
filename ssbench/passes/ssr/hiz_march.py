"""The Hi-Z SSR traversal (:mod:`.hiz`): the rays in ``(px, py, rz)`` and the stackless mip walk, vectorised.

Per ray, FidelityFX SSSR's ``FFX_SSSR_HierarchicalRaymarch`` (AMD, 2020; ``ffx_sssr.h``) in pixel units over the
reversed-depth max pyramid of :mod:`.hiz_pyramid`:

1. **Set-up** (:func:`hiz_rays`): origin ``o`` = the pixel centre and its ``rz``; the mirror ray, clipped at the
   near plane *before* it is projected (FidelityFX projects ``o + d`` unclipped, which lands behind the eye for
   rays toward the camera, ``w ≤ 0``, and flips the screen direction); ``v = (P1 − P0, rz1 − rz0)`` so ``t ∈ [0,
   1]`` spans the clipped segment. ``InitialAdvanceRay``: ``t`` moves to just past the origin texel's border.
2. **One iteration** (:func:`hiz_march`) reads the cell under ``o + t·v`` at the ray's level ``m`` and computes
   the ``t`` where the ray leaves the cell sideways (``t_x``, ``t_y``: the cell border crossed by ``EPSILON``
   pixels) and where it reaches the cell's closest depth (``t_z``, only for rays moving away, ``v.z < 0``).
   ``AdvanceRay``: if the ray is in front of the cell (``rz > cell``) it moves to ``min(t_x, t_y, t_z)``; if it
   left sideways the level goes up (the tile was skipped), else down. A ray not in front of a level-0 texel is a
   hit candidate.
3. **Candidates** are validated at the texel: the ray's view z must lie within the thickness behind the surface
   (``depth_buffer_thickness`` view units, or ``× |z|`` in HDRP's ``"relative"`` mode, or down to ``back_z``
   with layered depth), and with ``reject_backfaces`` the texel must face the ray (FidelityFX's
   ``dot(n_hit, d) > 0`` rejection). A failed candidate ends the ray (``BEHIND_SURFACE``, FidelityFX) or, with
   ``trace_behind``, the ray crosses that texel at level 0 and goes on (HDRP's "tracing behind objects has linear
   rather than logarithmic complexity").

Exits: ``OFF_SCREEN``; ``MAX_DISTANCE`` when the segment ends inside a cell it is in front of (``BEHIND_CAMERA`` if
the near plane clipped it); ``OUT_OF_STEPS`` when the budget runs out — FidelityFX's ``valid_hit = i ≤
max_traversal_intersections`` holds on every exit, so it reports those rays as hits.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import torch

from ...gbuffer import GBuffer
from .common import (BEHIND_CAMERA, BEHIND_SURFACE, HIT, MAX_DISTANCE, OFF_SCREEN, OUT_OF_STEPS, clip_ray_length,
                     reflection_rays)
from .dda_state import MarchOutput, select_rows
from .hiz_pyramid import DepthPyramid

__all__ = ["HiZRays", "HiZTexels", "EPSILON", "hiz_rays", "hiz_march", "cell_exit"]

#: how far past a cell border a crossing lands, in pixels (FidelityFX: ``0.005 · 2^most_detailed_mip`` texels)
EPSILON = 0.005


@dataclass
class HiZRays:
    """Per-ray Hi-Z state, each field :math:`(N,)`.

    Attributes:
        i, b: the ray's row in the outputs and its image.
        ox, oy, oz: the origin in ``(px, py, rz)``; ``vx, vy, vz``: the segment per unit of ``t``.
        dx, dy, dz: the unit view-space direction (the back-face test).
        t: the ray's parameter; ``mip``: its current level (long).
        clipped: the near plane shortened the segment.
    """

    i: torch.Tensor
    b: torch.Tensor
    ox: torch.Tensor
    oy: torch.Tensor
    oz: torch.Tensor
    vx: torch.Tensor
    vy: torch.Tensor
    vz: torch.Tensor
    dx: torch.Tensor
    dy: torch.Tensor
    dz: torch.Tensor
    t: torch.Tensor
    mip: torch.Tensor
    clipped: torch.Tensor

    @property
    def count(self) -> int:
        return self.i.numel()


@dataclass(frozen=True)
class HiZTexels:
    """What a candidate is validated against, flat over ``B·H·W``: ``view_z``, ``normal`` :math:`(BHW, 3)`,
    ``back_z`` (``None`` without layered depth)."""

    view_z: torch.Tensor
    normal: torch.Tensor
    back_z: Optional[torch.Tensor] = None


def cell_exit(o: torch.Tensor, v: torch.Tensor, cell: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """``t`` where ``o + t·v`` crosses the far border of ``cell`` (cells ``scale`` pixels wide) by
    :data:`EPSILON`; ``inf`` where ``v == 0``.

    Example:
        >>> cell_exit(torch.tensor([2.5, 2.5]), torch.tensor([2.0, -1.0]), torch.tensor([1, 1]), torch.tensor([2.0, 2.0]))
        tensor([0.7525, 0.5050])
    """
    border = (cell + (v >= 0).to(cell.dtype)).to(o.dtype) * scale + EPSILON * torch.sign(v)
    safe = torch.where(v == 0, torch.ones_like(v), v)
    return torch.where(v == 0, torch.full_like(o, torch.inf), (border - o) / safe)


def hiz_rays(gbuffer: GBuffer, max_ray_distance: float, sel: torch.Tensor):
    """Set-up of the rays of the pixels ``sel`` (flat ``b·H·W + j·W + i``): ``(HiZRays, sel, P0, P1)`` with the
    initial advance done; ``P0``, ``P1`` :math:`(N, 2)` the segment's ends in pixels."""
    cam, vz = gbuffer.camera, gbuffer.view_z
    B, _, H, W = vz.shape
    dt, dev = vz.dtype, vz.device
    b, px = sel // (H * W), sel % (H * W)
    col = lambda x: x.reshape(x.shape[0], x.shape[1], -1)[b, :, px].T[None, :, :, None]   # noqa: E731  (1, C, N, 1)
    uv = cam.uv_grid(dt, dev).reshape(2, -1)[:, px][None, :, :, None]
    pos = cam.uv_to_view(uv, col(vz))                                             # (1, 3, N, 1)
    R = reflection_rays(pos, col(gbuffer.normal).to(dt))
    o, d = pos[0, :, :, 0].T, R[0, :, :, 0].T                                     # (N, 3)
    length = clip_ray_length(o[:, 2], d[:, 2], max_ray_distance, cam.near)
    end = o + d * length[:, None]
    P0 = torch.stack([(px % W).to(dt) + 0.5, (px // W).to(dt) + 0.5], 1)          # the origin pixel's centre
    P1 = cam.view_to_pixel(end, dim=1)
    rz0, rz1 = cam.near / -o[:, 2], cam.near / -end[:, 2]
    v = P1 - P0
    zero = torch.zeros_like(rz0)
    t0 = torch.minimum(cell_exit(P0[:, 0], v[:, 0], P0[:, 0].floor(), zero + 1.0),
                       cell_exit(P0[:, 1], v[:, 1], P0[:, 1].floor(), zero + 1.0))   # InitialAdvanceRay
    rays = HiZRays(i=torch.arange(sel.numel(), device=dev), b=b, ox=P0[:, 0], oy=P0[:, 1], oz=rz0,
                   vx=v[:, 0], vy=v[:, 1], vz=rz1 - rz0, dx=d[:, 0], dy=d[:, 1], dz=d[:, 2],
                   t=torch.minimum(t0, zero + 1.0), mip=torch.zeros_like(b),
                   clipped=o[:, 2] + d[:, 2] * max_ray_distance > -cam.near)
    return rays, sel, P0, P1


def _validate(r: HiZRays, texel: torch.Tensor, z: torch.Tensor, near: float, tex: HiZTexels, params) -> torch.Tensor:
    """Which candidates hit: the ray within the thickness behind ``texel`` (flat index), facing it if asked."""
    zs = tex.view_z[texel]
    thick = params.depth_buffer_thickness * (zs.abs() if params.thickness_mode == "relative" else 1.0)
    bottom = (tex.back_z[texel] if tex.back_z is not None else zs) - thick
    ok = -near / z.clamp_min(torch.finfo(z.dtype).tiny) >= bottom
    if params.reject_backfaces:
        n = tex.normal[texel]
        ok = ok & (r.dx * n[:, 0] + r.dy * n[:, 1] + r.dz * n[:, 2] <= 0)
    return ok


def hiz_march(r: HiZRays, pyr: DepthPyramid, tex: HiZTexels, params, gbuffer: GBuffer,
              visits: Optional[torch.Tensor] = None, level_reads: Optional[torch.Tensor] = None) -> MarchOutput:
    """March ``r`` (owned: advanced in place) to termination; one pyramid read per iteration, at most
    ``params.max_traversal_intersections``. ``visits`` :math:`(BHW,)` counts level-0 reads per texel and
    ``level_reads`` :math:`(L,)` reads per level, when given."""
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    dt, dev = r.ox.dtype, r.ox.device
    out = MarchOutput.empty(r.count, dt, dev, OUT_OF_STEPS)
    scales = torch.pow(2.0, torch.arange(pyr.count, device=dev, dtype=dt))
    top = min(params.max_mip, pyr.count - 1)

    def finish(done: torch.Tensor, code) -> HiZRays:
        out.term[r.i[done]] = code if isinstance(code, int) else code[done]
        return select_rows(r, (~done).nonzero().squeeze(1))

    r = finish(r.t >= 1.0, torch.where(r.clipped, BEHIND_CAMERA, MAX_DISTANCE).to(torch.int8))
    for _ in range(params.max_traversal_intersections):
        if r.count == 0:
            break
        x, y, z = r.ox + r.t * r.vx, r.oy + r.t * r.vy, r.oz + r.t * r.vz
        r = finish((x < 0) | (x >= W) | (y < 0) | (y >= H), OFF_SCREEN)
        if r.count == 0:
            break
        x, y, z = r.ox + r.t * r.vx, r.oy + r.t * r.vy, r.oz + r.t * r.vz
        scale = scales[r.mip]
        cx, cy = torch.div(x, scale).floor().long(), torch.div(y, scale).floor().long()
        surface = pyr.cell(r.b, r.mip, cx, cy)
        out.steps.index_add_(0, r.i, torch.ones_like(r.i, dtype=torch.int32))
        if level_reads is not None:
            level_reads += torch.bincount(r.mip, minlength=level_reads.numel())
        if visits is not None:
            at0 = r.mip == 0
            visits.index_add_(0, (r.b * H * W + cy * W + cx)[at0], torch.ones_like(cx[at0], dtype=visits.dtype))
        tx, ty = cell_exit(r.ox, r.vx, cx, scale), cell_exit(r.oy, r.vy, cy, scale)
        neg = r.vz < 0
        tz = torch.where(neg, (surface - r.oz) / torch.where(neg, r.vz, -1.0), torch.inf)
        side = torch.minimum(tx, ty)
        above = z > surface
        skipped = above & (side < tz)
        t_new = torch.where(above, torch.minimum(side, tz), r.t)
        mip = torch.where(skipped, (r.mip + 1).clamp_max(top), r.mip - 1)
        cand = (mip < 0).nonzero().squeeze(1)
        hit = torch.zeros_like(above)
        if cand.numel():
            texel = r.b[cand] * H * W + cy[cand] * W + cx[cand]
            ok = _validate(select_rows(r, cand), texel, z[cand], cam.near, tex, params)
            hit[cand] = ok
            h = cand[ok]
            out.P[r.i[h]] = torch.stack([x[h], y[h]], 1)
            zv = -cam.near / z[h]
            uv = torch.stack([x[h] / W, 1.0 - y[h] / H], 0)
            out.Q[r.i[h]] = cam.uv_to_view(uv, zv, dim=0).T.to(dt)
            if params.trace_behind:                                               # cross the texel, stay at level 0
                t_new[cand] = torch.where(ok, t_new[cand], side[cand])
                mip[cand] = 0
        r.t, r.mip = t_new, mip
        ended = ~hit & (r.t >= 1.0) & (mip >= 0)
        rejected = ~hit & (mip < 0)
        code = torch.where(hit, HIT, torch.where(rejected, BEHIND_SURFACE,
                                                 torch.where(r.clipped, BEHIND_CAMERA, MAX_DISTANCE))).to(torch.int8)
        r = finish(hit | ended | rejected, code)
    return out
