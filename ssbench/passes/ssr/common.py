"""Shared pieces of the SSR passes (SSR article): the hit buffer, termination codes, the reflection ray.

Every SSR pass returns an :class:`SSRResult`: the reflection colour *and* a raw hit buffer, so the
classification in ``ssbench.metrics.ssr`` can compare what the pass found with the exact mirror hit.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Union

import torch

from ...layout import contiguous
from ..common import channel_rows, length  # noqa: F401  (channel_rows: re-exported for the marchers)

# Termination reasons (``SSRResult.termination``, int8)
NO_RAY = 0          #: background, non-reflective, or non-finite origin (depth precision exhausted): no ray
HIT = 1             #: thickness test passed (after refinement)
OFF_SCREEN = 2      #: the ray left the screen
MAX_DISTANCE = 3    #: reached MaxRayDistance / the clipped end point without a hit
OUT_OF_STEPS = 4    #: the iteration budget ran out before the end point (NOT a hit)
BEHIND_CAMERA = 5   #: the ray crossed the near plane toward the camera (clipped away)
BEHIND_SURFACE = 6  #: the ray went behind a surface deeper than the thickness and stopped there (Hi-Z, FidelityFX)
TERMINATION_NAMES = {NO_RAY: "no ray", HIT: "hit", OFF_SCREEN: "off screen", MAX_DISTANCE: "max distance",
                     OUT_OF_STEPS: "out of steps", BEHIND_CAMERA: "behind camera", BEHIND_SURFACE: "behind surface"}


@dataclass(frozen=True)
class SSRResult:
    """Output of an SSR pass; all tensors share B, H, W.

    Attributes:
        color: :math:`(B, 3, H, W)` reflected colour with fades applied (0 where no hit).
        hit: :math:`(B, 1, H, W)` bool, raw hit (before fades).
        hit_pixel: :math:`(B, 2, H, W)` continuous pixel coordinates ``(px, py)`` of the hit (NaN-free: −1 where
            no hit).
        hit_view: :math:`(B, 3, H, W)` view-space hit point (0 where no hit).
        steps: :math:`(B, 1, H, W)` int32 marching steps taken (refinement included).
        termination: :math:`(B, 1, H, W)` int8 code, see :data:`TERMINATION_NAMES`.
        fade: :math:`(B, 1, H, W)` combined fade weight in [0, 1] (1 = no fade) applied to ``color``.
        raw_color: :math:`(B, 3, H, W)` colour at the raw hit without fades.
        debug: extras, e.g. ``"visits"`` (per-pixel visit counts of a chosen ray), ``"ray_end"``.
    """

    color: torch.Tensor
    hit: torch.Tensor
    hit_pixel: torch.Tensor
    hit_view: torch.Tensor
    steps: torch.Tensor
    termination: torch.Tensor
    fade: torch.Tensor
    raw_color: torch.Tensor
    debug: dict = field(default_factory=dict)


def reflect(incident: torch.Tensor, normal: torch.Tensor, dim: int = 1) -> torch.Tensor:
    """GLSL ``reflect(I, N) = I − 2·dot(N, I)·N`` (SSR article §1.1); ``normal`` must be unit length."""
    return incident - 2.0 * (normal * incident).sum(dim, keepdim=True) * normal


def reflection_rays(position: torch.Tensor, normal: torch.Tensor) -> torch.Tensor:
    """Unit view-space reflection directions of the eye rays: ``reflect(normalize(P), N)`` (SSR article §1.1).

    Args:
        position: :math:`(B, 3, H, W)` view-space positions (the eye is at the origin).
        normal: :math:`(B, 3, H, W)` unit view-space normals.
    """
    incident = position / length(position).clamp_min(torch.finfo(position.dtype).tiny)
    r = reflect(incident, normal)
    return r / length(r).clamp_min(torch.finfo(r.dtype).tiny)


def crosses_near_plane(origin_z: torch.Tensor, dir_z: torch.Tensor, max_distance: Union[float, torch.Tensor],
                       near: float) -> torch.Tensor:
    """Whether the unclipped end point ``P.z + R.z·maxDistance`` lies beyond the near plane (``> −near``): the rays
    :func:`clip_ray_length` shortens, which the marchers report ``BEHIND_CAMERA`` when they run out of segment."""
    return origin_z + dir_z * max_distance > -near


def clip_ray_length(origin_z: torch.Tensor, dir_z: torch.Tensor, max_distance: Union[float, torch.Tensor],
                    near: float) -> torch.Tensor:
    """Ray length clipped so the end point stays in front of the near plane (SSR article §1.2, appendix A).

    ``rayLength = (P.z + R.z·maxDistance > −near) ? (−near − P.z) / R.z : maxDistance`` — rays heading toward
    the camera stop just before the near plane instead of crossing ``w = 0``.

    ``max_distance`` is a number or a 0-d tensor of the rays' dtype (the same bits). A size-dynamic compiled kernel
    passes the tensor: torch 2.13's ``torch.compile(dynamic=True)`` keeps the first call's value of a float argument
    that fills a tensor (``full_like``, a ``where`` operand) while it multiplies by the new one, so a float here gave
    wrong lengths from the second ``max_distance`` on (a tensor is an input, never a constant).
    """
    crossing = crosses_near_plane(origin_z, dir_z, max_distance, near)
    safe = torch.where(dir_z.abs() > 0, dir_z, torch.ones_like(dir_z))
    clipped = ((-near - origin_z) / safe).clamp_min(0.0)
    limit = max_distance if isinstance(max_distance, torch.Tensor) else torch.full_like(clipped, max_distance)
    return torch.where(crossing, torch.minimum(clipped, limit), limit)


def ray_segments(gbuffer, sel: torch.Tensor, max_ray_distance: float, directions: Optional[torch.Tensor] = None):
    """The view-space rays of the pixels ``sel`` (flat ``b·H·W + j·W + i``), clipped at the near plane:
    ``(b, px, o, d, end)`` — each ray's image and pixel index, origin ``rayOrg`` :math:`(N, 3)` (``uv_to_view``
    of its depth), unit direction (the mirror ray ``reflection_rays``, or ``directions`` :math:`(B, 3, H, W)`
    when given) and clipped end ``rayOrg + rayDir · clip_ray_length`` (SSR article §1.1–1.2). Shared by the
    marchers' set-ups (``dda_rays``, ``hiz_rays``)."""
    cam, vz = gbuffer.camera, gbuffer.view_z
    B, _, H, W = vz.shape
    dt, dev = vz.dtype, vz.device
    b, px = split_rays(sel, B, H * W)                                             # image and pixel of each ray

    def col(x: torch.Tensor) -> torch.Tensor:       # (B, C, H, W) -> (1, C, N, 1): one gather per channel row
        return channel_rows(x).index_select(1, sel)[None, :, :, None]
    uv = cam.pixel_to_uv(cam.pixel_centers_at(px, dt), dim=0)[None, :, :, None]       # uv_grid's values at px
    pos = cam.uv_to_view(uv, col(vz))                                             # (1, 3, N, 1) rayOrg
    R = reflection_rays(pos, col(gbuffer.normal).to(dt)) if directions is None else col(directions).to(dt)
    o, d = pos[0, :, :, 0].T, R[0, :, :, 0].T                                     # (N, 3)
    end = o + d * clip_ray_length(o[:, 2], d[:, 2], max_ray_distance, cam.near)[:, None]   # rayEnd
    return b, px, o, d, end


