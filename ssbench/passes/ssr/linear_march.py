"""The linear march's inner loops (SSR article §1.2–1.3), on flat per-ray tensors: the depth test of a
view-space sample (:class:`DepthTest`), the equal-step march that stops rays as they hit or leave the screen
(:func:`march`), and the bisection of the last step (:func:`refine`). :func:`ssbench.passes.ssr.linear.ssr_linear`
builds the rays (§1.1), calls these, and assembles the images (§1.4–1.5); :class:`MarchLog` holds the debug
buffers (visit counts, one pixel's samples) only when they are asked for."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import torch

from ...camera import Camera
from ..common import uv_to_texel
from .common import BEHIND_CAMERA, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS

__all__ = ["DepthTest", "MarchLog", "MarchOutcome", "march", "refine"]


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

    def intersects(self, z: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """``dist = z − sceneZMax``; hit iff ``−Thickness < dist < 0`` (or, with back faces, ``back − Thickness
        < z < sceneZ``). A cleared background texel is never hit (three.js ``SSRShader``: ``if (-vZ >= cameraFar)
        continue``)."""
        dist = z - self.scene_z.index_select(0, t)
        m = self.mask.index_select(0, t)
        if self.back is None:
            return (dist < 0) & (dist > -self.thickness) & m
        return (dist < 0) & (z > self.back.index_select(0, t) - self.thickness) & m


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
            self.trace[b] += [(q[s], bool(hit[s]), refine) for s in (ids == k).nonzero().squeeze(1).tolist()]


@dataclass(frozen=True)
class MarchOutcome:
    """Per ray: termination code, samples taken, the step index of the hit (−1: none) and the hit sample."""

    term: torch.Tensor
    steps: torch.Tensor
    hit_step: torch.Tensor
    hit_q: torch.Tensor


def march(test: DepthTest, log: MarchLog, Q: torch.Tensor, dS: torch.Tensor, base: torch.Tensor,
          clipped: torch.Tensor, iterations: int, max_iterations: int) -> MarchOutcome:
    """§1.2: ``Q += deltaStep`` up to ``Iterations`` times (at most ``max_iterations``, the shader's bound); a ray
    stops at its first hit or when its sample leaves [0, 1]² (``OFF_SCREEN``), else ends ``MAX_DISTANCE`` /
    ``BEHIND_CAMERA`` (near-plane ``clipped``) or ``OUT_OF_STEPS``. Only live rays are updated (compacted as
    they stop)."""
    n, dev = Q.shape[0], Q.device
    term, steps = torch.full((n,), NO_RAY, dtype=torch.int8, device=dev), torch.zeros(n, dtype=torch.int32, device=dev)
    hit_i, hitQ = torch.full((n,), -1, device=dev), torch.zeros(n, 3, dtype=Q.dtype, device=dev)
    ids, Qa, dSa, basea = torch.arange(n, device=dev), Q, dS, base
    n_run = min(iterations, max_iterations)
    for i in range(n_run):
        if ids.numel() == 0:
            break
        Qa = Qa + dSa                                                             # Q += deltaStep
        uv, t = test.project(Qa, basea)
        on = ((uv >= 0) & (uv <= 1)).all(1)
        hit = on & test.intersects(Qa[:, 2], t)
        if log.trace_ids:
            log.record(ids, Qa, hit, False)
        if log.counting:
            log.read(t[on])
        gone = (hit | ~on).nonzero().squeeze(1)                                   # rays that stop here
        if gone.numel():
            g_hit = hit.index_select(0, gone)
            g_ids = ids.index_select(0, gone)
            steps[g_ids] = i + 1                                                  # samples taken, this one too
            term[g_ids] = torch.where(g_hit, HIT, OFF_SCREEN).to(torch.int8)
            h_ray = gone[g_hit]
            hit_i[ids[h_ray]], hitQ[ids[h_ray]] = i, Qa[h_ray]
            keep = (on & ~hit).nonzero().squeeze(1)
            ids, Qa, dSa, basea = (x.index_select(0, keep) for x in (ids, Qa, dSa, basea))
    steps[ids] = n_run                                                            # live to the loop's end
    end = torch.where(clipped[ids], BEHIND_CAMERA, MAX_DISTANCE)                  # reached the end point
    term[ids] = (end if n_run == iterations else torch.full_like(end, OUT_OF_STEPS)).to(torch.int8)
    return MarchOutcome(term, steps, hit_i, hitQ)


def refine(test: DepthTest, log: MarchLog, h: torch.Tensor, O: torch.Tensor, dS: torch.Tensor,
           base: torch.Tensor, best: torch.Tensor, hit_step: torch.Tensor, iterations: int) -> torch.Tensor:
    """§1.3 on the hit rays ``h``: bisect the last step (from ``rayOrg`` when the first step hit) with strides
    ½, ¼, … forward after a miss and back after a hit; returns the last probe that hit (``best`` if none did)."""
    first = (hit_step == 0).unsqueeze(1)
    Qb = torch.where(first, O, best - dS)                                         # Q −= deltaStep (≥ rayOrg)
    step = torch.where(first, best - O, dS)
    originalStride = 0.5
    stride = torch.full((h.numel(), 1), originalStride, dtype=best.dtype, device=best.device)   # (m, 1)
    for _ in range(iterations):
        Qb = Qb + step * stride
        uv, t = test.project(Qb, base)
        hb = test.intersects(Qb[:, 2], t)
        if log.trace_ids:
            log.record(h, Qb, hb, True)
        log.read(t)
        best = torch.where(hb.unsqueeze(1), Qb, best)
        originalStride *= 0.5
        stride = torch.where(hb, -originalStride, originalStride).unsqueeze(1).to(best.dtype)
    return best
