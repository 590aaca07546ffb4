"""The linear march's rays (SSR article §1.1–1.2): ``rayOrg`` and the depth-buffer z as ``position_from`` says,
``rayDir = reflect(normalize(rayOrg), N)``, the end point clipped at the near plane, ``Iterations`` equal steps
and the optional jitter — flattened to the rays that are marched (:class:`LinearRays`). Used by
:func:`ssbench.passes.ssr.linear.ssr_linear`, its teaching twin and the Dr.Jit anchor
(:mod:`ssbench.bench.anchors`), so all three march the same rays."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

import torch

from ...camera import Camera
from ...checks import finite_vectors
from ...gbuffer import GBuffer
from ...indices import flat_nonzero
from ..common import make_generator
from ..compiled import kernel
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


@kernel(dynamic=True)
def ray_origin(cam: Camera, view_z: torch.Tensor, position: Optional[torch.Tensor], position_from: str) -> tuple:
    """§1.1 up to the reflection: ``(rayOrg, sceneZ)``, :math:`(B, 3, H, W)` and :math:`(B, 1, H, W)`, from ``view_z``
    as ``position_from`` says (``getViewPosition`` of the GL depth buffer for ``"depth"``, ``uvToView`` of ``view_z``,
    or the G-buffer's ``position``); a compilable, size-dynamic kernel (:mod:`ssbench.passes.compiled`)."""
    B = view_z.shape[0]
    uv0 = cam.uv_grid(view_z.dtype, view_z.device).unsqueeze(0).expand(B, -1, -1, -1)   # (B, 2, H, W) vUv
    if position_from == "depth":
        depth = cam.view_z_to_depth(view_z)                                       # DepthSampler
        return cam.view_position_from_depth(uv0, depth), cam.depth_to_view_z(depth)
    if position_from == "view_z":
        return cam.uv_to_view(uv0, view_z), view_z
    return position, view_z


@kernel(dynamic=True)
def ray_steps(cam: Camera, rayOrg: torch.Tensor, rayDir: torch.Tensor, view_z: torch.Tensor, mask: torch.Tensor,
              xi: Optional[torch.Tensor], max_ray_distance: torch.Tensor, iterations: int, jitter: float) -> tuple:
    """§1.2 per pixel: ``(rayLength, deltaStep, start, ok)`` — the ray length clipped at the near plane, ``deltaStep =
    (rayEnd − rayOrg) / Iterations``, the sample before the first (``rayOrg``, moved back by ``jitter·ξ·deltaStep``)
    and whether the pixel starts a ray (:class:`LinearRays`); a compilable, size-dynamic kernel. It takes the
    settings as numbers, not the parameter set, so that one compilation serves a sweep, and ``max_ray_distance`` as a
    0-d tensor (see :func:`~.common.clip_ray_length`)."""
    rayLength = clip_ray_length(rayOrg[:, 2:3], rayDir[:, 2:3], max_ray_distance, cam.near)
    rayEnd = rayOrg + rayDir * rayLength
    deltaStep = (rayEnd - rayOrg) / iterations
    Q = rayOrg if xi is None else rayOrg - deltaStep * (jitter * xi)
    # a pixel starts a ray where it holds geometry whose origin and direction are finite numbers (the origin
    # read back from a depth buffer whose precision is exhausted, e.g. near/far = 1e-30/1e30, is ±inf)
    # (and, as in the DDA marchers, not from geometry nearer than the near plane: no depth buffer holds it)
    ok = mask & (view_z <= -cam.near) & finite_vectors(rayOrg) & finite_vectors(deltaStep)
    return rayLength, deltaStep, Q, ok


def linear_rays(gbuffer: GBuffer, params: "LinearSSRParams", generator: Optional[torch.Generator] = None) -> LinearRays:
    """§1.1–1.2 of :func:`ssr_linear`: ``rayOrg`` and ``sceneZ`` as ``params.position_from`` says, ``rayDir =
    reflect(normalize(rayOrg), N)``, the end point clipped at the near plane, ``deltaStep = (rayEnd − rayOrg) /
    Iterations`` and the jitter; the rays flattened to those that are marched. Checks nothing (the pass does).

    Compiled, :func:`ray_origin` and :func:`ray_steps` run through ``torch.compile`` (exact operations only: the same
    bits); the reflection stays eager, as inductor's square roots differ from ATen's in the last bit."""
    cam, view_z, mask = gbuffer.camera, gbuffer.view_z, gbuffer.mask
    B, _, H, W = view_z.shape
    dtype, dev, HW = view_z.dtype, view_z.device, H * W

    # ---- rayOrg, sceneZ texture and the reflection vector (§1.1) ----
    position = gbuffer.position if params.position_from == "position" else None
    rayOrg, sceneZ = ray_origin(cam, view_z, position, params.position_from)
    rayDir = reflection_rays(rayOrg, gbuffer.normal)                              # (B, 3, H, W)
    back = torch.where(mask, gbuffer.back_z, view_z) if params.use_back_face_depth else None

    # ---- near-plane clip, equal steps, jitter (§1.2) ----
    xi = jitter_noise(params, generator, (B, 1, H, W))
    rayLength, deltaStep, Q, ok = ray_steps(cam, rayOrg, rayDir, view_z, mask,
                                            None if xi is None else xi.to(dtype=dtype, device=dev),
                                            torch.tensor(params.max_ray_distance, dtype=dtype, device=dev),
                                            params.iterations, float(params.jitter))

    # ---- flatten the marched rays: per-ray state tensors of length n ----
    ray = flat_nonzero(ok.reshape(-1))                                            # (n,) flat pixel ids
    O, dS, Q = (channel_rows(x).index_select(1, ray).T for x in (rayOrg, deltaStep, Q))   # (n, 3) views of (3, n)
    clipped = (rayLength < params.max_ray_distance).reshape(-1).index_select(0, ray)
    base = split_rays(ray, B, HW)[0] * HW                                         # batch offset of each ray
    test = DepthTest(cam, H, W, sceneZ.reshape(-1), back.reshape(-1) if back is not None else None,
                     mask.reshape(-1), float(params.thickness))
    return LinearRays(ray, base, O, dS, Q, clipped, test, rayLength, xi)
