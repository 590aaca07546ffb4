"""The linear march's inner loops (SSR article §1.2–1.3), on flat per-ray tensors: the depth test of a
view-space sample (:class:`DepthTest`), the equal-step march that stops rays as they hit or leave the screen
(:func:`march`), and the bisection of the last step (:func:`refine`). :func:`ssbench.passes.ssr.linear.ssr_linear`
builds the rays (§1.1), calls these, and assembles the images (§1.4–1.5); :class:`MarchLog` holds the debug
buffers (visit counts, one pixel's samples) only when they are asked for."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Optional

import torch

from ...camera import Camera
from ...indices import flat_nonzero
from ...layout import stack_columns
from ..common import index_dtype, texel_of, uv_to_texel
from ..compiled import kernel, step_blocks
from ..float_masks import float_flags
from .dda_state import select_rows
from .linear_float_step import float_march_step
from .common import (HIT, NO_RAY, OFF_SCREEN, OUT_OF_STEPS, compact_now, components, end_code, nan_off_mask)

__all__ = ["DepthTest", "MarchLog", "MarchOutcome", "LiveRays", "march_step", "march_steps", "march", "refine_step",
           "refine_steps", "refine"]


@dataclass(frozen=True)
class DepthTest:
    """§1.2's depth lookup: project a sample to its ``NEAREST`` texel and test ``rayIntersectsDepth``.

    Attributes:
        camera: the G-buffer's camera; ``H``, ``W`` its size.
        scene_z, back, mask: flat :math:`(B·H·W,)` depth-buffer view z, back-face view z (``None``: the constant
            ``thickness`` model) and mask.
        thickness: the article's ``Thickness``.
    """

    camera: Camera
    H: int
    W: int
    scene_z: torch.Tensor
    back: Optional[torch.Tensor]
    mask: torch.Tensor
    thickness: float

    def project(self, q: torch.Tensor, base: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(uv, texel)``: ``clip = P·(Q, 1)``, ``hitPixel = clip.xy / clip.w · 0.5 + 0.5`` (v up), and the flat
        index of its ``NEAREST``, ``CLAMP_TO_EDGE`` texel (``base``: each ray's batch offset)."""
        cam = self.camera
        uv = cam.ndc_to_uv(cam.view_to_ndc(q, dim=-1)[:, :2])                     # (m, 2) uv, v up
        col, row = uv_to_texel(uv, self.H, self.W, dim=1)
        return uv, base + row * self.W + col

    @cached_property
    def front(self) -> torch.Tensor:
        """``scene_z`` with NaN off the mask (built once, for the march and the bisection): with it,
        ``dist = z − front`` tests hit and mask in one read."""
        return nan_off_mask(self.scene_z, self.mask)


@dataclass
class MarchLog:
    """Debug buffers filled while marching: ``visits`` :math:`(B·H·W,)` int64 reads per texel (empty when not
    ``counting``) and the samples of the traced rays (``trace_ids``: batch → ray index)."""

    counting: bool
    visits: torch.Tensor
    trace_ids: dict = field(default_factory=dict)
    trace: dict = field(default_factory=dict)

    def read(self, t: torch.Tensor) -> None:
        """Count one read of each texel in ``t`` (an O(B·H·W) pass: only when counting)."""
        if self.counting:
            self.visits += torch.bincount(t, minlength=self.visits.numel())

    def record(self, ids: torch.Tensor, q: torch.Tensor, hit: torch.Tensor, refine: bool) -> None:
        """Append the traced rays' samples among ``ids`` (``(Q, hit, refine)``)."""
        for b, k in self.trace_ids.items():
            self.trace[b] += [(q[s], bool(hit[s]), refine) for s in flat_nonzero(ids == k).tolist()]


@dataclass(frozen=True)
class MarchOutcome:
    """Per ray: termination code, samples taken, the step index of the hit (−1: none) and the hit sample."""

    term: torch.Tensor
    steps: torch.Tensor
    hit_step: torch.Tensor
    hit_q: torch.Tensor


