"""Steps 1–2 of three.js ``SSRShader`` (:mod:`.three_ssr`) for any set of rays: ``viewPosition``, the reflected
direction, the far end ``d1viewPosition`` (pulled back to the near plane) and the pixel DDA's ``d0``, ``span``,
``totalStep``, ``sStep`` and perspective-correct ``1/z`` ends. Per ray, so a subset of the rays gets exactly the
values of the full set-up: the pass sets up and marches its rays a chunk at a time, and sets up its hit rays again
for their opacity.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import torch

from ...camera import Camera
from .three_ssr_step import unproject

__all__ = ["Shading", "ThreeRays"]


class ThreeRays(NamedTuple):
    """The shader's per-ray set-up, each :math:`(m,)` or :math:`(m, C)`: ``d0`` (``gl_FragCoord.xy``), ``vp``
    (``viewPosition``), ``n`` (``viewNormal``), ``inc`` (``viewIncidentDir``), ``refl`` (``viewReflectDir``),
    ``d1v`` (``d1viewPosition``), ``span`` (per step), ``total`` (``totalStep``), ``s_step`` (``sStep``) and
    ``recip``, ``recip_end`` (``1/z`` at ``d0`` and ``d1``)."""

    d0: torch.Tensor
    vp: torch.Tensor
    n: torch.Tensor
    inc: torch.Tensor
    refl: torch.Tensor
    d1v: torch.Tensor
    span: torch.Tensor
    total: torch.Tensor
    s_step: torch.Tensor
    recip: torch.Tensor
    recip_end: torch.Tensor


@dataclass(frozen=True)
class Shading:
    """What the set-up reads: the camera, ``max_distance``, the image ``size = (H, W)``, and flat per batch item
    ``depth`` (``tDepth``) and ``vz_tex`` (its view z), :math:`(B, H·W)`, and ``normal``, :math:`(B, H·W, 3)`."""

    camera: Camera
    max_distance: float
    size: tuple
    depth: torch.Tensor
    vz_tex: torch.Tensor
    normal: torch.Tensor

    @property
    def minv(self) -> torch.Tensor:
        """The inverse projection matrix (``cameraInverseProjectionMatrix``) in the depth's dtype and device."""
        return self.camera.inverse_projection_matrix(dtype=self.depth.dtype, device=self.depth.device)

    def rays(self, b: torch.Tensor, k: torch.Tensor) -> ThreeRays:
        """The set-up of the rays of pixels ``k`` (flat ``j·W + i``) in batch items ``b``, both :math:`(m,)`."""
        cam, (H, W), dt, dev = self.camera, self.size, self.depth.dtype, self.depth.device
        row, col = k // W, k % W
        d0 = torch.stack([col.to(dt) + 0.5, (H - 1 - row).to(dt) + 0.5], -1)      # gl_FragCoord.xy
        vuv = d0 / torch.tensor([W, H], dtype=dt, device=dev)
        vp = unproject(self.minv, vuv[:, 0], vuv[:, 1], self.depth[b, k], -self.vz_tex[b, k])   # viewPosition
        n = self.normal[b, k]
        inc = vp / vp.norm(dim=1, keepdim=True)                                  # viewIncidentDir
        refl = inc - 2.0 * (n * inc).sum(1, keepdim=True) * n                     # reflect(I, N)
        d1v = vp + refl * (self.max_distance / (-inc * n).sum(1, keepdim=True))
        cross_near = d1v[:, 2] > -cam.near
        t = (-cam.near - vp[:, 2]) / refl[:, 2]
        d1v = torch.where(cross_near[:, None], vp + refl * t[:, None], d1v)
        ndc = cam.view_to_ndc(d1v, dim=-1)[:, :2]
        d1 = (ndc + 1.0) / 2.0 * torch.tensor([W, H], dtype=dt, device=dev)     # viewPositionToXY
        span = d1 - d0
        total = span.abs().amax(1)                                               # totalStep
        return ThreeRays(d0, vp, n, inc, refl, d1v, span / total[:, None], total, 1.0 / total, 1.0 / vp[:, 2],
                         1.0 / d1v[:, 2])
