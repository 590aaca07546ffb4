"""The DDA's march (:mod:`.dda`, SSR article §2.2) on its per-ray state (:mod:`.dda_state`): the step loop
(:func:`dda_march`), ``texelFetch`` in the permuted frame, fetch counting
for the visit maps, and the two refinements of a strided hit (the article's binary search, G3D's 1-pixel
re-march). The supercover DDA (:mod:`.dda_supercover`) shares ``count_visits``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple, Optional

import torch

from ...indices import flat_nonzero
from ...layout import stack_columns
from ..compiled import kernel
from ..float_masks import float_flags
from .common import HIT, OFF_SCREEN, OUT_OF_STEPS, end_code, ray_view_z
from .dda_float_step import float_dda_step, float_fields
from .dda_state import DDARays, DepthTexels, MarchOutput
from .masked_march import add_visits, hit_rows, marching_fields, masked_march, next_state

if TYPE_CHECKING:                                        # (ssr_dda imports this module)
    from .dda import DDASSRParams


def fetch_cell(permute: torch.Tensor, b: torch.Tensor, Px: torch.Tensor, Py: torch.Tensor, tex, H: int, W: int):
    """``(on_screen, flat texel, sceneZMax, mask)`` at ``hitPixel = permute ? P.yx : P`` (``texelFetch``) of the
    rays in batch items ``b``; ``tex``: :func:`~ssbench.passes.ssr.dda.depth_texels`' textures
    (:class:`~ssbench.passes.ssr.dda_state.DepthTexels`)."""
    px, py = torch.where(permute, Py, Px), torch.where(permute, Px, Py)
    on = (px >= 0) & (px < W) & (py >= 0) & (py < H)
    t = b * (H * W) + py.floor().clamp(0, H - 1).long() * W + px.floor().clamp(0, W - 1).long()
    return on, t, torch.take(tex.view_z, t), torch.take(tex.mask, t)         # (take: a faster gather than [t])


def count_visits(out: MarchOutput, visits, i, t, active) -> None:
    """Add the fetches of ``active`` rays (bool, or int32 0/1) to their step counts and to the visit map."""
    out.steps.index_add_(0, i, active.int())
    if visits is not None:
        add_visits(visits, t, active)


def refine_hits(h: DDARays, tex, params: "DDASSRParams", H: int, W: int, out: MarchOutput, visits) -> None:
    """Refine hits in place (``h``: rays at their coarse hit ``P``) where the stride exceeds 1 px.

    ``"binary"`` bisects the footprint ``[P − ½dP, P + ½dP]`` and keeps the nearest probe with the ray at or behind
    its texel; if none is, the far end when the ray is within ``z_thickness`` in front of its texel there (texel
    quantisation), else ``P`` (a thin feature the probes stepped off). ``"remarch"`` walks pixels from ``P − dP``.
    """
    binary, keys, need = params.refinement == "binary", ("Px", "Py", "Qz", "k", "n"), h.stride > 1.0
    rounds = params.binary_search_iterations if binary else int(1.4 * float(h.stride.max()))
    if params.refinement == "none" or rounds == 0 or not bool(need.any()):
        return
    inv, back = 1.0 / h.stride, (0.5 if binary else 1.0)
    at = {key: getattr(h, key) for key in keys}                                   # the coarse hit
    step = {"Px": h.dPx, "Py": h.dPy, "Qz": h.dQz, "k": h.dk, "n": torch.ones_like(h.k)}   # per stride
    cur = {key: at[key] - step[key] * back for key in keys}                      # footprint start / last miss
    best, found = dict(at), torch.zeros_like(need)                                # the coarse hit by default
    original = h.stride * 0.5
    stride = original if binary else torch.ones_like(inv)                        # pixels (article §1.3; G3D)
    for r in range(1, rounds + 1):
        cur = {key: cur[key] + step[key] * inv * stride for key in keys}
        on, t, sceneZMax, m = fetch_cell(h.permute, h.b, cur["Px"], cur["Py"], tex, H, W)
        if binary:
            active = need & on
            behind = active & m & (ray_view_z(cur["Qz"], cur["k"], h.zlo, h.zhi) <= sceneZMax)
            original = original * 0.5
            stride = torch.where(behind, -original, original)
        else:
            active = need & on & ~found & (r <= 1.4 * h.stride)
            zA = ray_view_z(cur["Qz"] - 0.5 * h.dQz * inv, cur["k"] - 0.5 * h.dk * inv, h.zlo, h.zhi)
            zB = ray_view_z(cur["Qz"] + 0.5 * h.dQz * inv, cur["k"] + 0.5 * h.dk * inv, h.zlo, h.zhi)
            behind = active & m & (torch.minimum(zA, zB) <= sceneZMax)
        take = behind & (~found | (cur["n"] <= best["n"]))                         # the nearest probe behind
        best, found = {key: torch.where(take, cur[key], best[key]) for key in keys}, found | behind
        count_visits(out, visits, h.i, t, active)
    if binary:                                  # no probe behind: the far end, if the ray is just in front there
        far = {key: at[key] + step[key] * 0.5 for key in keys}
        on, t, sceneZMax, m = fetch_cell(h.permute, h.b, far["Px"], far["Py"], tex, H, W)
        active = need & on & ~found
        use = active & m & (ray_view_z(far["Qz"], far["k"], h.zlo, h.zhi) <= sceneZMax + params.z_thickness)
        best = {key: torch.where(use, far[key], best[key]) for key in keys}
        count_visits(out, visits, h.i, t, active)
    for key in keys:
        setattr(h, key, best[key])


class DDAState(NamedTuple):
    """What one DDA step changes, per ray of the working set (each :math:`(N,)`; fields of :class:`MarchingRays`):
    the sample ``Px, Py`` (permuted frame), ``Qz``, ``k``, the step count ``n``, the ray's z at the end of the last
    footprint ``prevZ``, ``alive32`` and ``steps`` (fetches), int32 (a compiled kernel loads bool arrays lane by
    lane), and ``term``, the int32 termination code (``OUT_OF_STEPS`` until the ray stops)."""

    Px: torch.Tensor
    Py: torch.Tensor
    Qz: torch.Tensor
    k: torch.Tensor
    n: torch.Tensor
    prevZ: torch.Tensor
    alive32: torch.Tensor
    steps: torch.Tensor
    term: torch.Tensor


class DDARay(NamedTuple):
    """What one DDA step reads and leaves as it is, per ray (fields of :class:`MarchingRays`): the step ``dPx, dPy,
    dQz, dk``, the ``stride``, ``stepDir``, where the footprints stop (``stop``) and the ray ends (``end``), the
    z clamp ``zlo, zhi``, ``permute32`` and ``clipped32`` (int32) and the batch index ``b_index``."""

    dPx: torch.Tensor
    dPy: torch.Tensor
    dQz: torch.Tensor
    dk: torch.Tensor
    stride: torch.Tensor
    stepDir: torch.Tensor
    stop: torch.Tensor
    end: torch.Tensor
    zlo: torch.Tensor
    zhi: torch.Tensor
    permute32: torch.Tensor
    clipped32: torch.Tensor
    b_index: torch.Tensor


def dda_step(state: DDAState, ray: DDARay, tex: tuple, size: tuple, z_thickness: float,
             go: Optional[torch.Tensor] = None) -> tuple:
    """One DDA step of :func:`dda_march` for every ray of the working set: advance by a stride, shorten the last
    footprint at ``stop``, ``texelFetch`` and the depth test. A ray that has stopped keeps its state (a hit ray:
    where it hit, for the refinement); so does every ray where ``go`` (a 0-d bool, if given) is false.

    Args:
        state: :class:`DDAState`; ray: :class:`DDARay`.
        tex: ``(front, back, second)`` flat: the scene view z with NaN off the mask (a NaN compares false, so a
            cleared texel is never hit), the back-face and second-layer z (or ``None``) likewise.

    Returns:
        ``(state, done, t, live)``: the new :class:`DDAState`, the rays that stopped here, the fetched texels and
        the rays that fetched them.
    """
    if state.alive32.is_floating_point():        # eager 0/1 float flags (dda_march, float_fields): the same bits
        return float_dda_step(state, ray, tex, size, z_thickness)
    st, r = state, ray
    front, back_z, second_z = tex
    H, W = size
    marching = st.alive32 != 0 if go is None else (st.alive32 != 0) & go
    Px, Py, Qz, k = st.Px + r.dPx, st.Py + r.dPy, st.Qz + r.dQz, st.k + r.dk
    n = st.n + 1.0
    u = Px * r.stepDir
    beyond = marching & (u > r.stop)                                              # centre past P1 / the edge
    f = ((r.stop - u) / r.stride + 0.5).clamp(0.0, 1.0)                           # footprint share before stop
    partial = beyond & (f > 0)                                                    # last, shortened footprint
    past = beyond & ~partial                                                      # nothing left to test: ended
    back = torch.where(partial, 0.5 * (1.0 - f), 0.0)                             # centre of [P − ½dP, stop]
    Px, Py, Qz, k = Px - r.dPx * back, Py - r.dPy * back, Qz - r.dQz * back, k - r.dk * back
    n = n - back
    half = torch.where(partial, 0.5 * f, 0.5)
    swap, b = r.permute32 != 0, r.b_index
    px, py = torch.where(swap, Py, Px), torch.where(swap, Px, Py)                 # hitPixel = permute ? P.yx : P
    on = (px >= 0) & (px < W) & (py >= 0) & (py < H)
    t = b * (H * W) + py.floor().clamp(0, H - 1).to(b.dtype) * W + px.floor().clamp(0, W - 1).to(b.dtype)
    sceneZMax = front.index_select(0, t)
    off, live = marching & ~past & ~on, marching & ~past & on                    # live: this sample is fetched
    rayZMin = st.prevZ
    rayZMax = ray_view_z(r.dQz * half + Qz, r.dk * half + k, r.zlo, r.zhi)        # footprint end
    prevZ = rayZMax
    rayZMin, rayZMax = torch.minimum(rayZMin, rayZMax), torch.maximum(rayZMin, rayZMax)   # swap
    bottom = back_z.index_select(0, t) if back_z is not None else sceneZMax       # layered depth: the back face
    hit = live & (rayZMax >= bottom - z_thickness) & (rayZMin <= sceneZMax)
    if second_z is not None:                                                      # the second depth layer
        z2 = second_z.index_select(0, t)
        hit = hit | (live & (rayZMax >= z2 - z_thickness) & (rayZMin <= z2))
    term = torch.where(u > r.end, end_code(r.clipped32), OFF_SCREEN)   # past P1 at the full step's centre; int32
    term = torch.where(off, OFF_SCREEN, torch.where(hit, HIT, term))
    done = past | off | hit | partial
    return next_state(st, marching, (Px, Py, Qz, k, n, prevZ), done, live, term), done, t, live


@kernel(dynamic=True, fuse_whole=True)
def dda_steps(state: DDAState, ray: DDARay, tex: tuple, size: tuple, z_thickness: float, count: int,
              left: Optional[torch.Tensor], debug: bool = False) -> tuple:
    """``count`` steps of :func:`dda_step` for every ray of the working set (the march's size-dynamic compilable
    kernel), the ``j``-th only while ``j < left`` (a 0-d count of the steps the march has left; ``None``: all;
    :func:`~ssbench.passes.compiled.step_blocks`). One step per call streams the working set's ~120 bytes per
    ray through memory; eight keep them in registers in between.

    Returns:
        The new state, how many rays stopped (0-d) and, with ``debug`` (``count`` 1), the fetched texels and which
        rays fetched them (int32).
    """
    done = torch.zeros_like(state.alive32)
    for j in range(count):
        state, d, t, live = dda_step(state, ray, tex, size, z_thickness, None if left is None else left > j)
        done = d.to(done.dtype) if j == 0 else done | d.to(done.dtype)
    return (state, done.sum()) + ((t, live.to(torch.int32)) if debug else ())


def flush(out: MarchOutput, s: DDARays, rows: torch.Tensor, set_up: DDARays, tex, params: "DDASSRParams", H: int,
          W: int, visits: Optional[torch.Tensor]) -> None:
    """Write the termination and fetches of the working set's ``rows`` (stopped rays, or every ray at the end)
    into ``out``; refine the hits among them (:func:`refine_hits`) and write their hit points (``set_up``: the
    rays before the march, for the fields :data:`HIT_ONLY`)."""
    term = out.write_ends(rows, s.i, s.term, s.steps)
    hi = rows.index_select(0, flat_nonzero(term == HIT))
    if hi.numel():
        h = hit_rows(s, hi, set_up)
        refine_hits(h, tex, params, H, W, out, visits)
        out.write_hits(h.i, torch.where(h.permute[:, None], stack_columns([h.Py, h.Px]), stack_columns([h.Px, h.Py])),
                       stack_columns([h.Q0x + h.dQx * h.n, h.Q0y + h.dQy * h.n, h.Qz]), h.k)


def dda_march(s: DDARays, tex: DepthTexels, params: "DDASSRParams", H: int, W: int,
              visits: Optional[torch.Tensor]) -> MarchOutput:
    """The DDA loop; per-ray outputs by ``s.i``. Each step is :func:`dda_step`; stopped rays keep their state,
    masked, until 1/8 of the working set has stopped; then they are written back, their hits refined
    (:func:`refine_hits`), and the set compacted (:func:`~.masked_march.masked_march`)."""
    N, set_up = s.count, s
    out = MarchOutput.empty(N, s.k.dtype, s.k.device, OUT_OF_STEPS)
    s = MarchingRays(**marching_fields(s, tex.view_z.numel()))
    if float_flags(s.k, tex.view_z.numel()):                                     # eager: 0/1 float flags
        s = float_fields(s)
    run = lambda state, ray, count, left: dda_steps(state, ray, tex.marched, (H, W), params.z_thickness,  # noqa: E731
                                                    count, left, visits is not None)
    masked_march(s, DDAState, DDARay, run, lambda s, rows: flush(out, s, rows, set_up, tex, params, H, W, visits),
                 params.max_steps, visits)
    return out


@dataclass
class MarchingRays(DDARays):
    """:class:`DDARays` as :func:`dda_march` marches them: the batch index in the texel index dtype, ``permute``,
    ``clipped`` and ``alive`` as int32 (for the compiled step), and each ray's fetches ``steps`` (int32) and
    termination code ``term`` (int32), written back when the ray is dropped. Eagerly, the batch index, ``clipped``,
    ``alive``, ``steps`` and ``term`` are in the samples' dtype instead (:mod:`.dda_float_step`)."""

    b_index: Optional[torch.Tensor] = None
    permute32: Optional[torch.Tensor] = None
    clipped32: Optional[torch.Tensor] = None
    alive32: Optional[torch.Tensor] = None
    steps: Optional[torch.Tensor] = None
    term: Optional[torch.Tensor] = None
