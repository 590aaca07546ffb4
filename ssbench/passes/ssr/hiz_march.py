"""The Hi-Z SSR traversal (:mod:`.hiz`): the rays in ``(px, py, rz)`` and the stackless mip walk, vectorised.

Per ray, FidelityFX SSSR's ``FFX_SSSR_HierarchicalRaymarch`` (AMD, 2020; ``ffx_sssr.h``) in pixel units over the
reversed-depth max pyramid of :mod:`.hiz_pyramid`:

1. **Set-up** (:func:`hiz_rays`): origin ``o`` = the pixel centre and its ``rz``; the mirror ray, clipped at the
   near plane *before* it is projected (FidelityFX projects ``o + d`` unclipped, which lands behind the eye for
   rays toward the camera, ``w ≤ 0``, and flips the screen direction); ``v = (P1 − P0, rz1 − rz0)`` so ``t ∈ [0,
   1]`` spans the clipped segment. ``InitialAdvanceRay``: ``t`` moves to just past the origin texel's border.
2. **One iteration** (:func:`~.hiz_step.hiz_step`) reads the cell under ``o + t·v`` at the ray's level ``m`` and computes
   the ``t`` where the ray leaves the cell sideways (``t_x``, ``t_y``: the cell border crossed by ``EPSILON``
   pixels) and where it reaches the cell's closest depth (``t_z``, only for rays moving away, ``v.z < 0``).
   ``AdvanceRay``: if the ray is in front of the cell (``rz > cell``) it moves to ``min(t_x, t_y, t_z)``; if it
   left sideways the level goes up (the tile was skipped), else down. A ray not in front of a level-0 texel is a
   hit candidate.
3. **Candidates** are validated (:func:`~.hiz_step.validate`) at the texel: the ray's view z must lie within the thickness behind the surface
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
from typing import Optional

import torch

from ...camera import Camera
from ...gbuffer import GBuffer
from ...indices import flat_nonzero
from ...layout import contiguous, stack_columns
from ..compiled import kernel, step_blocks
from .common import HIT, OUT_OF_STEPS, compact_now, crosses_near_plane, end_code, ray_segments
from .dda_state import MarchOutput
from .hiz_pyramid import DepthPyramid, padded_levels
from .hiz_step import (BIG, COLUMNS, EPSILON, OX, OY, OZ, VX, VY, VZ, HiZRules, HiZTexels, MarchState, PyramidLayers,
                       cell_exit, hiz_iterations, inverse)

__all__ = ["HiZRays", "HiZTexels", "EPSILON", "BIG", "COLUMNS", "RAY_CHUNK", "hiz_rays", "index_dtype", "march_layers",
           "hiz_march"]

#: rays marched at once: ~130 bytes of state per ray, so a chunk holds ~35 MB; larger than the DDA's chunk because
#: every chunk pays the long tail of the few rays that need the most iterations
RAY_CHUNK = 1 << 18


@dataclass
class HiZRays:
    """The rays of a Hi-Z march's working set, :math:`(N,)` per field.

    Attributes:
        i, b: the ray's row in the outputs and its image.
        c: :math:`(13, N)` per-ray constants, rows :data:`~.hiz_step.COLUMNS` (each row contiguous): the origin
            ``o`` in ``(px, py, rz)``, the segment ``v`` per unit of ``t``, ``inv = 1/v`` (:data:`BIG` for ``v.xy =
            0``; ``invz`` only for rays moving away, ``v.z < 0``, else 0), ``off = (v ≥ 0)`` (FidelityFX's
            ``floor_offset``) and the signed crossing ``eps = EPSILON·sign(v)`` per screen axis.
        ray_dir: :math:`(3, N)` the unit view-space direction; ``ended``: int32, the code of reaching the segment's
            end (``BEHIND_CAMERA`` where the near plane shortened it, else ``MAX_DISTANCE``).
        state: the changing :class:`~.hiz_step.MarchState` (``t``, level, termination, reads, hit ``t``).
    """

    i: torch.Tensor
    b: torch.Tensor
    c: torch.Tensor
    ray_dir: torch.Tensor
    ended: torch.Tensor
    state: MarchState

    @property
    def count(self) -> int:
        return self.i.numel()

    def select(self, index: torch.Tensor) -> "HiZRays":
        """The rays at ``index``."""
        take = lambda x, dim=0: x.index_select(dim, index)       # noqa: E731  (gathers: 5× faster than x[index])
        return HiZRays(i=take(self.i), b=take(self.b), c=take(self.c, 1), ray_dir=take(self.ray_dir, 1),
                       ended=take(self.ended), state=MarchState(*(take(v) for v in self.state)))


@kernel(dynamic=True)
def ray_constants(cam: Camera, px: torch.Tensor, o: torch.Tensor, d: torch.Tensor, end: torch.Tensor,
                  max_ray_distance: float) -> tuple:
    """The per-ray constants of :func:`hiz_rays` from the rays' pixels ``px`` :math:`(N,)`, origins, directions and
    clipped ends :math:`(N, 3)`: ``(c, P0, P1, t, clipped)`` — :class:`HiZRays`' ``c`` :math:`(13, N)`, the segment's
    ends in pixels :math:`(N, 2)`, the first ``t`` (``InitialAdvanceRay``) and whether the near plane shortened the
    ray. A compilable, size-dynamic kernel (:mod:`ssbench.passes.compiled`; exact operations: the same bits)."""
    P0 = cam.pixel_centers_at(px, o.dtype)                                        # (2, N) the origin pixel's centre
    P1 = cam.view_to_pixel(end, dim=1)                                            # (N, 2)
    oz = cam.near / -o[:, 2]                                                      # rz0
    v = torch.stack([P1[:, 0] - P0[0], P1[:, 1] - P0[1], cam.near / -end[:, 2] - oz])   # v = (P1 − P0, rz1 − rz0)
    inv = inverse(v[:2])
    away = v[2] < 0
    invz = torch.where(away, 1.0 / torch.where(away, v[2], -1.0), 0.0)
    off = (v[:2] >= 0).to(o.dtype)
    eps = torch.sign(v[:2]) * EPSILON
    c = torch.cat([P0, oz[None], v, inv, invz[None], off, eps])                   # rows COLUMNS
    one = torch.ones_like(oz)
    t0 = torch.minimum(cell_exit(P0[0], inv[0], off[0], eps[0], P0[0].floor(), one),
                       cell_exit(P0[1], inv[1], off[1], eps[1], P0[1].floor(), one))   # InitialAdvanceRay
    clipped = crosses_near_plane(o[:, 2], d[:, 2], max_ray_distance, cam.near)
    return c, P0.T, P1, torch.minimum(t0, one), clipped


def hiz_rays(gbuffer: GBuffer, max_ray_distance: float, sel: torch.Tensor, directions: Optional[torch.Tensor] = None,
             index: torch.dtype = torch.int64):
    """Set-up of the rays of the pixels ``sel`` (flat ``b·H·W + j·W + i``): ``(HiZRays, sel, P0, P1)`` with the
    initial advance done; ``P0``, ``P1`` :math:`(N, 2)` the segment's ends in pixels. The rays follow
    ``directions`` :math:`(B, 3, H, W)` (unit, view space) when given, else the mirror reflections; their image
    ``b`` and level have the integer type ``index`` (:func:`index_dtype`), which the march's index arithmetic
    follows."""
    dev = gbuffer.view_z.device
    b, px, o, d, end = ray_segments(gbuffer, sel, max_ray_distance, directions)
    c, P0, P1, t, clipped = ray_constants(gbuffer.camera, px, o, d, end, float(max_ray_distance))
    n = sel.numel()
    b = b.to(index)
    state = MarchState(t=t, mip=torch.zeros_like(b), alive32=torch.ones(n, dtype=torch.int32, device=dev),
                       term=torch.full((n,), OUT_OF_STEPS, dtype=torch.int32, device=dev),
                       steps=torch.zeros(n, dtype=torch.int32, device=dev), hit_t=torch.zeros_like(t))
    rays = HiZRays(i=torch.arange(n, device=dev), b=b, c=c, ray_dir=contiguous(d.T),
                   ended=end_code(clipped), state=state)
    return rays, sel, P0, P1


def write_back(out: MarchOutput, r: HiZRays, rows: torch.Tensor, hit_t: torch.Tensor) -> None:
    """Copy the termination, reads and hit ``t`` of the working set's ``rows`` into ``out`` and ``hit_t`` (rows by
    ``r.i``); the hit points follow once, after the march (:func:`hit_points`)."""
    out.write_ends(rows, r.i, r.state.term, r.state.steps)
    hit_t.index_copy_(0, r.i.index_select(0, rows), r.state.hit_t.index_select(0, rows))


def hit_points(out: MarchOutput, c: torch.Tensor, hit_t: torch.Tensor, gbuffer: GBuffer) -> None:
    """Write the hit points of the rays that hit into ``out``: ``P`` in pixels and ``Q`` in view space, from the
    set-up's constants ``c`` :math:`(13, N)` (rows ``o`` and ``v``; column ``k`` is output row ``k``) at their hit
    ``t``. Once per march, not per compaction: each ray's arithmetic is the same, so are its bits."""
    cam = gbuffer.camera
    H, W = gbuffer.view_z.shape[-2:]
    h = flat_nonzero(out.term == HIT)
    if h.numel():
        t, c = hit_t.index_select(0, h), c[:VZ + 1].index_select(1, h)          # rows o and v
        px, py, pz = c[OX] + t * c[VX], c[OY] + t * c[VY], c[OZ] + t * c[VZ]
        out.P.index_copy_(0, h, stack_columns([px, py]))
        uv = torch.stack([px / W, 1.0 - py / H], 0)
        out.Q.index_copy_(0, h, cam.uv_to_view(uv, -cam.near / pz, dim=0).T.to(out.Q.dtype))