@dataclass(frozen=True)
class LiveRays:
    """The march's working set: ``ids`` (into the rays), each ray's sample ``Q`` and ``deltaStep`` as x, y, z
    apart (flat arrays, so a compiled step runs vectorised), its batch offset ``base`` (in the index dtype) and
    its state, all int32 (a compiled step loads and stores bool arrays lane by lane): ``live`` (1: still marching),
    ``hit`` (1: stopped on a hit; ``Q`` stays at the hit sample) and ``steps`` (samples taken). Eagerly, ``base`` and
    the state are in the samples' dtype instead (:func:`~ssbench.passes.float_masks.float_flags`). Stopped rays ride
    along, masked, until a quarter of the set has stopped."""

    ids: torch.Tensor
    qx: torch.Tensor
    qy: torch.Tensor
    qz: torch.Tensor
    dx: torch.Tensor
    dy: torch.Tensor
    dz: torch.Tensor
    base: torch.Tensor
    live: torch.Tensor
    hit: torch.Tensor
    steps: torch.Tensor


def _probe(scale: tuple, size: tuple, thickness: float, front: torch.Tensor, back: Optional[torch.Tensor],
           q: tuple, base: torch.Tensor) -> tuple:
    """``(u, v, t, hit)`` of view samples ``q`` (x, y, z apart): :meth:`DepthTest.project`'s texel (its uv in two
    passes, :meth:`~ssbench.camera.Camera.scaled_uv_xy`), then
    ``rayIntersectsDepth`` against ``front`` (the scene z, NaN off the mask, so a cleared texel is never hit)."""
    x, y, z = q
    u, v = Camera.scaled_uv_xy(x, y, z, scale)                                    # hitPixel (uv, v up)
    col, row = texel_of(u, v, size[0], size[1], dtype=base.dtype)
    t = base + torch.add(col, row, alpha=size[1])                                 # base + row·W + col (integers)
    dist = z - front.index_select(0, t)                                           # dist = Q.z − sceneZMax
    if back is None:
        return u, v, t, (dist < 0) & (dist > -thickness)
    return u, v, t, (dist < 0) & (z > back.index_select(0, t) - thickness)


def march_step(scale: tuple, size: tuple, thickness: float, front: torch.Tensor, back: Optional[torch.Tensor],
               rays: tuple, go: Optional[torch.Tensor] = None) -> tuple:
    """One step of §1.2 for every ray of a working set: ``Q += deltaStep``, project (:meth:`DepthTest.project`, op
    for op), read ``front`` (the scene z, NaN off the mask: a cleared texel is never hit) and test
    ``rayIntersectsDepth``; a live ray stops on a hit or off screen. Rays that stopped earlier keep their state, and
    so does every ray where ``go`` (a 0-d bool) is false.

    Args:
        scale: the camera's :meth:`~ssbench.camera.Camera.ndc_scale`; size: ``(H, W)``.
        rays: ``(qx, qy, qz, dx, dy, dz, base, live, hit, steps)`` of :class:`LiveRays`, each :math:`(m,)`.

    Returns:
        ``(rays, t, on, h)``: the rays with their new ``(qx, qy, qz, live, hit, steps)``, the texel index, the
        on-screen test and this step's hits.
    """
    qx, qy, qz, dx, dy, dz, base, live, hit, steps = rays
    if live.is_floating_point():                 # eager 0/1 float flags (march, float_flags): the same bits
        return float_march_step(scale, size, thickness, front, back, rays)
    x, y, z = qx + dx, qy + dy, qz + dz                                           # Q += deltaStep
    u, v, t, h = _probe(scale, size, thickness, front, back, (x, y, z), base)
    on = (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1)
    h = on & h
    act = live if go is None else torch.where(go, live, 0)                       # marching this step: 1
    marching = act != 0
    stop = marching & (h | ~on)
    steps = steps + act                                                           # this sample counts too
    hit = torch.where(stop & h, 1, hit)
    qx, qy, qz = torch.where(marching, x, qx), torch.where(marching, y, qy), torch.where(marching, z, qz)
    live = torch.where(stop, 0, live)
    return (qx, qy, qz, dx, dy, dz, base, live, hit, steps), t, on, h


@kernel(dynamic=True, fuse_whole=True)
def march_steps(scale: tuple, size: tuple, thickness: float, front: torch.Tensor, back: Optional[torch.Tensor],
                rays: tuple, count: int = 1, left: Optional[torch.Tensor] = None, debug: bool = False) -> tuple:
    """``count`` :func:`march_step` s, the ``j``-th only while ``j < left`` (a 0-d count of the steps the march has
    left; ``None``: all; :func:`~ssbench.passes.compiled.step_blocks`): the march's compilable, size-dynamic kernel.

    Returns:
        ``(qx, qy, qz, live, hit, steps, n_live)`` (``n_live`` a 0-d count), plus the texel index, the on-screen
        test and this step's hits with ``debug`` (``count`` 1).
    """
    for j in range(count):
        rays, t, on, h = march_step(scale, size, thickness, front, back, rays, None if left is None else left > j)
    qx, qy, qz, _, _, _, _, live, hit, steps = rays
    return (qx, qy, qz, live, hit, steps, live.sum()) + ((t, on, h) if debug else ())


