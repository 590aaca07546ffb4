"""The supercover DDA's cell walk (:mod:`.dda_supercover`; J. Amanatides and A. Woo, "A Fast Voxel Traversal
Algorithm for Ray Tracing", Eurographics 1987, http://www.cse.yorku.ca/~amana/research/grid.pdf) on its per-ray
state: the start (:func:`cell_setup`), one cell per step for every ray of the working set (:func:`walk_step`,
several per compiled call: :func:`walk_steps`), and the exact hit point in the hit cell (:func:`hit_at`), computed
when a stopped ray is written back (:func:`flush`).

The step keeps a fixed shape, as the DDA's (:func:`~ssbench.passes.ssr.dda_march.dda_step`) does: a ray that
stops keeps its state, masked, until :func:`~ssbench.passes.ssr.masked_march.masked_march` compacts the set, so the
step compiles (``torch.compile``) once for every working-set size. A hit ray keeps the cell it hit, its edge
parameters after the step and the entry parameter ``nA`` of that cell: all :func:`hit_at` needs.
Each cell's exit z, ``z(nB)``, is the next cell's entry z (``prevZ``, as the DDA's ``prevZ``): one division per
step, not two.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Optional

import torch

from ...indices import flat_nonzero
from ...layout import stack_columns
from ..compiled import kernel
from .common import HIT, OFF_SCREEN, OUT_OF_STEPS, end_code, ray_view_z
from .masked_march import HIT_ONLY, hit_rows, marching_fields, masked_march, next_state
from .dda_state import DDARays, DepthTexels, MarchOutput

__all__ = ["CellWalk", "WalkState", "WalkRay", "cell_setup", "hit_at", "walk_step", "walk_steps",
           "supercover_march"]


@dataclass(kw_only=True)
class CellWalk(DDARays):
    """:class:`~ssbench.passes.ssr.dda_state.DDARays` plus the Amanatides–Woo cell state, each :math:`(N,)`
    (permuted frame, ``n`` in major-axis pixels from ``P0``): cell ``cx, cy``; edge parameters ``tx, ty``
    (``tMaxX/Y``); ``nA``, where the ray entered its cell; ``prevZ``, the ray's z where it leaves that cell (where it
    enters the next; before the first step: where it enters the first); ``ddy`` (``tDeltaY``; ``tDeltaX = 1``);
    ``sy`` (``stepY``; ``stepX = stepDir``); ``nEnd`` (``P1``); ``Wm, Hm``: the image's size along the major and
    minor axes; and as the march keeps them: the batch index in the texel index dtype, ``permute``, ``clipped`` and
    ``alive`` as int32, the fetches ``steps`` (int32) and the termination code ``term`` (int32)."""

    cx: torch.Tensor
    cy: torch.Tensor
    tx: torch.Tensor
    ty: torch.Tensor
    nA: torch.Tensor
    ddy: torch.Tensor
    sy: torch.Tensor
    nEnd: torch.Tensor
    Wm: torch.Tensor
    Hm: torch.Tensor
    b_index: torch.Tensor
    permute32: torch.Tensor
    clipped32: torch.Tensor
    alive32: torch.Tensor
    steps: torch.Tensor
    term: torch.Tensor


class WalkState(NamedTuple):
    """What one cell of the walk changes, per ray of the working set (fields of :class:`CellWalk`): the cell ``cx,
    cy``, the edge parameters ``tx, ty``, the entry ``nA``, ``prevZ``, ``alive32``, ``steps`` and ``term``."""

    cx: torch.Tensor
    cy: torch.Tensor
    tx: torch.Tensor
    ty: torch.Tensor
    nA: torch.Tensor
    prevZ: torch.Tensor
    alive32: torch.Tensor
    steps: torch.Tensor
    term: torch.Tensor


class WalkRay(NamedTuple):
    """What one cell of the walk reads and leaves as it is, per ray (fields of :class:`CellWalk`): ``stepDir``,
    ``sy``, ``ddy``, ``nEnd``, the image's size ``Wm, Hm`` along the major and minor axes, ``Qz, dQz, k, dk`` (the
    ray's z), its clamp ``zlo, zhi``, ``permute32``, ``clipped32`` and the batch index ``b_index``."""

    stepDir: torch.Tensor
    sy: torch.Tensor
    ddy: torch.Tensor
    nEnd: torch.Tensor
    Wm: torch.Tensor
    Hm: torch.Tensor
    Qz: torch.Tensor
    dQz: torch.Tensor
    k: torch.Tensor
    dk: torch.Tensor
    zlo: torch.Tensor
    zhi: torch.Tensor
    permute32: torch.Tensor
    clipped32: torch.Tensor
    b_index: torch.Tensor


