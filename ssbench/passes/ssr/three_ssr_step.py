"""Steps of three.js ``SSRShader``'s pixel DDA (steps 3–4 of :mod:`ssbench.passes.ssr.three_ssr`) over the
march's working set (:func:`pixel_step`): the sample, its texel fetch and unprojection, the ray's
perspective-correct depth, the hit test and the hit's verdict (a back face, or a texel beyond ``maxDistance`` from
the reflecting plane, ends the ray without a hit). :func:`march_steps` is the size-dynamic compiled kernel
(:mod:`ssbench.passes.compiled`): compiled, it runs :data:`~ssbench.passes.compiled.STEPS_PER_CALL` steps per call,
the rays' state in registers between them (one step per call read and wrote the whole working set, ~40 bytes a
ray, and was bound by that traffic).
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import torch

from ...indices import flat_nonzero
from ...layout import stack_columns
from ...rays import component_norm, cross_components
from ..common import flat_texel, gl_texel
from ..compiled import kernel
from .common import HIT, MAX_DISTANCE, OFF_SCREEN

__all__ = ["StepTextures", "MarchRays", "MarchState", "take_rows", "unproject_components", "unproject",
           "point_to_line", "pixel_step", "march_steps"]


def unproject_components(minv: torch.Tensor, u: torch.Tensor, v: torch.Tensor, d: torch.Tensor,
                         clip_w: torch.Tensor, rows: int = 3) -> tuple:
    """``getViewPosition``: ``(cameraInverseProjectionMatrix · ((uv, d) − ½)·2·clipW).xyz`` as its ``x, y, z``
    (only ``x`` with ``rows=1``); ``minv`` the inverse projection matrix."""
    clip = ((u - 0.5) * 2.0 * clip_w, (v - 0.5) * 2.0 * clip_w, (d - 0.5) * 2.0 * clip_w, clip_w)
    return tuple(sum(minv[i, k] * clip[k] for k in range(4)) for i in range(rows))


def unproject(minv: torch.Tensor, u: torch.Tensor, v: torch.Tensor, d: torch.Tensor, clip_w: torch.Tensor,
              rows: int = 3) -> torch.Tensor:
    """:func:`unproject_components` stacked: ``(..., 3)`` (``(..., 1)`` with ``rows=1``)."""
    return torch.stack(unproject_components(minv, u, v, d, clip_w, rows), -1)


class StepTextures(NamedTuple):
    """What a step reads, flat over ``B·H·W``: the GL depth (``tDepth``) and ``getViewZ`` of every texel, the
    inverse projection matrix :math:`(4, 4)` and the view normals as :math:`(B·H·W, 3)` rows."""

    depth: torch.Tensor
    view_z: torch.Tensor
    minv: torch.Tensor
    normal: torch.Tensor


class MarchRays(NamedTuple):
    """The constants of the pixel DDA's working set: ray ids (``ray``, into the rays the shader casts), the batch
    index ``b`` (in the texel index dtype), ``d0``, ``span``, ``totalStep``, ``1/z`` at both ends,
    ``viewPosition``, the far end ``d1viewPosition``, the ray's length, ``viewReflectDir``, ``viewNormal`` and
    ``sStep``. Each is :math:`(N,)`; a vector is a tuple of its components (``d0``, ``span``: x, y; ``vp``,
    ``d1v``, ``refl``, ``n``: x, y, z), each contiguous, so that the compiled step loads them a vector of rays at a
    time (rows of ``(N, 3)`` compiled to a scalar loop)."""

    ray: torch.Tensor
    b: torch.Tensor
    d0: tuple
    span: tuple
    total: torch.Tensor
    recip: torch.Tensor
    recip_end: torch.Tensor
    vp: tuple
    d1v: tuple
    length: torch.Tensor
    refl: tuple
    n: tuple
    s_step: torch.Tensor

    def take(self, keep: torch.Tensor) -> "MarchRays":
        """The rays at positions ``keep`` of this set."""
        return MarchRays(*(_take(v, keep) for v in self))


class MarchState(NamedTuple):
    """Each ray's state, :math:`(N,)` per field: ``alive32`` (1 while still marching), ``term`` (its termination
    code once stopped), ``steps``, ``s`` (the interpolation parameter, which does not advance on a background texel
    or a hit) and the hit's record: ``hit_tex`` (the texel in its image), ``hit_xy`` (x, y) and ``hit_vp`` (x, y, z),
    written when the ray stops on a hit that passes its verdict. The flag and the code are int32: a compiled step
    stores a bool array and selects int8 codes one lane at a time (perf: a quarter of its time)."""

    alive32: torch.Tensor
    term: torch.Tensor
    steps: torch.Tensor
    s: torch.Tensor
    hit_tex: torch.Tensor
    hit_xy: tuple
    hit_vp: tuple

    def take(self, keep: torch.Tensor) -> "MarchState":
        """The rays at positions ``keep`` of this set."""
        return MarchState(*(_take(v, keep) for v in self))


def _take(v, keep: torch.Tensor):
    return tuple(c.index_select(0, keep) for c in v) if isinstance(v, tuple) else v.index_select(0, keep)


def take_rows(components: tuple, at: torch.Tensor) -> torch.Tensor:
    """The vectors of ``components`` (a tuple of :math:`(N,)`) at positions ``at``, as :math:`(m, C)` rows."""
    return stack_columns([c.index_select(0, at) for c in components])


def point_to_line(a: list, b: list) -> torch.Tensor:
    """``length(cross(a, b))`` of vectors given as their x, y, z (``pointToLineDistance``'s numerator), the cross
    product on components (:func:`ssbench.rays.cross_components`). Eager: its components stacked once into rows for
    ``Tensor.norm`` (ATen's bits; stacking ``a`` and ``b`` too, for :func:`ssbench.rays.cross`, made the eager
    three.js march 1.2× slower); compiled: :func:`ssbench.rays.component_norm` of them (a stack inside the kernel is
    stored and read back a row at a time)."""
    c = cross_components(a, b)
    if torch.compiler.is_compiling():
        return component_norm(*c)
    return stack_columns(c).norm(dim=1)                                       # cross's bits, no stacked a, b


def _verdict(hit: torch.Tensor, texel: torch.Tensor, vpt: tuple, ws: MarchRays, tex: StepTextures,
             max_distance: float) -> torch.Tensor:
    """Which of the rays judged pass (every hit ends its ray): the texel faces the ray (``dot(R, vN) < 0``) and lies
    within ``max_distance`` of the reflecting plane (``pointPlaneDistance``). Compiled: every ray, by components (a
    data-dependent selection would break the graph), ``hit`` masking the verdicts. Eager: ``hit`` holds the hit
    rays' positions and the verdicts are theirs, from rows (``(R · vN).sum(1)``, ATen's bits)."""
    if torch.compiler.is_compiling():
        nrm, n, o = tex.normal.index_select(0, texel), ws.n, ws.vp
        back = ws.refl[0] * nrm[:, 0] + ws.refl[1] * nrm[:, 1] + ws.refl[2] * nrm[:, 2] >= 0
        plane = (n[0] * vpt[0] + n[1] * vpt[1] + n[2] * vpt[2]) - (n[0] * o[0] + n[1] * o[1] + n[2] * o[2])
        return hit & ~back & ~(plane > max_distance)
    nh, vph = take_rows(ws.n, hit), take_rows(vpt, hit)
    back = (take_rows(ws.refl, hit) * tex.normal.index_select(0, texel.index_select(0, hit))).sum(1) >= 0
    plane = (nh * vph).sum(1) - (nh * take_rows(ws.vp, hit)).sum(1)                  # pointPlaneDistance
    return ~back & ~(plane > max_distance)


def _end_hits(hit: torch.Tensor, term: torch.Tensor, st: "MarchState", sample: tuple, ws: MarchRays,
              tex: StepTextures, max_distance: float) -> tuple:
    """End the ``hit`` rays: ``term`` ``HIT`` where they pass :func:`_verdict` (and their records, ``sample`` =
    ``(t, texel, (x, y), vpt)``, written), else ``MAX_DISTANCE``. Returns ``(term, hit_tex, hit_xy, hit_vp)``.
    Compiled, by ``where`` over every ray; eager, on the hit rays only, writing into ``term`` (this step's) and the
    records of ``st`` (the march's working set owns them) in place."""
    t, texel, xy, vpt = sample
    if torch.compiler.is_compiling():
        done = _verdict(hit, texel, vpt, ws, tex, max_distance)
        pick = lambda new, old: tuple(torch.where(done, a, c) for a, c in zip(new, old))   # noqa: E731
        return (torch.where(hit, torch.where(done, HIT, MAX_DISTANCE), term).to(term.dtype),
                torch.where(done, t, st.hit_tex), pick(xy, st.hit_xy), pick(vpt, st.hit_vp))
    h = flat_nonzero(hit)
    if h.numel():
        done = _verdict(h, texel, vpt, ws, tex, max_distance)
        term[h] = torch.where(done, HIT, MAX_DISTANCE).to(term.dtype)
        d = h[done]
        st.hit_tex[d] = t[d]
        for rec, val in zip(st.hit_xy + st.hit_vp, xy + vpt):
            rec[d] = val[d]
    return term, st.hit_tex, st.hit_xy, st.hit_vp


def pixel_step(i, ws: MarchRays, st: MarchState, tex: StepTextures, size: tuple[int, int], far: float,
               thickness: torch.Tensor, infinite_thick: bool, max_distance: float,
               go: Optional[torch.Tensor] = None) -> MarchState:
    """Step ``i`` of the pixel DDA for the live rays (every one where ``go``, a 0-d bool, is true); ``size`` =
    ``(H, W)``. A ray is hit when it is behind a texel that is not background and, unless ``infinite_thick``, that
    texel's view point lies within ``max(thickness, 3 × the texel's width in view units)`` of the ray's line
    (``pointToLineDistance``); a hit ends the ray, as ``HIT`` if it passes :func:`_verdict`, else
    ``MAX_DISTANCE``. ``thickness`` is a 0-d tensor of the rays' dtype: as a number, the compiled steps would be
    specialised on its value (its ``clamp`` bound), compiling again for every thickness a sweep sets."""
    H, W = size
    was = st.alive32 != 0 if go is None else (st.alive32 != 0) & go
    end = i >= ws.total
    x, y = ws.d0[0] + i * ws.span[0], ws.d0[1] + i * ws.span[1]                   # xy = d0 + i·span
    off = ~end & ((x < 0) | (x > W) | (y < 0) | (y > H))
    alive = was & ~(end | off)
    term = torch.where(was & off, OFF_SCREEN, torch.where(was & end, MAX_DISTANCE, st.term))
    steps = torch.where(was, i - 1 + (~end).int(), st.steps)
    size_t = torch.tensor([float(W), float(H)], dtype=x.dtype, device=x.device)
    u, v = x / size_t[0], y / size_t[1]                                           # uv = xy / resolution
    t = flat_texel(*gl_texel(u, v, H, W), (H, W), ws.b.dtype)                     # in the index dtype (int32: AVX2)
    texel = ws.b * (H * W) + t
    d, vz = tex.depth.index_select(0, texel), tex.view_z.index_select(0, texel)
    sky = -vz >= far                                                         # continue: s does not advance
    vpt = unproject_components(tex.minv, u, v, d, -vz)
    ray_z = 1.0 / (ws.recip + st.s * (ws.recip_end - ws.recip))
    behind = alive & ~sky & (ray_z <= vz)
    if infinite_thick:
        hit = behind
    else:
        to_start, to_end = [a - c for a, c in zip(vpt, ws.vp)], [a - c for a, c in zip(vpt, ws.d1v)]
        away = point_to_line(to_start, to_end) / ws.length                              # pointToLineDistance
        nb = unproject_components(tex.minv, (x + 1.0) / W, v, d, -vz, rows=1)[0]          # the texel to the right
        hit = behind & (away <= torch.clamp((nb - vpt[0]) * 3.0, min=thickness))
    s = st.s + torch.where(sky | hit, 0.0, ws.s_step)
    if go is not None:
        s = torch.where(go, s, st.s)
    term, hit_tex, hit_xy, hit_vp = _end_hits(hit, term, st, (t, texel, (x, y), vpt), ws, tex, max_distance)
    return MarchState((alive & ~hit).to(torch.int32), term, steps, s, hit_tex, hit_xy, hit_vp)


@kernel(dynamic=True, fuse_whole=True)
def march_steps(i0, ws: MarchRays, st: MarchState, tex: StepTextures, size: tuple[int, int], far: float,
                thickness: torch.Tensor, infinite_thick: bool, max_distance: float, count: int = 1,
                left: Optional[torch.Tensor] = None) -> MarchState:
    """Steps ``i0 … i0 + count − 1`` (:func:`pixel_step`), the ``j``-th only while ``j < left`` (a 0-d count of the
    steps the march has left; ``None``: all; :func:`~ssbench.passes.compiled.step_blocks`): the march's compilable,
    size-dynamic kernel. With ``left``, ``i0`` is a 0-d integer tensor: dynamo specialises the numbers 0 and 1, so
    the march's first call (``i0 = 1``) would compile a graph of its own."""
    for j in range(count):
        st = pixel_step(i0 + j, ws, st, tex, size, far, thickness, infinite_thick, max_distance,
                        None if left is None else left > j)
    return st
