"""One iteration of the Hi-Z march (:mod:`.hiz_march`, steps 2–3 of its docstring) for every ray of a working set.

:func:`hiz_step` is FidelityFX SSSR's loop body (AMD, 2020; ``ffx_sssr.h``, ``FFX_SSSR_HierarchicalRaymarch``):
one read of the closest-depth pyramid under ``o + t·v`` at the ray's level, and ``AdvanceRay``. :func:`validate`
tests a hit candidate at its level-0 texel (the thickness, back faces, the second depth layer). :func:`hiz_iteration`
is both, for every ray at once, with the ray's termination, read count and hit ``t`` updated in place of the
per-step gathers and scatters of a working set: a ray that is not a candidate, or has stopped, computes its
validation anyway and discards it (``torch.where``). It is the march's size-dynamic compiled kernel
(:mod:`ssbench.passes.compiled`); the march around it only compacts the set now and then and writes back.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import torch

from ...indices import flat_nonzero
from ..compiled import kernel
from .common import BEHIND_SURFACE, HIT, OFF_SCREEN

__all__ = ["EPSILON", "BIG", "COLUMNS", "PyramidLayers", "StepGeometry", "HiZTexels", "HiZRules", "MarchState",
           "inverse", "cell_exit", "hiz_step", "validate", "judge", "hiz_iteration", "hiz_iterations"]

#: how far past a cell border a crossing lands, in pixels (FidelityFX: ``0.005 · 2^most_detailed_mip`` texels)
EPSILON = 0.005
#: ``1/v`` of an axis the ray does not move along: ``t`` of its borders is then huge, never the minimum
#: (FidelityFX uses ``FLT_MAX`` in uv units; in pixels that would overflow)
BIG = 1e30
#: the per-ray constants, rows of :attr:`~.hiz_march.HiZRays.c`
COLUMNS = ("ox", "oy", "oz", "vx", "vy", "vz", "invx", "invy", "invz", "offx", "offy", "epsx", "epsy")
OX, OY, OZ, VX, VY, VZ, INVX, INVY, INVZ, OFFX, OFFY, EPSX, EPSY = range(len(COLUMNS))


class PyramidLayers(NamedTuple):
    """The pyramid as :func:`hiz_step` reads it: ``cells`` the levels ``0 … layers − 1`` of every image, laid out
    by :func:`~.hiz_pyramid.padded_levels`, so that a cell's index is arithmetic (a compiled kernel emulates a
    lookup in a small table of level offsets lane by lane); ``base`` = ``B·H·W``, where level 1 starts."""

    cells: torch.Tensor
    layers: int
    base: int


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


class HiZTexels(NamedTuple):
    """What a candidate is validated against, flat over ``B·H·W``: ``view_z``, ``normal`` :math:`(3, BHW)` (a row
    per component: a compiled kernel gathers each with a vector loop, where a size-3 inner dimension compiles to a
    per-ray reduction loop),
    ``back_z`` (``None`` without layered depth), ``second_z`` (``None`` without the second layer)."""

    view_z: torch.Tensor
    normal: torch.Tensor
    back_z: Optional[torch.Tensor] = None
    second_z: Optional[torch.Tensor] = None


class HiZRules(NamedTuple):
    """The validation's switches (:class:`~.hiz.HiZSSRParams`) and the camera's ``near``; ``thickness`` is
    :func:`hiz_iteration`'s tensor argument, so a new thickness compiles nothing new."""

    reject_backfaces: bool
    trace_behind: bool
    relative: bool
    near: float


class MarchState(NamedTuple):
    """A working set's changing state, :math:`(N,)` each: ``t``, level ``mip``, ``alive32`` (1 while not stopped),
    ``term`` (termination code, ``OUT_OF_STEPS`` until it stops), ``steps`` (on-screen reads) and ``hit_t`` (the
    ``t`` of its hit point, set when it hits). The flags and codes are int32: a compiled kernel stores a bool array
    and selects int8 codes one lane at a time (perf: a quarter of Hi-Z's compiled iteration)."""

    t: torch.Tensor
    mip: torch.Tensor
    alive32: torch.Tensor
    term: torch.Tensor
    steps: torch.Tensor
    hit_t: torch.Tensor


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