def index_dtype(layers: PyramidLayers) -> torch.dtype:
    """The integer type of a march's images, levels, cells and texel indices over ``layers``: int32 while every
    index into the pyramid fits in it, else int64. The step kernel's index arithmetic then runs on vectors of 32-bit
    lanes, twice as many per instruction as 64-bit ones (and an AVX2 machine has no 64-bit vector multiply).

    Example:
        >>> index_dtype(PyramidLayers(torch.zeros(12), 2, 8))
        torch.int32
    """
    return torch.int32 if layers.cells.numel() < 2 ** 31 else torch.int64


def march_layers(pyr: DepthPyramid, max_mip: int, gbuffer: GBuffer) -> PyramidLayers:
    """The levels ``0 … min(max_mip, top)`` of ``pyr`` as the march reads them (:func:`~.hiz_pyramid.padded_levels`):
    built once per pass and read by every chunk of rays."""
    top = min(max_mip, pyr.count - 1)
    return PyramidLayers(padded_levels(pyr, top + 1), top + 1, gbuffer.view_z.numel())


def hiz_march(r: HiZRays, pyramid: PyramidLayers, tex: HiZTexels, params, gbuffer: GBuffer,
              visits: Optional[torch.Tensor] = None, level_reads: Optional[torch.Tensor] = None) -> MarchOutput:
    """March ``r`` (as :func:`hiz_rays` sets it up: output rows ``i`` = 0 … N−1, the columns of its constants) to
    termination through ``pyramid`` (:func:`march_layers`); one pyramid read per iteration
    (:func:`~.hiz_step.hiz_iterations`), at most ``params.max_traversal_intersections``. Stopped rays ride along
    masked until a quarter of the working set has stopped; then the set is compacted and the stopped rays are
    written back (their hit points once, at the end). ``visits`` :math:`(BHW,)` counts level-0 reads per texel
    and ``level_reads`` :math:`(L,)` reads per level, when given."""
    B, _, H, W = gbuffer.view_z.shape
    dt, dev = r.c.dtype, r.c.device
    out = MarchOutput.empty(r.count, dt, dev, OUT_OF_STEPS)
    constants, hit_t = r.c, torch.zeros_like(r.state.t)                 # by output row (hiz_rays numbers them)
    top = pyramid.layers - 1
    rules = HiZRules(params.reject_backfaces, params.trace_behind, params.thickness_mode == "relative",
                     float(gbuffer.camera.near))
    thickness = torch.tensor(params.depth_buffer_thickness, dtype=dt, device=dev)
    debug = visits is not None or level_reads is not None
    done = r.state.t >= 1.0                                              # the initial advance left the segment
    if compact_now(int((~done).sum()), r.count):
        out.term[r.i[done]] = r.ended[done].to(out.term.dtype)
        r = r.select(flat_nonzero(~done))
    else:                             # few: they ride along stopped (no copy of the whole set) until it is compacted
        r.state = r.state._replace(alive32=torch.where(done, 0, r.state.alive32),
                                   term=torch.where(done, r.ended, r.state.term))
    for count, left in step_blocks(params.max_traversal_intersections, debug, dev):
        if r.count == 0:
            break
        level = r.state.mip
        r.state, seen = hiz_iterations(r.state, r.c, r.b, r.ray_dir, r.ended, pyramid, tex, rules, thickness, W, H,
                                       top, count, left, debug)
        if seen is not None:
            on, cx, cy = seen
            if level_reads is not None:
                level_reads += torch.bincount(level[on], minlength=level_reads.numel())
            if visits is not None:
                at0 = on & (level == 0)
                visits.index_add_(0, (r.b * H * W + cy * W + cx)[at0], torch.ones_like(cx[at0], dtype=visits.dtype))
        alive = r.state.alive32 != 0
        if compact_now(int(alive.sum()), r.count):
            write_back(out, r, flat_nonzero(~alive), hit_t)
            r = r.select(flat_nonzero(alive))
    write_back(out, r, torch.arange(r.count, device=dev), hit_t)
    hit_points(out, constants, hit_t, gbuffer)
    return out
