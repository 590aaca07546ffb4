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
   ``dot(n_hit, d) > 0`` rejection), or — with the second depth layer — within the thickness behind the surface
   the first one hides. A failed candidate ends the ray (``BEHIND_SURFACE``, FidelityFX) or, with
   ``trace_behind``, the ray crosses that texel at level 0 and goes on (HDRP's "tracing behind objects has linear
   rather than logarithmic complexity"); with the second layer, a ray still in front of it goes on too.

Exits: ``OFF_SCREEN``; ``MAX_DISTANCE`` when the segment ends inside a cell it is in front of (``BEHIND_CAMERA`` if
the near plane clipped it); ``OUT_OF_STEPS`` when the budget runs out — FidelityFX's ``valid_hit = i ≤
max_traversal_intersections`` holds on every exit, so it reports those rays as hits.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple, Optional

import torch

from ...gbuffer import GBuffer
from ..compiled import kernel
from .common import (BEHIND_CAMERA, BEHIND_SURFACE, HIT, MAX_DISTANCE, OFF_SCREEN, OUT_OF_STEPS, compact_now,
                     ray_segments)
from .dda_state import MarchOutput
from .hiz_pyramid import DepthPyramid

__all__ = ["HiZRays", "HiZTexels", "PyramidLevels", "StepGeometry", "EPSILON", "BIG", "RAY_CHUNK", "hiz_rays",
           "hiz_step", "hiz_march", "cell_exit", "inverse"]

#: how far past a cell border a crossing lands, in pixels (FidelityFX: ``0.005 · 2^most_detailed_mip`` texels)
EPSILON = 0.005


#: rays marched at once: ~130 bytes of state per ray, so a chunk holds ~35 MB; larger than the DDA's chunk because
#: every chunk pays the long tail of the few rays that need the most iterations
RAY_CHUNK = 1 << 18
#: ``1/v`` of an axis the ray does not move along: ``t`` of its borders is then huge, never the minimum
#: (FidelityFX uses ``FLT_MAX`` in uv units; in pixels that would overflow)
BIG = 1e30
#: the per-ray constants, rows of :attr:`HiZRays.c`
COLUMNS = ("ox", "oy", "oz", "vx", "vy", "vz", "invx", "invy", "invz", "offx", "offy", "epsx", "epsy")
OX, OY, OZ, VX, VY, VZ, INVX, INVY, INVZ, OFFX, OFFY, EPSX, EPSY = range(len(COLUMNS))


@dataclass
class HiZRays:
    """The live rays of a Hi-Z march, :math:`(N,)` per field.

    Attributes:
        i, b: the ray's row in the outputs and its image.
        t: the ray's parameter; ``mip``: its current level (long).
        c: :math:`(13, N)` per-ray constants, rows :data:`COLUMNS` (each row contiguous): the origin ``o`` in ``(px, py, rz)``, the
            segment ``v`` per unit of ``t``, ``inv = 1/v`` (:data:`BIG` for ``v.xy = 0``; ``invz`` only for rays
            moving away, ``v.z < 0``, else 0), ``off = (v ≥ 0)`` (FidelityFX's ``floor_offset``) and the signed
            crossing ``eps = EPSILON·sign(v)`` per screen axis.
    """

    i: torch.Tensor
    b: torch.Tensor
    t: torch.Tensor
    mip: torch.Tensor
    c: torch.Tensor
    ray_dir: torch.Tensor
    clipped: torch.Tensor

    @property
    def count(self) -> int:
        return self.i.numel()

    def select(self, index: torch.Tensor) -> "HiZRays":
        """The live rays at ``index``; ``ray_dir`` :math:`(N_0, 3)` and ``clipped`` :math:`(N_0,)` stay whole
        (every ray of the chunk, read by ``i``: the unit view-space direction, the near plane shortened it)."""
        take = lambda x, dim=0: x.index_select(dim, index)       # noqa: E731  (gathers: 5× faster than x[index])
        return HiZRays(i=take(self.i), b=take(self.b), t=take(self.t), mip=take(self.mip), c=take(self.c, 1),
                       ray_dir=self.ray_dir, clipped=self.clipped)


@dataclass(frozen=True)
class HiZTexels:
    """What a candidate is validated against, flat over ``B·H·W``: ``view_z``, ``normal`` :math:`(BHW, 3)`,
    ``back_z`` (``None`` without layered depth), ``second_z`` (``None`` without the second layer)."""

    view_z: torch.Tensor
    normal: torch.Tensor
    back_z: Optional[torch.Tensor] = None
    second_z: Optional[torch.Tensor] = None


def inverse(v: torch.Tensor) -> torch.Tensor:
    """``1/v``, :data:`BIG` where ``v == 0``."""
    return torch.where(v == 0, BIG, 1.0 / torch.where(v == 0, torch.ones_like(v), v))


def cell_exit(o: torch.Tensor, inv: torch.Tensor, off: torch.Tensor, eps: torch.Tensor, cell: torch.Tensor,
              scale: torch.Tensor) -> torch.Tensor:
    """``AdvanceRay``'s border time: ``t`` where ``o + t·v`` crosses the far border of ``cell`` (cells ``scale``
    pixels wide) by :data:`EPSILON`, from the ray's constants along that axis (:data:`COLUMNS`): ``inv = 1/v``
    (:func:`inverse`: huge, never the nearest border, where ``v == 0``), ``off = (v ≥ 0)``, ``eps =
    EPSILON·sign(v)``.

    Example:
        >>> v = torch.tensor([2.0, -1.0])
        >>> cell_exit(torch.tensor([2.5, 2.5]), inverse(v), (v >= 0).float(), EPSILON * torch.sign(v),
        ...           torch.tensor([1, 1]), torch.tensor([2.0, 2.0]))
        tensor([0.7525, 0.5050])
    """
    return ((cell.to(o.dtype) + off) * scale + eps - o) * inv


def hiz_rays(gbuffer: GBuffer, max_ray_distance: float, sel: torch.Tensor, directions: Optional[torch.Tensor] = None):
    """Set-up of the rays of the pixels ``sel`` (flat ``b·H·W + j·W + i``): ``(HiZRays, sel, P0, P1)`` with the
    initial advance done; ``P0``, ``P1`` :math:`(N, 2)` the segment's ends in pixels. The rays follow
    ``directions`` :math:`(B, 3, H, W)` (unit, view space) when given, else the mirror reflections."""
    cam, vz = gbuffer.camera, gbuffer.view_z
    W = vz.shape[-1]
    dt, dev = vz.dtype, vz.device
    b, px, o, d, end = ray_segments(gbuffer, sel, max_ray_distance, directions)
    P0 = torch.stack([(px % W).to(dt) + 0.5, (px // W).to(dt) + 0.5], 1)          # the origin pixel's centre
    P1 = cam.view_to_pixel(end, dim=1)
    rz0, rz1 = cam.near / -o[:, 2], cam.near / -end[:, 2]
    v = torch.cat([P1 - P0, (rz1 - rz0)[:, None]], 1)
    away = v[:, 2] < 0
    c = torch.stack([P0[:, 0], P0[:, 1], rz0, v[:, 0], v[:, 1], v[:, 2], inverse(v[:, 0]), inverse(v[:, 1]),
                     torch.where(away, 1.0 / torch.where(away, v[:, 2], -1.0), 0.0),
                     (v[:, 0] >= 0).to(dt), (v[:, 1] >= 0).to(dt), EPSILON * torch.sign(v[:, 0]),
                     EPSILON * torch.sign(v[:, 1])], 0)
    one = torch.ones_like(rz0)
    t0 = torch.minimum(cell_exit(c[OX], c[INVX], c[OFFX], c[EPSX], P0[:, 0].floor(), one),
                       cell_exit(c[OY], c[INVY], c[OFFY], c[EPSY], P0[:, 1].floor(), one))   # InitialAdvanceRay
    rays = HiZRays(i=torch.arange(sel.numel(), device=dev), b=b, t=torch.minimum(t0, one), mip=torch.zeros_like(b),
                   c=c, ray_dir=d, clipped=o[:, 2] + d[:, 2] * max_ray_distance > -cam.near)
    return rays, sel, P0, P1


def _thickness(params, z: torch.Tensor) -> torch.Tensor:
    return params.depth_buffer_thickness * (z.abs() if params.thickness_mode == "relative" else 1.0)


def _validate(ray_dir: torch.Tensor, texel: torch.Tensor, z: torch.Tensor, near: float, tex: HiZTexels,
              params) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Which candidates hit: the ray within the thickness behind ``texel`` (flat index), facing it if asked, or
    within the second layer's; which are in front of the second layer (they go on), and that layer's ``rz``."""
    at = lambda v: v.index_select(0, texel)                   # noqa: E731
    zs = at(tex.view_z)
    bottom = (at(tex.back_z) if tex.back_z is not None else zs) - _thickness(params, zs)
    zr = -near / z.clamp_min(torch.finfo(z.dtype).tiny)
    ok = zr >= bottom
    if params.reject_backfaces:
        ok = ok & ((ray_dir * at(tex.normal)).sum(1) <= 0)
    if tex.second_z is None:
        return ok, torch.zeros_like(ok), torch.zeros_like(z)
    z2 = at(tex.second_z)
    in2 = (zr <= z2) & (zr >= z2 - _thickness(params, z2))
    front2 = ~ok & (zr > z2)
    return ok | in2, front2, torch.where(front2, near / -z2.clamp_max(-torch.finfo(z.dtype).tiny), 0.0)


class PyramidLevels(NamedTuple):
    """The pyramid as :func:`hiz_step` reads it: ``flat`` :math:`(B·T,)` every image's levels; ``scales`` and
    ``inv_scales`` :math:`(L,)` a level's cell size in pixels and its inverse; ``offsets``, ``widths`` :math:`(L,)`
    long (:class:`~.hiz_pyramid.DepthPyramid`); ``total`` = ``T``, the cells of one image."""

    flat: torch.Tensor
    scales: torch.Tensor
    inv_scales: torch.Tensor
    offsets: torch.Tensor
    widths: torch.Tensor
    total: int


class StepGeometry(NamedTuple):
    """What one iteration computes per live ray, :math:`(N,)` each: the position ``x, y, z`` (``z`` = ``rz``), whether
    it left the screen (``off``), its cell ``cx, cy`` at its level, ``side`` (``min(t_x, t_y)``), and the ``t`` and
    level ``AdvanceRay`` gives it (level −1: a hit candidate)."""

    x: torch.Tensor
    y: torch.Tensor
    z: torch.Tensor
    off: torch.Tensor
    cx: torch.Tensor
    cy: torch.Tensor
    side: torch.Tensor
    t_new: torch.Tensor
    mip: torch.Tensor


@kernel(dynamic=True)
def hiz_step(c: torch.Tensor, t: torch.Tensor, mip: torch.Tensor, b: torch.Tensor, levels: PyramidLevels, W: int,
             H: int, top: int) -> StepGeometry:
    """Step 2 of the module docstring for the live rays (constants ``c`` :math:`(13, N)`, :data:`COLUMNS`; ``t``,
    ``mip``, image ``b`` :math:`(N,)`): one read of the pyramid and ``AdvanceRay`` (levels up to ``top``); a
    size-dynamic compiled kernel (:mod:`ssbench.passes.compiled`)."""
    x, y, z = c[OX] + t * c[VX], c[OY] + t * c[VY], c[OZ] + t * c[VZ]
    off = ~((x >= 0) & (x < W) & (y >= 0) & (y < H))                        # NaN (degenerate input) too
    level = mip.clamp_min(0)                        # a stopped ray riding along masked may be at level −1
    inv_s, scale = levels.inv_scales.index_select(0, level), levels.scales.index_select(0, level)
    cx, cy = (x * inv_s).long(), (y * inv_s).long()                           # x, y ≥ 0 on screen: trunc = floor
    index = (b * levels.total + levels.offsets.index_select(0, level) + cy * levels.widths.index_select(0, level)
             + cx).clamp(0, levels.flat.numel() - 1)
    surface = torch.take(levels.flat, index)                                  # garbage only for `off` rays
    tx = cell_exit(c[OX], c[INVX], c[OFFX], c[EPSX], cx, scale)              # AdvanceRay: the borders
    ty = cell_exit(c[OY], c[INVY], c[OFFY], c[EPSY], cy, scale)
    tz = torch.where((c[INVZ] != 0) & (surface > 0), (surface - c[OZ]) * c[INVZ], torch.inf)   # its closest depth
    side = torch.minimum(tx, ty)
    above = (z > surface) | (surface <= 0)                                    # a cell of background: skip it
    skipped = above & (side < tz)
    t_new = torch.where(above, torch.minimum(side, tz), t)
    return StepGeometry(x, y, z, off, cx, cy, side, t_new, torch.where(skipped, (mip + 1).clamp_max(top), mip - 1))


def hiz_march(r: HiZRays, pyr: DepthPyramid, tex: HiZTexels, params, gbuffer: GBuffer,
              visits: Optional[torch.Tensor] = None, level_reads: Optional[torch.Tensor] = None) -> MarchOutput:
    """March ``r`` to termination; one pyramid read per iteration (:func:`hiz_step`), at most
    ``params.max_traversal_intersections``. Stopped rays ride along masked until a quarter of the working set has
    stopped, then it is compacted. ``visits`` :math:`(BHW,)` counts level-0 reads per texel and ``level_reads``
    :math:`(L,)` reads per level, when given."""
    cam = gbuffer.camera
    B, _, H, W = gbuffer.view_z.shape
    dt, dev = r.c.dtype, r.c.device
    out = MarchOutput.empty(r.count, dt, dev, OUT_OF_STEPS)
    scales = torch.pow(2.0, torch.arange(pyr.count, device=dev, dtype=dt))
    inv_scales = 1.0 / scales
    top = min(params.max_mip, pyr.count - 1)
    total = pyr.flat.shape[1]
    flat = pyr.flat.reshape(-1)
    ended = torch.where(r.clipped, BEHIND_CAMERA, MAX_DISTANCE).to(torch.int8)      # the segment's end, per ray

    def finish(done: torch.Tensor, code: torch.Tensor) -> HiZRays:
        out.term[r.i[done]] = code[done]
        return r.select((~done).nonzero().squeeze(1))

    r = finish(r.t >= 1.0, ended[r.i])
    levels = PyramidLevels(flat, scales, inv_scales, pyr.offsets, pyr.widths, total)
    alive = torch.ones(r.count, dtype=torch.bool, device=dev)     # stopped rays ride along until a quarter stopped
    for _ in range(params.max_traversal_intersections):
        if r.count == 0:
            break
        c, t = r.c, r.t
        x, y, z, off, cx, cy, side, t_new, mip = hiz_step(c, t, r.mip, r.b, levels, W, H, top)
        on = alive & ~off
        out.steps.index_add_(0, r.i, on.int())
        if level_reads is not None:
            level_reads += torch.bincount(r.mip[on], minlength=level_reads.numel())
        if visits is not None:
            at0 = on & (r.mip == 0)
            visits.index_add_(0, (r.b * H * W + cy * W + cx)[at0], torch.ones_like(cx[at0], dtype=visits.dtype))
        hit = torch.zeros_like(on)
        cand = (on & (mip < 0)).nonzero().squeeze(1)
        if cand.numel():
            at = lambda v, dim=0: v.index_select(dim, cand)      # noqa: E731  (gathers: faster than v[cand])
            i_c, x_c, y_c, z_c, side_c, t_new_c = at(r.i), at(x), at(y), at(z), at(side), at(t_new)
            ok, front2, rz2 = _validate(r.ray_dir.index_select(0, i_c), at(r.b) * H * W + at(cy) * W + at(cx),
                                        z_c, cam.near, tex, params)
            cc = at(c, 1)                                     # the second layer, reached inside this texel
            t2 = torch.where(front2 & (cc[INVZ] != 0), (rz2 - cc[OZ]) * cc[INVZ], torch.inf)
            reach = front2 & (rz2 > 0) & (t2 <= side_c)                           # (no layer behind: rz2 = 0)
            t_hit = torch.where(reach, t2, at(t))
            px_, py_, pz_ = cc[OX] + t_hit * cc[VX], cc[OY] + t_hit * cc[VY], cc[OZ] + t_hit * cc[VZ]
            px_, py_, pz_ = (torch.where(reach, a, b) for a, b in ((px_, x_c), (py_, y_c), (pz_, z_c)))
            ok = ok | reach
            front2 = front2 & ~reach
            hit.index_copy_(0, cand, ok)
            h = ok.nonzero().squeeze(1)
            px_, py_, pz_, i_h = (v.index_select(0, h) for v in (px_, py_, pz_, i_c))
            out.P.index_copy_(0, i_h, torch.stack([px_, py_], 1))
            uv = torch.stack([px_ / W, 1.0 - py_ / H], 0)
            out.Q.index_copy_(0, i_h, cam.uv_to_view(uv, -cam.near / pz_, dim=0).T.to(dt))
            go = ~ok if params.trace_behind else front2                           # cross the texel at level 0
            t_new.index_copy_(0, cand, torch.where(go, side_c, t_new_c))
            mip.index_copy_(0, cand, torch.where(go, 0, at(mip)))
        r.t, r.mip = t_new, mip
        done = alive & (off | hit | (mip < 0) | (t_new >= 1.0))
        code = torch.where(off, OFF_SCREEN, torch.where(hit, HIT, torch.where(
            mip < 0, BEHIND_SURFACE, ended[r.i].int()))).to(torch.int8)
        stopped = done.nonzero().squeeze(1)
        out.term.index_copy_(0, r.i.index_select(0, stopped), code.index_select(0, stopped))
        alive = alive & ~done
        if compact_now(int(alive.sum()), r.count):
            r = r.select(alive.nonzero().squeeze(1))
            alive = torch.ones(r.count, dtype=torch.bool, device=dev)
    return out