def hiz_step(c: torch.Tensor, t: torch.Tensor, mip: torch.Tensor, b: torch.Tensor, pyramid: PyramidLayers, W: int,
             H: int, top: int) -> StepGeometry:
    """Step 2 of :mod:`.hiz_march` for the rays (constants ``c`` :math:`(13, N)`, :data:`COLUMNS`; ``t``, ``mip``,
    image ``b`` :math:`(N,)`): one read of the pyramid and ``AdvanceRay`` (levels up to ``top``)."""
    x, y, z = c[OX] + t * c[VX], c[OY] + t * c[VY], c[OZ] + t * c[VZ]
    off = ~((x >= 0) & (x < W) & (y >= 0) & (y < H))                        # NaN (degenerate input) too
    level = mip.clamp_min(0)                        # a stopped ray riding along masked may be at level −1
    scale = torch.bitwise_left_shift(torch.ones_like(level), level).to(x.dtype)       # 2^m pixels, exactly
    inv_s = 1.0 / scale
    cx, cy = (x * inv_s).to(b.dtype), (y * inv_s).to(b.dtype)                 # x, y ≥ 0 on screen: trunc = floor
    H2, W2 = (H + 1) // 2, (W + 1) // 2                                       # level ≥ 1: a half-size block each
    index = torch.where(level == 0, (b * H + cy) * W + cx,
                        pyramid.base + ((b * (pyramid.layers - 1) + level - 1) * H2 + cy) * W2 + cx)
    index = index.clamp(0, pyramid.cells.numel() - 1)
    surface = pyramid.cells.index_select(0, index)                            # garbage only for `off` rays
    tx = cell_exit(c[OX], c[INVX], c[OFFX], c[EPSX], cx, scale)              # AdvanceRay: the borders
    ty = cell_exit(c[OY], c[INVY], c[OFFY], c[EPSY], cy, scale)
    tz = torch.where((c[INVZ] != 0) & (surface > 0), (surface - c[OZ]) * c[INVZ], torch.inf)   # its closest depth
    side = torch.minimum(tx, ty)
    above = (z > surface) | (surface <= 0)                                    # a cell of background: skip it
    skipped = above & (side < tz)
    t_new = torch.where(above, torch.minimum(side, tz), t)
    return StepGeometry(x, y, z, off, cx, cy, side, t_new, torch.where(skipped, (mip + 1).clamp_max(top), mip - 1))


