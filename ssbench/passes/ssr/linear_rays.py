"""The linear march's rays (SSR article §1.1–1.2): ``rayOrg`` and the depth-buffer z as ``position_from`` says,
``rayDir = reflect(normalize(rayOrg), N)``, the end point clipped at the near plane, ``Iterations`` equal steps
and the optional jitter — flattened to the rays that are marched (:class:`LinearRays`). Used by
:func:`ssbench.passes.ssr.linear.ssr_linear`, its teaching twin and the Dr.Jit anchor
(:mod:`ssbench.bench.anchors`), so all three march the same rays."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

import torch

from ...checks import finite_vectors
from ...gbuffer import GBuffer
from ..common import make_generator
from .common import channel_rows, clip_ray_length, reflection_rays, split_rays
from .linear_march import DepthTest

if TYPE_CHECKING:                                        # (ssr_linear imports this module)
    from .linear import LinearSSRParams

__all__ = ["LinearRays", "linear_rays", "jitter_noise"]


def jitter_noise(params: "LinearSSRParams", generator: Optional[torch.Generator], shape) -> Optional[torch.Tensor]:
    """:math:`(B, 1, H, W)` float64 ``ξ ~ U[0, 1)`` (one ``torch.rand``; the teaching twin draws it too), or None."""
    if params.jitter == 0:
        return None
    return torch.rand(shape, generator=make_generator(params.seed, generator), dtype=torch.float64)


@dataclass(frozen=True)
class LinearRays:
    """The rays :func:`ssr_linear` marches, after §1.1–1.2, flat over the ``n`` pixels that start one (a pixel
    with geometry in front of the near plane whose origin and step are finite numbers).

    Attributes:
        ray: :math:`(n,)` flat pixel index ``b·H·W + row·W + col``; ``base`` :math:`(n,)` its ``b·H·W``.
        origin, delta, start: :math:`(n, 3)` ``rayOrg``, ``deltaStep`` and the sample before the first
            (``rayOrg``, moved back by ``jitter·ξ·deltaStep`` when jittered): transposed views of contiguous
            :math:`(3, n)` channel rows (``.T`` gives the rows; a gather of ``(B·H·W, 3)`` pixel rows and its
            transpose cost 12 of the set-up's 27 ms at 640×360).
        clipped: :math:`(n,)` bool, the near plane shortened the ray.
        test: the depth test of the G-buffer (:class:`~ssbench.passes.ssr.linear_march.DepthTest`).
        ray_length: :math:`(B, 1, H, W)` after near-plane clipping; ``jitter``: ξ :math:`(B, 1, H, W)` or None.
    """

    ray: torch.Tensor
    base: torch.Tensor
    origin: torch.Tensor
    delta: torch.Tensor
    start: torch.Tensor
    clipped: torch.Tensor
    test: DepthTest
    ray_length: torch.Tensor
    jitter: Optional[torch.Tensor]


def linear_rays(gbuffer: GBuffer, params: "LinearSSRParams", generator: Optional[torch.Generator] = None) -> LinearRays:
    """§1.1–1.2 of :func:`ssr_linear`: ``rayOrg`` and ``sceneZ`` as ``params.position_from`` says, ``rayDir =
    reflect(normalize(rayOrg), N)``, the end point clipped at the near plane, ``deltaStep = (rayEnd − rayOrg) /
    Iterations`` and the jitter; the rays flattened to those that are marched. Checks nothing (the pass does)."""
    cam, view_z, mask = gbuffer.camera, gbuffer.view_z, gbuffer.mask
    B, _, H, W = view_z.shape
    dtype, dev, HW = view_z.dtype, view_z.device, H * W
    T, N_it = float(params.thickness), params.iterations

    # ---- rayOrg, sceneZ texture and the reflection vector (§1.1) ----
    uv0 = cam.uv_grid(dtype, dev).unsqueeze(0).expand(B, -1, -1, -1)              # (B, 2, H, W) vUv
    if params.position_from == "depth":
        depth = cam.view_z_to_depth(view_z)                                       # DepthSampler
        rayOrg, sceneZ = cam.view_position_from_depth(uv0, depth), cam.depth_to_view_z(depth)
    elif params.position_from == "view_z":
        rayOrg, sceneZ = cam.uv_to_view(uv0, view_z), view_z
    else:
        rayOrg, sceneZ = gbuffer.position, view_z
    rayDir = reflection_rays(rayOrg, gbuffer.normal)                              # (B, 3, H, W)
    back = torch.where(mask, gbuffer.back_z, view_z) if params.use_back_face_depth else None

    # ---- near-plane clip, equal steps, jitter (§1.2) ----
    rayLength = clip_ray_length(rayOrg[:, 2:3], rayDir[:, 2:3], params.max_ray_distance, cam.near)
    rayEnd = rayOrg + rayDir * rayLength
    deltaStep = (rayEnd - rayOrg) / N_it
    xi = jitter_noise(params, generator, (B, 1, H, W))
    Q = rayOrg if xi is None else rayOrg - deltaStep * (params.jitter * xi.to(dtype=dtype, device=dev))

    # ---- flatten the marched rays: per-ray state tensors of length n ----
    # a pixel starts a ray where it holds geometry whose origin and direction are finite numbers (the origin
    # read back from a depth buffer whose precision is exhausted, e.g. near/far = 1e-30/1e30, is ±inf)
    # (and, as in the DDA marchers, not from geometry nearer than the near plane: no depth buffer holds it)
    ok = mask & (view_z <= -cam.near) & finite_vectors(rayOrg) & finite_vectors(deltaStep)
    ray = ok.reshape(-1).nonzero().squeeze(1)                                     # (n,) flat pixel ids
    O, dS, Q = (channel_rows(x).index_select(1, ray).T for x in (rayOrg, deltaStep, Q))   # (n, 3) views of (3, n)
    clipped = (rayLength < params.max_ray_distance).reshape(-1).index_select(0, ray)
    base = split_rays(ray, B, HW)[0] * HW                                         # batch offset of each ray
    test = DepthTest(cam, H, W, sceneZ.reshape(-1), back.reshape(-1) if back is not None else None,
                     mask.reshape(-1), T)
    return LinearRays(ray, base, O, dS, Q, clipped, test, rayLength, xi)