#: the set-up's fields that the walk reads only where a ray hits (the DDA's :data:`~.masked_march.HIT_ONLY`, the sample
#: point and the DDA's per-stride state, which the cell walk replaces): read back by row for the hits
#: (:func:`~.masked_march.hit_rows`), not copied by every compaction
WALK_HIT_ONLY = HIT_ONLY + ("Px", "Py", "n", "dPx", "dPy", "stride", "end", "stop")


def cell_setup(s: DDARays, H: int, W: int, texels: int) -> CellWalk:
    """The cell walk's start from the DDA's set-up ``s`` (``ssr.dda_rays.dda_rays`` at stride 1, no jitter), over
    ``texels`` depth texels (which picks the index dtype); the fields :data:`WALK_HIT_ONLY` are left out."""
    sd, dPy = s.stepDir, s.dPy
    cx, cy = s.Px.floor(), s.Py.floor()
    safe = torch.where(dPy != 0, dPy, 1.0)
    ty = torch.where(dPy != 0, (torch.where(dPy > 0, cy + 1, cy) - s.Py) / safe, math.inf)
    tx = ((cx + (sd > 0).to(cx.dtype)) - s.Px) * sd
    nA = torch.minimum(tx, ty)                                                     # the first cell's entry
    first = {"prevZ": ray_view_z(s.Qz + s.dQz * nA, s.k + s.dk * nA, s.zlo, s.zhi)}
    return CellWalk(**{**marching_fields(s, texels, WALK_HIT_ONLY), **first}, cx=cx, cy=cy, tx=tx, ty=ty, nA=nA,
                    ddy=torch.where(dPy != 0, 1.0 / safe.abs(), math.inf), sy=torch.sign(dPy), nEnd=s.end - s.Px * sd,
                    Wm=torch.where(s.permute, float(H), float(W)), Hm=torch.where(s.permute, float(W), float(H)))


def walk_step(state: WalkState, ray: WalkRay, view_z: torch.Tensor, size: tuple, z_thickness: float,
              go: Optional[torch.Tensor] = None) -> tuple:
    """One cell of the walk for every ray of the working set: cross the nearer of the next column and row edge
    (both at a lattice corner), ``texelFetch`` the cell entered and test the ray's z interval over it,
    ``[z(nA), z(nB)]``, against the texel's box. A ray that has stopped keeps its state (a hit ray: its hit
    cell); so does every ray where ``go`` (a 0-d bool, if given) is false.

    Args:
        state: :class:`WalkState`; ray: :class:`WalkRay`.
        view_z: :math:`(B·H·W,)` the scene's view z, NaN off the mask (a NaN compares false: never hit).
        size: ``(H, W)``; z_thickness: ``zThickness``.

    Returns:
        ``(state, done, t, live)``: the new :class:`WalkState`, the rays that stopped here, the fetched texels and
        the rays that fetched them.
    """
    st, r = state, ray
    H, W = size
    marching = st.alive32 != 0 if go is None else (st.alive32 != 0) & go
    nA = torch.minimum(st.tx, st.ty)                                               # edge crossed into the cell
    stepx, stepy = st.tx <= st.ty, st.ty <= st.tx                                  # both: through a corner
    cx, tx = torch.where(stepx, st.cx + r.stepDir, st.cx), torch.where(stepx, st.tx + 1, st.tx)
    cy, ty = torch.where(stepy, st.cy + r.sy, st.cy), torch.where(stepy, st.ty + r.ddy, st.ty)
    nB = torch.minimum(torch.minimum(tx, ty), r.nEnd)                              # where it leaves (or P1)
    past = marching & (nA >= r.nEnd)
    off = marching & ~past & ((cx < 0) | (cx >= r.Wm) | (cy < 0) | (cy >= r.Hm))
    live = marching & ~past & ~off
    t = texel(cx, cy, r.permute32, r.b_index, H, W)
    sceneZMax = view_z.index_select(0, t)
    zA = st.prevZ                                 # z(nA): the last cell's z(nB), as nA is its nB (or the ray is past)
    zB = ray_view_z(r.Qz + r.dQz * nB, r.k + r.dk * nB, r.zlo, r.zhi)
    rayZMin, rayZMax = torch.minimum(zA, zB), torch.maximum(zA, zB)
    hit = live & (rayZMax >= sceneZMax - z_thickness) & (rayZMin <= sceneZMax)
    term = torch.where(off, OFF_SCREEN, torch.where(past, end_code(r.clipped32), HIT))   # past, off: exclusive
    done = past | off | hit
    return next_state(st, marching, (cx, cy, tx, ty, nA, zB), done, live, term), done, t, live