def validate(ray_dir: torch.Tensor, texel: torch.Tensor, z: torch.Tensor, tex: HiZTexels, rules: HiZRules,
             thickness: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Step 3 of :mod:`.hiz_march` for rays at ``texel`` (flat, in range) with ``rz`` = ``z`` and unit view-space
    ``ray_dir`` :math:`(3, N)`: which hit (the ray within the thickness behind the texel, facing it if asked, or
    within the second layer's); which are in front of the second layer (they go on), and that layer's ``rz``."""
    def behind(surface_z: torch.Tensor) -> torch.Tensor:
        return thickness * surface_z.abs() if rules.relative else thickness
    zs = tex.view_z.index_select(0, texel)
    bottom = (tex.back_z.index_select(0, texel) if tex.back_z is not None else zs) - behind(zs)
    zr = -rules.near / z.clamp_min(torch.finfo(z.dtype).tiny)
    ok = zr >= bottom
    if rules.reject_backfaces:
        n = tex.normal
        facing = (ray_dir[0] * n[0].index_select(0, texel) + ray_dir[1] * n[1].index_select(0, texel)
                  + ray_dir[2] * n[2].index_select(0, texel))       # ATen's sum over a size-3 dimension: in order
        ok = ok & (facing <= 0)
    if tex.second_z is None:
        return ok, torch.zeros_like(ok), torch.zeros_like(z)
    z2 = tex.second_z.index_select(0, texel)
    in2 = (zr <= z2) & (zr >= z2 - behind(z2))
    front2 = ~ok & (zr > z2)
    return ok | in2, front2, torch.where(front2, rules.near / -z2.clamp_max(-torch.finfo(z.dtype).tiny), 0.0)


def judge(oz: torch.Tensor, invz: torch.Tensor, t: torch.Tensor, z: torch.Tensor, side: torch.Tensor,
          texel: torch.Tensor, ray_dir: torch.Tensor, tex: HiZTexels, rules: HiZRules, thickness: torch.Tensor):
    """The verdict on hit candidates at ``texel`` (the constants ``oz`` and ``invz`` of :data:`COLUMNS`, ``t``,
    ``rz`` = ``z`` and ``side`` of :class:`StepGeometry`): ``(hit, go, t_hit)``: whether each hits
    (:func:`validate`, or it reaches the second layer inside the texel), whether it crosses the texel at level 0 and
    goes on (with ``trace_behind``, or in front of the second layer), and the ``t`` of its hit point."""
    ok, front2, rz2 = validate(ray_dir, texel, z, tex, rules, thickness)
    t2 = torch.where(front2 & (invz != 0), (rz2 - oz) * invz, torch.inf)          # the second layer, in the texel
    reach = front2 & (rz2 > 0) & (t2 <= side)                                      # (no layer behind: rz2 = 0)
    ok = ok | reach
    return ok, (~ok if rules.trace_behind else front2 & ~reach), torch.where(reach, t2, t)


def hiz_iteration(s: MarchState, c: torch.Tensor, b: torch.Tensor, ray_dir: torch.Tensor, ended: torch.Tensor,
                  pyramid: PyramidLayers, tex: HiZTexels, rules: HiZRules, thickness: torch.Tensor, W: int, H: int,
                  top: int, go: Optional[torch.Tensor] = None) -> tuple[MarchState, torch.Tensor, torch.Tensor,
                                                                          torch.Tensor]:
    """One iteration for every ray of the working set (state ``s``, constants ``c`` :math:`(13, N)`, image ``b``,
    ``ray_dir`` :math:`(3, N)`, ``ended``: the int32 code of reaching the segment's end), for no ray where ``go``
    (a 0-d bool, if given) is false: :func:`hiz_step`, then :func:`validate` of the candidates. A rejected candidate crosses
    its texel at level 0 and goes on with ``trace_behind``, or when it is in front of the second layer. Returns
    the new state, which rays read on screen and the cell ``cx, cy`` they read (for the debug counters)."""
    g = hiz_step(c, s.t, s.mip, b, pyramid, W, H, top)
    alive = s.alive32 != 0 if go is None else (s.alive32 != 0) & go
    on = alive & ~g.off
    cand = on & (g.mip < 0)
    texel = b * H * W + g.cy * W + g.cx
    if torch.compiler.is_compiling():            # one fused loop: every ray judged, the verdicts of non-candidates
        hit, go, t_hit = judge(c[OZ], c[INVZ], s.t, g.z, g.side, torch.where(cand, texel, 0), ray_dir, tex, rules,
                               thickness)
        hit, go = cand & hit, cand & go
    else:                                        # eager: only the candidates, each operation a pass over them
        i = flat_nonzero(cand)
        sub = lambda v: v.index_select(-1, i)    # noqa: E731
        h, gi, th = judge(sub(c[OZ]), sub(c[INVZ]), sub(s.t), sub(g.z), sub(g.side), sub(texel), sub(ray_dir), tex,
                          rules, thickness)                  # (of the constants, only the two rows it reads)
        hit, go = torch.zeros_like(cand).index_copy_(0, i, h), torch.zeros_like(cand).index_copy_(0, i, gi)
        t_hit = s.t.index_copy(0, i, th)
    t_new = torch.where(go, g.side, g.t_new)
    mip = torch.where(go, 0, g.mip)
    done = alive & (g.off | hit | (mip < 0) | (t_new >= 1.0))
    code = torch.where(g.off, OFF_SCREEN, torch.where(hit, HIT, torch.where(mip < 0, BEHIND_SURFACE, ended)))  # int32
    state = MarchState(t=t_new, mip=mip, alive32=torch.where(done, 0, s.alive32),
                       term=torch.where(done, code, s.term), steps=s.steps + on.int(),
                       hit_t=torch.where(hit, t_hit, s.hit_t))
    return state, on, g.cx, g.cy


@kernel(dynamic=True, fuse_whole=True)
def hiz_iterations(s: MarchState, c: torch.Tensor, b: torch.Tensor, ray_dir: torch.Tensor, ended: torch.Tensor,
                   pyramid: PyramidLayers, tex: HiZTexels, rules: HiZRules, thickness: torch.Tensor, W: int, H: int,
                   top: int, count: int, left: Optional[torch.Tensor],
                   debug: bool = False) -> tuple[MarchState, Optional[tuple[torch.Tensor, ...]]]:
    """``count`` :func:`hiz_iteration` s, the ``j``-th only while ``j < left`` (a 0-d count of the iterations the
    march has left; ``None``: all; :func:`~ssbench.passes.compiled.step_blocks`): the march's size-dynamic compiled
    kernel. One iteration per call streams the working set's ~110 bytes per ray through memory; eight keep them in
    registers in between. Returns the new state and, with ``debug``
    (``count`` 1), the rays that read on screen and their cells."""
    for j in range(count):
        s, on, cx, cy = hiz_iteration(s, c, b, ray_dir, ended, pyramid, tex, rules, thickness, W, H, top,
                                      None if left is None else left > j)
    return s, ((on, cx, cy) if debug else None)