def split_rays(ray: torch.Tensor, B: int, HW: int) -> tuple[torch.Tensor, torch.Tensor]:
    """``(b, pixel)`` of flat ray ids ``ray = b·H·W + pixel``: each ray's image and its pixel ``j·W + i`` in that
    image (``HW`` = H·W). For one image ``b`` is 0 and the pixel the id itself, with no int64 division (a scalar
    loop on the CPU: 1.8 ms for 640×360 rays).

    Example:
        >>> split_rays(torch.tensor([1, 6, 11]), 2, 6)
        (tensor([0, 1, 1]), tensor([1, 0, 5]))
    """
    if B == 1:
        return torch.zeros_like(ray), ray
    b = ray // HW
    return b, ray - b * HW


def empty_result(like: torch.Tensor, debug: Optional[dict] = None) -> SSRResult:
    """An all-miss result shaped like ``like`` :math:`(B, *, H, W)` (for tests and degenerate inputs)."""
    B, _, H, W = like.shape
    z = lambda c: torch.zeros(B, c, H, W, dtype=like.dtype, device=like.device)   # noqa: E731
    return SSRResult(color=z(3), hit=torch.zeros(B, 1, H, W, dtype=torch.bool, device=like.device),
                     hit_pixel=z(2) - 1, hit_view=z(3),
                     steps=torch.zeros(B, 1, H, W, dtype=torch.int32, device=like.device),
                     termination=torch.zeros(B, 1, H, W, dtype=torch.int8, device=like.device),
                     fade=z(1) + 1, raw_color=z(3), debug=debug or {})


