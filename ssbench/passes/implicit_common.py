"""Shared pieces of the implicit-surface ray casters (seed 004): camera rays, the result buffer, the surface
protocol.

Ray convention (the same for every method *and* for ``ssbench.reference.implicit``): a pixel's ray starts at
the camera ``eye`` and runs along the **unit** world-space direction ``d`` through the pixel centre (or a
jittered point of the pixel); ``t`` is the distance along it in world units. The article's far distance
``d_f`` ("camera to far plane") is per pixel the ``t`` where the ray meets the far plane,
``t_far = far / cos θ`` with ``cos θ = −d_view.z``; likewise ``t_near = near / cos θ``.

A *surface* is any object with (``ssbench.implicit.ImplicitSurface`` is the real one)::

    f(p)                  -> Tensor (...)        p: (..., 3) world points, any float dtype/device
    f_and_grad(p)         -> (Tensor (...), Tensor (..., 3))   value and ∇f (autograd)
    object_index(p)       -> LongTensor (...)    which object of a union is nearest (argmin)
    interval(lo, hi)      -> (Tensor, Tensor)    float64 enclosure of f over boxes (..., 3); NaN = unknown
    bounds                -> ((x0, y0, z0), (x1, y1, z1))   world AABB outside which f > 0
    lipschitz             -> float | None        declared bound on |∇f| (None: not declared)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import torch

from ..camera import Camera

# Termination reasons (``ImplicitResult.termination``, int8)
MISS = 0            #: nothing found on [t_near, t_far] (transparent / background)
HIT = 1             #: a root was bracketed (or the distance fell below epsilon) and refined
OUT_OF_STEPS = 2    #: the step budget ran out before the end of the ray (NOT a hit)
INVALIDATED = 3     #: progressive method: the stored t' failed the (1+eps)t' probe and the recast found nothing
TERMINATION_NAMES = {MISS: "miss", HIT: "hit", OUT_OF_STEPS: "out of steps", INVALIDATED: "invalidated"}


@dataclass(frozen=True)
class CameraRays:
    """World-space rays through pixel centres (plus optional sub-pixel jitter), all ``(B, H, W)``-shaped.

    Attributes:
        origin: :math:`(B, 3, H, W)` ray origins (the eye, broadcast).
        direction: :math:`(B, 3, H, W)` unit world-space directions.
        t_near: :math:`(B, 1, H, W)` distance to the near plane along the ray.
        t_far: :math:`(B, 1, H, W)` distance to the far plane along the ray (the article's ``d_f``).
        view_dir: :math:`(B, 3, H, W)` the same unit directions in view space.
    """

    origin: torch.Tensor
    direction: torch.Tensor
    t_near: torch.Tensor
    t_far: torch.Tensor
    view_dir: torch.Tensor

    def point(self, t: torch.Tensor) -> torch.Tensor:
        """World points ``o + t d`` for ``t`` of shape :math:`(B, 1, H, W)` (or ``(B, K, H, W)`` → ``(B, K, 3, H, W)``)."""
        if t.shape[1] == 1:
            return self.origin + t * self.direction
        return self.origin.unsqueeze(1) + t.unsqueeze(2) * self.direction.unsqueeze(1)


def camera_rays(camera: Camera, batch: int = 1, jitter: Optional[torch.Tensor] = None,
                dtype: torch.dtype = torch.float32, device=None) -> CameraRays:
    """Rays of every pixel of ``camera``.

    Args:
        camera: the pinhole camera (GL conventions, ``CONVENTIONS.md``).
        batch: batch size ``B`` when ``jitter`` is None.
        jitter: optional :math:`(B, 2, H, W)` or :math:`(B, 2, 1, 1)` sub-pixel offsets in pixels (x right,
            y down the rows) added to the pixel centres, e.g. TXAA jitter in ``[-0.5, 0.5)``.
        dtype, device: of the returned tensors (float64 for the reference).

    Example:
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 45.0, 4, 3, 0.1, 10.0)
        >>> r = camera_rays(cam, dtype=torch.float64)
        >>> r.direction.shape, bool(torch.allclose(r.direction.norm(dim=1), torch.ones(1, 3, 4, dtype=torch.float64)))
        (torch.Size([1, 3, 3, 4]), True)
    """
    px = camera.pixel_centers(dtype, device).unsqueeze(0)                 # (1, 2, H, W)
    if jitter is not None:
        if jitter.dim() != 4 or jitter.shape[1] != 2:
            raise ValueError(f"jitter: expected shape (B, 2, H, W) or (B, 2, 1, 1), got {tuple(jitter.shape)}")
        px = px + jitter.to(dtype=dtype, device=device)
        batch = px.shape[0]
    else:
        px = px.expand(batch, -1, -1, -1)
    uv = camera.pixel_to_uv(px, dim=1)
    v = camera.uv_to_view(uv, torch.full_like(uv[:, :1], -1.0), dim=1)    # z = -1
    v = v / v.norm(dim=1, keepdim=True)
    cos_t = -v[:, 2:3]
    c2w = camera.camera_to_world(dtype=dtype, device=device)
    d = torch.einsum("ij,bjhw->bihw", c2w[:3, :3], v)
    d = d / d.norm(dim=1, keepdim=True)
    eye = torch.tensor(camera.eye, dtype=dtype, device=device).view(1, 3, 1, 1)
    return CameraRays(origin=eye.expand_as(d), direction=d, t_near=camera.near / cos_t,
                      t_far=camera.far / cos_t, view_dir=v)


@dataclass(frozen=True)
class ImplicitResult:
    """Output of an implicit-surface ray caster; all tensors share B, H, W.

    Attributes:
        t: :math:`(B, 1, H, W)` distance along the unit ray of the hit (``t_far`` where no hit).
        hit: :math:`(B, 1, H, W)` bool.
        evaluations: :math:`(B, 1, H, W)` int32 number of f evaluations spent on the pixel (refinement and
            gradient for shading included; a gradient counts as one evaluation).
        steps: :math:`(B, 1, H, W)` int32 marching steps (refinement excluded).
        termination: :math:`(B, 1, H, W)` int8 code, see :data:`TERMINATION_NAMES`.
        normal: :math:`(B, 3, H, W)` unit world-space normal ∇f/|∇f| at the hit (0 where no hit).
        object_index: :math:`(B, 1, H, W)` int32 index of the object hit (−1 where no hit).
        debug: extras (e.g. ``"bracket"`` (B, 2, H, W) the bracketing interval, ``"invalidated"`` mask).
    """

    t: torch.Tensor
    hit: torch.Tensor
    evaluations: torch.Tensor
    steps: torch.Tensor
    termination: torch.Tensor
    normal: torch.Tensor
    object_index: torch.Tensor
    debug: dict = field(default_factory=dict)