def march(test: DepthTest, log: MarchLog, Q: torch.Tensor, dS: torch.Tensor, base: torch.Tensor,
          clipped: torch.Tensor, iterations: int, max_iterations: int) -> MarchOutcome:
    """§1.2: ``Q += deltaStep`` up to ``Iterations`` times (at most ``max_iterations``, the shader's bound); a ray
    stops at its first hit or when its sample leaves [0, 1]² (``OFF_SCREEN``), else ends ``MAX_DISTANCE`` /
    ``BEHIND_CAMERA`` (near-plane ``clipped``) or ``OUT_OF_STEPS``. Each step is :func:`march_step` over a
    :class:`LiveRays` working set, compacted once a quarter of it has stopped."""
    n, dev = Q.shape[0], Q.device
    out = _Outcome(torch.full((n,), NO_RAY, dtype=torch.int8, device=dev), torch.zeros(n, dtype=torch.int32, device=dev),
                   torch.full((n,), -1, device=dev), torch.zeros(n, 3, dtype=Q.dtype, device=dev))
    front = test.front
    floats = float_flags(Q, front.numel())                                       # eager: 0/1 float flags
    flags = torch.zeros(n, dtype=Q.dtype if floats else torch.int32, device=dev)  # live, hit, steps (else int32)
    ws = LiveRays(torch.arange(n, device=dev), *components(Q), *components(dS),
                  base.to(Q.dtype if floats else index_dtype(front.numel())), flags + 1, flags, flags.clone())
    scale, debug = test.camera.ndc_scale(), bool(log.trace_ids) or log.counting
    n_run = min(iterations, max_iterations)
    for count, left in step_blocks(n_run, debug, dev):
        m = ws.ids.numel()
        if m == 0:
            break
        r = march_steps(scale, (test.H, test.W), test.thickness, front, test.back, (ws.qx, ws.qy, ws.qz, ws.dx, ws.dy,
                        ws.dz, ws.base, ws.live, ws.hit, ws.steps), count, left, debug=debug)
        was = ws.live != 0 if debug else None                                     # (a pass over the set)
        ws = LiveRays(ws.ids, *r[:3], ws.dx, ws.dy, ws.dz, ws.base, *r[3:6])
        if debug:
            t, on, h = r[7:]
            marched = flat_nonzero(was)
            if log.trace_ids:
                log.record(ws.ids[marched], stack_columns([ws.qx, ws.qy, ws.qz])[marched], h[marched], False)
            log.read(t[was & (on != 0)].long())
        n_live = int(r[6])
        if compact_now(n_live, m):
            out.flush(ws, flat_nonzero(ws.live == 0))
            ws = select_rows(ws, flat_nonzero(ws.live))
    out.flush(ws, flat_nonzero(ws.live == 0))
    ids = ws.ids.index_select(0, flat_nonzero(ws.live))
    out.steps.index_fill_(0, ids, n_run)                                          # live to the loop's end
    end = end_code(clipped.index_select(0, ids))                                 # reached the end point
    out.term.index_copy_(0, ids, (end if n_run == iterations else torch.full_like(end, OUT_OF_STEPS)).to(torch.int8))
    return MarchOutcome(out.term, out.steps, out.hit_step, out.hit_q)


@dataclass(frozen=True)
class _Outcome:
    """:class:`MarchOutcome`'s arrays while :func:`march` fills them."""

    term: torch.Tensor
    steps: torch.Tensor
    hit_step: torch.Tensor
    hit_q: torch.Tensor

    def flush(self, ws: LiveRays, stopped: torch.Tensor) -> None:
        """Write the results of the stopped rays at positions ``stopped`` of ``ws``."""
        g, h = ws.ids.index_select(0, stopped), ws.hit.index_select(0, stopped) != 0
        steps = ws.steps.index_select(0, stopped)
        self.steps.index_copy_(0, g, steps.to(self.steps.dtype))
        self.term.index_copy_(0, g, torch.where(h, HIT, OFF_SCREEN).to(torch.int8))
        hi = flat_nonzero(h)
        gh, at = g.index_select(0, hi), stopped.index_select(0, hi)
        self.hit_step.index_copy_(0, gh, steps.index_select(0, hi).long() - 1)   # the step index of the hit
        self.hit_q.index_copy_(0, gh, stack_columns([c.index_select(0, at) for c in (ws.qx, ws.qy, ws.qz)]))