def nan_off_mask(z: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Depth ``z`` with NaN where ``mask`` is False: a marcher's depth test against it reads hit and mask at once,
    as every comparison with NaN is false (a cleared texel is never hit)."""
    return torch.where(mask, z, torch.full_like(z, float("nan")))


def end_code(clipped: torch.Tensor) -> torch.Tensor:
    """The termination code, int32, of a ray that reached the end of its segment: ``BEHIND_CAMERA`` where the near
    plane ``clipped`` it (bool, or int 0/1), else ``MAX_DISTANCE``. The marchers keep their codes in int32 while
    marching: a compiled step selected int8 codes through a per-lane conversion of each mask (perf: a fifth of the
    DDA's step kernel), and ``where`` of two Python numbers is int64.

    Example:
        >>> end_code(torch.tensor([False, True])).tolist() == [MAX_DISTANCE, BEHIND_CAMERA]
        True
    """
    return torch.where(clipped != 0, BEHIND_CAMERA, torch.full_like(clipped, MAX_DISTANCE, dtype=torch.int32))


def compact_now(live: int, size: int) -> bool:
    """Whether a marcher drops its stopped rays now: once a quarter of its working set of ``size`` rays has stopped
    (gathering every ray's constants anew each step cost more than marching a few stopped rays along, masked), and
    never down to a set of one ray, which a size-dynamic compiled step would compile anew.

    Example:
        >>> compact_now(75, 100), compact_now(76, 100), compact_now(1, 4), compact_now(0, 4)
        (True, False, False, True)
    """
    return live <= 3 * size // 4 and live != 1


def components(rows: torch.Tensor) -> tuple:
    """The columns of :math:`(N, C)` ``rows`` as ``C`` contiguous :math:`(N,)` tensors of their own, never views
    (a size-dynamic compiled step first called on views of one tensor, whose base dynamo guards, compiles again on
    the fresh tensors its outputs are).

    Example:
        >>> x, y = components(torch.arange(6.0).view(3, 2).T.T)
        >>> x.tolist(), y._base is None
        ([0.0, 2.0, 4.0], True)
    """
    return tuple(c.clone(memory_format=torch.contiguous_format) for c in rows.unbind(1))


def flat(t: torch.Tensor) -> torch.Tensor:
    """:math:`(B, C, H, W)` → :math:`(B·H·W, C)`, pixels in row-major order, contiguous (for ``B = 1`` the
    reshape is a strided view, and ``index_select`` of its rows took 19 ms at 640×360 against 1.4 ms)."""
    return contiguous(t.permute(0, 2, 3, 1)).view(-1, t.shape[1])


def unflat(values: torch.Tensor, rows: torch.Tensor, fill, shape: tuple, dtype: torch.dtype) -> torch.Tensor:
    """Per-ray ``values`` :math:`(N, C)` (or :math:`(N,)`) at the flat pixels ``rows`` → a :math:`(B, C, H, W)`
    image of ``shape`` ``(B, H, W)``, ``fill`` elsewhere: the inverse of :func:`flat`'s gather. Written through
    ``(C, B·H·W)`` channel rows with ``index_copy_`` (``x[rows] = …`` into ``(B·H·W, C)`` and a permute ran 3-5×
    slower).

    Example:
        >>> unflat(torch.tensor([[1.0, 2.0]]), torch.tensor([3]), 0.0, (1, 2, 2), torch.float32)[0].tolist()
        [[[0.0, 0.0], [0.0, 1.0]], [[0.0, 0.0], [0.0, 2.0]]]
    """
    B, H, W = shape
    values = values if values.dim() == 2 else values[:, None]
    out = torch.full((values.shape[1], B * H * W), fill, dtype=dtype, device=values.device)
    out.index_copy_(1, rows, values.T.to(dtype))
    return contiguous(out.reshape(-1, B, H, W).transpose(0, 1))


def ray_view_z(Qz: torch.Tensor, k: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor) -> torch.Tensor:
    """The DDA marchers' perspective-correct view z ``Q.z / k`` (SSR article §2.2), clamped to the segment's z range
    ``[lo, hi]`` (finite where ``k`` ≤ 0).

    Example:
        >>> ray_view_z(torch.tensor([-4.0, -4.0]), torch.tensor([2.0, 0.0]), torch.tensor(-9.0), torch.tensor(-1.0))
        tensor([-2., -9.])
    """
    return torch.minimum(torch.maximum(Qz / k.clamp_min(torch.finfo(k.dtype).tiny), lo), hi)
