r"""Analytic ray–sphere intersection, the closed form of the article's background (progressive-tracing article, 背景 /
レイキャスティング).

For the sphere :math:`f(\vec x) = \lVert \vec x - \vec c\rVert - r` and the unit ray :math:`\vec s + t\vec d`
the article solves

.. math::
    t^2 + 2\,((\vec s - \vec c)\cdot\vec d)\,t + ((\vec s - \vec c)^2 - r^2) = 0 .

Written naively (``b² − c`` under the root, ``−b ± √…``) the quadratic loses digits twice: the discriminant
cancels for rays far from the sphere and the smaller root cancels when ``|b| ≫ √disc``. We use the stable
form: with ``m = s − c`` and ``b = m·d``, the discriminant is ``r² − |m − b d|²`` (the squared half chord,
from the perpendicular distance of the centre to the ray), ``c = (|m| − r)(|m| + r)``, and the roots are
``q = −(b + sign(b)·√disc)`` and ``c / q``. A tangent ray (``disc = 0``) is a double root: reported as a hit.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Union

import torch
from torch import nn

from .common import HIT, MISS, CameraRays, ImplicitResult, as_rays, flat, unflat

__all__ = ["AnalyticSphereParams", "analytic_sphere", "sphere_roots", "AnalyticSphere"]


@dataclass(frozen=True)
class AnalyticSphereParams:
    """Parameters of :func:`analytic_sphere`.

    Attributes:
        use_near: accept only roots ``t ≥ t_near`` (the near plane clips); False accepts ``t ≥ 0``.
    """

    use_near: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.use_near, bool):
            raise ValueError(f"use_near: expected a bool, got {self.use_near!r}")


def sphere_roots(origin: torch.Tensor, direction: torch.Tensor, center: torch.Tensor,
                 radius: float) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Both roots ``t0 ≤ t1`` of the article's quadratic (stable form) and the mask ``disc ≥ 0``.

    ``origin``, ``direction`` (unit) and ``center`` broadcast along the last axis (size 3); roots are 0 where
    there is no real root.

    Example:
        >>> o, d = torch.tensor([0.0, 0.0, 5.0]), torch.tensor([0.0, 0.0, -1.0])
        >>> t0, t1, ok = sphere_roots(o, d, torch.zeros(3), 1.0)
        >>> t0.item(), t1.item(), ok.item()
        (4.0, 6.0, True)
    """
    m = origin - center
    b = (m * direction).sum(-1)                                         # (s − c)·d
    perp = m - b.unsqueeze(-1) * direction                              # centre-to-ray offset
    disc = radius * radius - (perp * perp).sum(-1)                      # (half chord)²
    ok = disc >= 0
    mn = m.norm(dim=-1)
    c = (mn - radius) * (mn + radius)                                   # (s − c)² − r², no cancellation
    root = torch.sqrt(disc.clamp_min(0))
    q = -(b + torch.where(b >= 0, root, -root))
    q_safe = torch.where(q == 0, torch.ones_like(q), q)
    ta, tb = q, torch.where(q == 0, torch.zeros_like(q), c / q_safe)
    t0, t1 = torch.minimum(ta, tb), torch.maximum(ta, tb)
    zero = torch.zeros_like(t0)
    return torch.where(ok, t0, zero), torch.where(ok, t1, zero), ok


def analytic_sphere(camera: Union[CameraRays, "object"], center: Union[Sequence[float], torch.Tensor],
                    radius: float, params: AnalyticSphereParams = AnalyticSphereParams(), *,
                    jitter: Optional[torch.Tensor] = None, dtype: Optional[torch.dtype] = None,
                    device=None) -> ImplicitResult:
    r"""First root ``t ≥ t_near`` of a sphere per pixel, in closed form (progressive-tracing article, 背景).

    Args:
        camera: a :class:`~ssbench.camera.Camera` (rays through pixel centres, plus ``jitter``) or ready
            :class:`CameraRays` with :math:`(B, 3, H, W)` origins/directions.
        center: the sphere's centre (3 numbers or a tensor of shape (3,)).
        radius: ``r > 0``.
        params: :class:`AnalyticSphereParams`.
        jitter: optional :math:`(B, 2, H, W)` or :math:`(B, 2, 1, 1)` sub-pixel offsets (only with a Camera).
        dtype, device: of the rays built from a Camera (default float32).

    Returns:
        :class:`ImplicitResult` with 0 evaluations and steps; ``normal = (p − c)/r``; ``object_index`` 0 on
        hits; ``debug["roots"]`` :math:`(B, 2, H, W)` both roots (0 where none).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 45.0, 4, 3, 0.1, 10.0)
        >>> r = analytic_sphere(cam, (0, 0, 0), 1.0, dtype=torch.float64)
        >>> r.t.shape, int(r.hit.sum()), round(r.t[0, 0, 1, 1].item(), 6)
        (torch.Size([1, 1, 3, 4]), 2, 3.125338)
    """
    if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not radius > 0:
        raise ValueError(f"radius: must be a number > 0, got {radius!r}")
    if not isinstance(params, AnalyticSphereParams):
        raise TypeError(f"params: expected AnalyticSphereParams, got {type(params).__name__}")
    rays = as_rays(camera, jitter, dtype, device)
    B, _, H, W = rays.direction.shape
    o, d = flat(rays.origin), flat(rays.direction)
    c = torch.as_tensor(center, dtype=o.dtype, device=o.device)
    if c.shape != (3,) or not bool(torch.isfinite(c).all()):
        raise ValueError(f"center: expected three finite numbers, got {center!r}")
    t_min = flat(rays.t_near).squeeze(1) if params.use_near else torch.zeros_like(o[:, 0])
    t_far = flat(rays.t_far).squeeze(1)
    t0, t1, ok = sphere_roots(o, d, c, float(radius))
    first = torch.where(t0 >= t_min, t0, t1)                            # first root at or past t_near
    hit = ok & (first >= t_min) & (first <= t_far)
    term = torch.where(hit, HIT, MISS).to(torch.int8)
    zeros = torch.zeros(o.shape[0], dtype=torch.int32, device=o.device)
    t = torch.where(hit, first, t_far)
    normal = torch.where(hit.unsqueeze(1), (o + t.unsqueeze(1) * d - c) / radius, torch.zeros_like(o))
    obj = torch.where(hit, 0, -1).to(torch.int32)
    shape = (B, H, W)
    return ImplicitResult(t=unflat(t, shape), hit=unflat(hit, shape), evaluations=unflat(zeros, shape),
                          steps=unflat(zeros, shape), termination=unflat(term, shape),
                          normal=unflat(normal, shape), object_index=unflat(obj, shape),
                          debug={"roots": unflat(torch.stack([t0, t1], 1), shape)})

class AnalyticSphere(nn.Module):
    """``nn.Module`` wrapper of :func:`analytic_sphere`; ``forward(camera)`` returns its result."""

    def __init__(self, center: Sequence[float], radius: float,
                 params: AnalyticSphereParams = AnalyticSphereParams()) -> None:
        super().__init__()
        self.center, self.radius, self.params = tuple(float(v) for v in center), float(radius), params

    def forward(self, camera, jitter: Optional[torch.Tensor] = None) -> ImplicitResult:
        return analytic_sphere(camera, self.center, self.radius, self.params, jitter=jitter)
