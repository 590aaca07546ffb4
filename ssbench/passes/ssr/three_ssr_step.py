"""One step of three.js ``SSRShader``'s pixel DDA (steps 3–4 of :mod:`ssbench.passes.ssr.three_ssr`) over the
march's working set, as a size-dynamic compiled kernel (:mod:`ssbench.passes.compiled`): the sample, its texel
fetch and unprojection, the ray's perspective-correct depth and the hit test.
"""
from __future__ import annotations

from typing import NamedTuple

import torch

from ..common import cross, flat_texel, gl_texel
from ..compiled import kernel
from .common import MAX_DISTANCE, OFF_SCREEN

__all__ = ["StepTextures", "MarchRays", "StepResult", "unproject", "pixel_step"]


def unproject(minv: torch.Tensor, u: torch.Tensor, v: torch.Tensor, d: torch.Tensor, clip_w: torch.Tensor,
              rows: int = 3) -> torch.Tensor:
    """``getViewPosition``: ``(cameraInverseProjectionMatrix · ((uv, d) − ½)·2·clipW).xyz`` → ``(..., 3)`` (only
    ``x`` with ``rows=1``, ``(..., 1)``); ``minv`` the inverse projection matrix."""
    clip = ((u - 0.5) * 2.0 * clip_w, (v - 0.5) * 2.0 * clip_w, (d - 0.5) * 2.0 * clip_w, clip_w)
    return torch.stack([sum(minv[i, k] * clip[k] for k in range(4)) for i in range(rows)], -1)


class StepTextures(NamedTuple):
    """What a step reads, flat over ``B·H·W``: the GL depth (``tDepth``) and ``getViewZ`` of every texel, and the
    inverse projection matrix :math:`(4, 4)`."""

    depth: torch.Tensor
    view_z: torch.Tensor
    minv: torch.Tensor


class MarchRays(NamedTuple):
    """The working set of the pixel DDA, :math:`(N,)` or :math:`(N, k)` per field: ray ids (``ray``, into the rays
    the shader casts) and each ray's constants (batch index ``b`` in the texel index dtype, ``d0``, ``span``,
    ``totalStep``, ``1/z`` at both ends, ``viewPosition``, the far end ``d1viewPosition``, the ray's length,
    ``viewReflectDir``, ``viewNormal``, ``sStep``) and its state ``s``, all compacted together."""

    ray: torch.Tensor
    b: torch.Tensor
    d0: torch.Tensor
    span: torch.Tensor
    total: torch.Tensor
    recip: torch.Tensor
    recip_end: torch.Tensor
    vp: torch.Tensor
    d1v: torch.Tensor
    length: torch.Tensor
    refl: torch.Tensor
    n: torch.Tensor
    s_step: torch.Tensor
    s: torch.Tensor

    def take(self, keep: torch.Tensor) -> "MarchRays":
        """The rays at positions ``keep`` of this set."""
        return MarchRays(*(v.index_select(0, keep) for v in self))


class StepResult(NamedTuple):
    """One step's outcome per ray: ``alive`` (still marching: not past ``totalStep``, on screen, not hit), the
    sample ``xy`` :math:`(N, 2)`, its texel ``tex`` (in the image) and ``texel`` (flat), the texel's view point
    ``vpt`` :math:`(N, 3)`, ``hit``, and the rays' state after the step: ``term`` (``OFF_SCREEN`` /
    ``MAX_DISTANCE`` for the rays this step stopped; a hit's code is the caller's), ``steps`` and ``s`` (which
    does not advance on a background texel or a hit)."""

    alive: torch.Tensor
    xy: torch.Tensor
    tex: torch.Tensor
    texel: torch.Tensor
    vpt: torch.Tensor
    hit: torch.Tensor
    term: torch.Tensor
    steps: torch.Tensor
    s: torch.Tensor


@kernel(dynamic=True)
def pixel_step(i: int, ws: MarchRays, was: torch.Tensor, state: tuple, tex: StepTextures, size: tuple[int, int],
               far: float, thickness: float, infinite_thick: bool) -> StepResult:
    """Step ``i`` of the pixel DDA for the live rays (``was``), whose termination codes and step counts are
    ``state`` ``(term, steps)``; ``size`` = ``(H, W)``. A ray is hit when it is behind a texel that is not
    background and, unless ``infinite_thick``, that texel's view point lies within ``max(thickness, 3 × the
    texel's width in view units)`` of the ray's line (``pointToLineDistance``)."""
    H, W = size
    end = i >= ws.total
    xy = ws.d0 + i * ws.span
    off = ~end & ((xy[:, 0] < 0) | (xy[:, 0] > W) | (xy[:, 1] < 0) | (xy[:, 1] > H))
    alive = was & ~(end | off)
    term = torch.where(was & off, OFF_SCREEN, torch.where(was & end, MAX_DISTANCE, state[0]))
    steps = torch.where(was, i - 1 + (~end).int(), state[1])
    uv = xy / torch.tensor([W, H], dtype=xy.dtype, device=xy.device)
    t = flat_texel(*gl_texel(uv[:, 0], uv[:, 1], H, W), (H, W), ws.b.dtype)   # in the index dtype (int32: AVX2)
    texel = ws.b * (H * W) + t
    d, vz = tex.depth.index_select(0, texel), tex.view_z.index_select(0, texel)
    sky = -vz >= far                                                         # continue: s does not advance
    vpt = unproject(tex.minv, uv[:, 0], uv[:, 1], d, -vz)
    ray_z = 1.0 / (ws.recip + ws.s * (ws.recip_end - ws.recip))
    behind = alive & ~sky & (ray_z <= vz)
    if infinite_thick:
        hit = behind
    else:
        away = cross(vpt - ws.vp, vpt - ws.d1v, dim=1).norm(dim=1) / ws.length   # pointToLineDistance
        nb = unproject(tex.minv, (xy[:, 0] + 1.0) / W, uv[:, 1], d, -vz, rows=1)           # the texel to the right
        hit = behind & (away <= torch.clamp((nb[:, 0] - vpt[:, 0]) * 3.0, min=thickness))
    s = ws.s + torch.where(sky | hit, 0.0, ws.s_step)
    return StepResult(alive & ~hit, xy, t, texel, vpt, hit, term, steps, s)