def refine_step(scale: tuple, size: tuple, thickness: float, front: torch.Tensor, back: Optional[torch.Tensor],
                probe: tuple, base: torch.Tensor, go: Optional[torch.Tensor] = None) -> tuple:
    """One probe of §1.3 on flat :math:`(m,)` arrays ``probe = (qx, qy, qz, sx, sy, sz, stride, bx, by, bz)``
    (``Qb``, the step, the signed stride and ``best``, x, y, z apart): ``Qb += step·stride``, the depth test (no
    screen test, as the shader), ``best = Qb`` where it hit, and the next stride, half as long (a power of two:
    exact), back after a hit and forward after a miss. Every ray keeps its state where ``go`` (a 0-d bool) is false.

    Returns:
        ``(probe, t, hit)``: the new probe state, the texel index and the hits.
    """
    qx, qy, qz, sx, sy, sz, stride, bx, by, bz = probe
    x, y, z = qx + sx * stride, qy + sy * stride, qz + sz * stride
    _, _, t, hb = _probe(scale, size, thickness, front, back, (x, y, z), base)
    half = stride.abs() * 0.5
    nxt = torch.where(hb, -half, half)
    take = hb if go is None else hb & go
    bx, by, bz = torch.where(take, x, bx), torch.where(take, y, by), torch.where(take, z, bz)
    if go is not None:
        x, y, z = torch.where(go, x, qx), torch.where(go, y, qy), torch.where(go, z, qz)
        nxt = torch.where(go, nxt, stride)
    return (x, y, z, sx, sy, sz, nxt, bx, by, bz), t, hb


@kernel(dynamic=True, fuse_whole=True)
def refine_steps(scale: tuple, size: tuple, thickness: float, front: torch.Tensor, back: Optional[torch.Tensor],
                 probe: tuple, base: torch.Tensor, count: int = 1, left: Optional[torch.Tensor] = None,
                 debug: bool = False) -> tuple:
    """``count`` :func:`refine_step` s, the ``j``-th only while ``j < left``
    (:func:`~ssbench.passes.compiled.step_blocks`): the bisection's compilable, size-dynamic kernel (one call runs
    a block of probes, the rays' state in registers between them).

    Returns:
        ``(qx, qy, qz, stride, bx, by, bz)``, plus the texel index and the hits with ``debug`` (``count`` 1).
    """
    for j in range(count):
        probe, t, hb = refine_step(scale, size, thickness, front, back, probe, base, None if left is None else left > j)
    qx, qy, qz, _, _, _, stride, bx, by, bz = probe
    return (qx, qy, qz, stride, bx, by, bz) + ((t, hb) if debug else ())


def refine(test: DepthTest, log: MarchLog, h: torch.Tensor, O: torch.Tensor, dS: torch.Tensor,
           base: torch.Tensor, best: torch.Tensor, hit_step: torch.Tensor, iterations: int) -> torch.Tensor:
    """§1.3 on the hit rays ``h``: bisect the last step (from ``rayOrg`` when the first step hit) with strides
    ½, ¼, … forward after a miss and back after a hit; returns the last probe that hit (``best`` if none did)."""
    first = (hit_step == 0).unsqueeze(1)
    Qb = torch.where(first, O, best - dS)                                         # Q −= deltaStep (≥ rayOrg)
    step = torch.where(first, best - O, dS)
    originalStride = 0.5
    stride = torch.full((h.numel(),), originalStride, dtype=best.dtype, device=best.device)
    front, debug = test.front, bool(log.trace_ids) or log.counting
    base = base.to(index_dtype(front.numel()))
    q, best_c, step_c = components(Qb), components(best), components(step)
    for count, left in step_blocks(iterations, debug, best.device):
        r = refine_steps(test.camera.ndc_scale(), (test.H, test.W), test.thickness, front, test.back,
                         (*q, *step_c, stride, *best_c), base, count, left, debug=debug)
        q, stride, best_c = r[0:3], r[3], r[4:7]
        if debug:
            if log.trace_ids:
                log.record(h, stack_columns(q), r[8], True)
            log.read(r[7].long())
    return stack_columns(best_c)
