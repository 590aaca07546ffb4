"""The DDA's rays (SSR article §2.2 up to the loop; McGuire & Mara 2014): which pixels start one, the mirror ray
clipped at the near plane, both ends projected to pixels by :func:`project_to_pixel_matrix`, the major axis and
``permute``, the per-stride increments of ``P``, ``Q`` and ``k``, the stride and the jitter, and where the segment
leaves the viewport — flat over the rays, in the permuted frame (:class:`~.dda_state.DDARays`). Used by
:func:`ssbench.passes.ssr.dda.ssr_dda`, the supercover DDA, the visit maps and the teaching twins, so all of them
march the same rays."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Optional

import torch

from ...camera import Camera
from ...gbuffer import GBuffer
from ...indices import flat_nonzero
from ...layout import contiguous, stack_columns
from ..compiled import kernel
from .common import crosses_near_plane, ray_segments, ray_view_z
from .dda_state import DDARays

if TYPE_CHECKING:                                        # (ssr_dda imports this module)
    from .dda import DDASSRParams

__all__ = ["project_to_pixel_matrix", "ray_pixels", "ray_constants", "dda_rays"]


def project_to_pixel_matrix(camera: Camera, dtype=torch.float64, device=None) -> torch.Tensor:
    """G3D's ``projectToPixelMatrix``: ``gluPerspective`` then NDC → pixels, so ``H.xy / H.w = view_to_pixel``."""
    W, H = camera.width, camera.height                  # NOTE: the row flip, py = (0.5 − 0.5·ndc.y)·H
    S = torch.tensor([[W / 2, 0, 0, W / 2], [0, -H / 2, 0, H / 2], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=torch.float64)
    return (S @ camera.projection_matrix()).to(dtype=dtype, device=device)


def ray_pixels(gbuffer: GBuffer) -> torch.Tensor:
    """:math:`(N,)` flat indices ``b·H·W + j·W + i`` of the pixels that start a ray: ``mask`` pixels not nearer
    than the near plane (such geometry cannot be in a depth buffer; its rays would start behind w = 0)."""
    return flat_nonzero((gbuffer.mask & (gbuffer.view_z <= -gbuffer.camera.near))[:, 0].reshape(-1))


@kernel(dynamic=True)
def ray_constants(cam: Camera, M: torch.Tensor, o: torch.Tensor, dz: torch.Tensor, end: torch.Tensor,
                  j: torch.Tensor, *, max_ray_distance: float, pixel_stride: float, pixel_stride_z_cutoff: float,
                  fit_steps: Optional[int]) -> tuple:
    """The per-ray constants of :func:`dda_rays` (article §2.2 up to the loop) from the clipped segments ``o``,
    ``end`` :math:`(3, N)` (rows x, y, z), the directions' z ``dz`` :math:`(N,)`, the pixel matrix ``M``
    (:func:`project_to_pixel_matrix`) and each ray's jitter ``j`` :math:`(N,)` in strides: ``(fields, P0, P1)``,
    the :class:`~.dda_state.DDARays` fields but ``i`` and ``b`` by name, and the segment's ends in pixels
    :math:`(N, 2)`. ``fit_steps`` is ``max_steps`` with ``fit_stride_to_steps``, else None.

    A compilable, size-dynamic kernel (:mod:`ssbench.passes.compiled`) of exact operations: the same bits as eager.
    The settings come as numbers, not the parameter set, so that one compilation serves a sweep; none of them fills
    a tensor (compiled with dynamic numbers, such a float keeps its first value; ``compiled.py``)."""
    hom = lambda c: [c[0] * M[r, 0] + c[1] * M[r, 1] + c[2] * M[r, 2] + M[r, 3] for r in range(4)]  # noqa: E731
    H0, H1 = hom(o), hom(end)                                                     # M·(c, 1), four rows
    k0, k1 = 1.0 / H0[3], 1.0 / H1[3]
    Q0, Q1 = [c * k0 for c in o], [c * k1 for c in end]
    P0, P1 = [c * k0 for c in H0[:2]], [c * k1 for c in H1[:2]]                   # pixels (py down)
    nudge = torch.where((P1[0] - P0[0]) ** 2 + (P1[1] - P0[1]) ** 2 < 0.0001, 0.01, 0.0)   # degenerate line
    P1 = [c + nudge for c in P1]
    delta = [P1[0] - P0[0], P1[1] - P0[1]]
    permute = delta[0].abs() < delta[1].abs()                                     # more-vertical line
    sw = lambda v: (torch.where(permute, v[1], v[0]), torch.where(permute, v[0], v[1]))   # noqa: E731  (.yx)
    delta, P0p, P1p = sw(delta), sw(P0), sw(P1)
    stepDir = torch.sign(delta[0])
    invdx = stepDir / delta[0]
    dQ, dk = [(a - c) * invdx for a, c in zip(Q1, Q0)], (k1 - k0) * invdx
    slope = delta[1] * invdx                                                      # minor px per unit of u
    dP = [stepDir, slope]
    # where the segment leaves the viewport, as a signed major coordinate u = P.x·stepDir (permuted frame)
    Wm, Hm = sw((float(cam.width), float(cam.height)))          # (sizes are ints: safe to fill, unlike floats)
    u0, y0 = P0p[0] * stepDir, P0p[1]
    exit_ = torch.minimum(torch.where(stepDir > 0, Wm, 0.0) * stepDir,
                          torch.where(slope > 0, u0 + (Hm - y0) / slope,
                                      torch.where(slope < 0, u0 - y0 / slope, math.inf)))
    strideScalar = 1.0 - torch.clamp(-o[2] / pixel_stride_z_cutoff, max=1.0)
    pixelStride = 1.0 + strideScalar * (pixel_stride - 1.0)
    if fit_steps is not None:                                                     # max_steps samples reach P1
        pixelStride = torch.maximum(pixelStride, torch.ceil(delta[0].abs() / fit_steps))
    dP, dQ, dk = [c * pixelStride for c in dP], [c * pixelStride for c in dQ], dk * pixelStride
    P0p, Q0, k0 = [a + c * j for a, c in zip(P0p, dP)], [a + c * j for a, c in zip(Q0, dQ)], k0 + dk * j
    zlo, zhi = torch.minimum(o[2], end[2]), torch.maximum(o[2], end[2])
    end_u = P1p[0] * stepDir
    fields = dict(Px=P0p[0], Py=P0p[1], Qz=Q0[2], k=k0, n=torch.zeros_like(k0), dPx=dP[0], dPy=dP[1], dQz=dQ[2],
                  dk=dk, stride=pixelStride, Q0x=Q0[0], Q0y=Q0[1], dQx=dQ[0], dQy=dQ[1], end=end_u,
                  stop=torch.minimum(end_u, exit_),                               # P1 or the viewport edge
                  stepDir=stepDir, permute=permute, zlo=zlo, zhi=zhi,
                  prevZ=ray_view_z(Q0[2] + 0.5 * dQ[2], k0 + 0.5 * dk, zlo, zhi),  # footprint edge of sample 1
                  clipped=crosses_near_plane(o[2], dz, max_ray_distance, cam.near))
    return fields, stack_columns(P0), stack_columns(P1)


def dda_rays(gbuffer: GBuffer, params: "DDASSRParams", jitter: torch.Tensor, sel: Optional[torch.Tensor] = None):
    """Per-ray set-up (article §2.2 up to the loop) of the pixels ``sel`` (default :func:`ray_pixels`, every
    pixel that starts a ray): ``(DDARays, sel, P0, P1)``, ``sel`` the rays' flat pixel indices
    ``b·H·W + j·W + i`` and ``P0``, ``P1`` their end points in pixels. Per ray, so a subset of ``sel`` sets up
    exactly those rays of the full set-up (the marchers set up and march chunks of rays).

    The mirror rays and their near-plane clip are the shared eager :func:`~.common.ray_segments`; the rest is the
    compilable :func:`ray_constants`."""
    cam, vz = gbuffer.camera, gbuffer.view_z
    dt, dev = vz.dtype, vz.device
    sel = ray_pixels(gbuffer) if sel is None else sel
    b, _, o, d, end = ray_segments(gbuffer, sel, params.max_ray_distance)          # rayOrg, rayDir, rayEnd
    rows = lambda x: contiguous(x.T)                    # noqa: E731  (a row per component: (N, 3)'s are strided)
    j = jitter.to(device=dev).reshape(-1).index_select(0, sel).to(dt)           # (this chunk's rays only)
    fields, P0, P1 = ray_constants(
        cam, project_to_pixel_matrix(cam, dt, dev), rows(o), d[:, 2], rows(end), j,
        max_ray_distance=float(params.max_ray_distance), pixel_stride=float(params.pixel_stride),
        pixel_stride_z_cutoff=float(params.pixel_stride_z_cutoff),
        fit_steps=params.max_steps if params.fit_stride_to_steps else None)
    return DDARays(i=torch.arange(sel.numel(), device=dev), b=b, **fields), sel, P0, P1