def texel(cx, cy, permute, b, H: int, W: int) -> torch.Tensor:
    """The flat texel index ``b·H·W + y·W + x`` of cell ``(cx, cy)`` (permuted frame; clamped into the image)."""
    swap = permute != 0
    px, py = torch.where(swap, cy, cx), torch.where(swap, cx, cy)
    return b * (H * W) + py.clamp(0, H - 1).to(b.dtype) * W + px.clamp(0, W - 1).to(b.dtype)


@kernel(dynamic=True, fuse_whole=True)
def walk_steps(state: WalkState, ray: WalkRay, tex: tuple, size: tuple, z_thickness: float, count: int,
               left: Optional[torch.Tensor], debug: bool = False) -> tuple:
    """``count`` steps of :func:`walk_step` (the walk's size-dynamic compilable kernel), the ``j``-th only while
    ``j < left`` (``None``: all); ``tex``: the DDA's ``(view_z, back_z, second_z)`` step textures, of which the walk
    reads the first. Returns the new state, how many rays stopped (0-d) and, with ``debug`` (``count`` 1), the
    fetched texels and which rays fetched them (int32)."""
    done = torch.zeros_like(state.alive32)
    for j in range(count):
        state, d, t, live = walk_step(state, ray, tex[0], size, z_thickness, None if left is None else left > j)
        done = done | d.to(done.dtype)
    return (state, done.sum()) + ((t, live.to(torch.int32)) if debug else ())


def hit_at(h: DDARays, nA, nB, zA, sceneZMax):
    """``n`` of the hit: ``nA`` if the ray enters the cell at or behind ``sceneZMax``, else where it crosses
    ``z = sceneZMax`` (perspective-correct: ``Q_z(n) = sceneZMax·k(n)``), clamped to ``[nA, nB]``."""
    den = h.dQz - sceneZMax * h.dk
    n_star = (sceneZMax * h.k - h.Qz) / torch.where(den != 0, den, 1.0)
    n_star = torch.where((den != 0) & torch.isfinite(n_star), n_star, nA)
    return torch.where(zA <= sceneZMax, nA, torch.minimum(torch.maximum(n_star, nA), nB))


def flush(out: MarchOutput, c: CellWalk, rows: torch.Tensor, set_up: DDARays, view_z: torch.Tensor, H: int,
          W: int) -> None:
    """Write the termination and fetches of the walk's ``rows`` into ``out``, and the hit points of its hits:
    :func:`hit_at` in the hit cell, from the cell's entry ``nA`` and exit ``nB`` (``view_z``: the scene's;
    ``set_up``: the rays before the walk, for the fields :data:`WALK_HIT_ONLY`)."""
    term = out.write_ends(rows, c.i, c.term, c.steps)
    hi = rows.index_select(0, flat_nonzero(term == HIT))
    if not hi.numel():
        return
    h = hit_rows(c, hi, set_up, WALK_HIT_ONLY)
    nA, nB = h.nA, torch.minimum(torch.minimum(h.tx, h.ty), h.nEnd)
    sceneZMax = view_z.index_select(0, texel(h.cx, h.cy, h.permute32, h.b_index, H, W))
    n = hit_at(h, nA, nB, ray_view_z(h.Qz + h.dQz * nA, h.k + h.dk * nA, h.zlo, h.zhi), sceneZMax)
    inside = lambda v, cell: torch.minimum(torch.maximum(v, cell), torch.nextafter(cell + 1, cell))  # noqa: E731
    x, y = inside(h.Px + h.stepDir * n, h.cx), inside(h.Py + h.dPy * n, h.cy)
    out.write_hits(h.i, torch.where(h.permute[:, None], stack_columns([y, x]), stack_columns([x, y])),
                   stack_columns([h.Q0x + h.dQx * n, h.Q0y + h.dQy * n, h.Qz + h.dQz * n]), h.k + h.dk * n)


def supercover_march(s: DDARays, tex: DepthTexels, z_thickness: float, max_steps: int, H: int, W: int,
                     visits: Optional[torch.Tensor]) -> MarchOutput:
    """The cell walk of the rays ``s`` over the textures ``tex`` (:func:`~ssbench.passes.ssr.dda.depth_texels`);
    per-ray outputs by ``s.i``; ``visits`` (or ``None``): the debug visit map, counted per fetch."""
    out = MarchOutput.empty(s.count, s.k.dtype, s.k.device, OUT_OF_STEPS)
    c = cell_setup(s, H, W, tex.view_z.numel())
    run = lambda state, ray, count, left: walk_steps(state, ray, tex.marched, (H, W), z_thickness, count,  # noqa: E731
                                                     left, visits is not None)
    masked_march(c, WalkState, WalkRay, run, lambda c, rows: flush(out, c, rows, s, tex.view_z, H, W), max_steps,
                 visits)
    return out
