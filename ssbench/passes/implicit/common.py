"""Shared pieces of the implicit-surface ray casters (progressive-tracing article): camera rays, the result buffer, the surface
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
from typing import Any, Optional

import torch

from ...camera import Camera
from ...implicit.shading import safe_normal, shade_hits  # noqa: F401  (re-exported for the casters)
from ...indices import flat_nonzero
from ...rays import CameraRays, camera_rays, length  # noqa: F401  (re-exported for the casters)

# Termination reasons (``ImplicitResult.termination``, int8)
MISS = 0            #: nothing found on [t_near, t_far] (transparent / background)
HIT = 1             #: a root was bracketed (or the distance fell below epsilon) and refined
OUT_OF_STEPS = 2    #: the step budget ran out before the end of the ray (NOT a hit)
INVALIDATED = 3     #: progressive method: the stored t' failed the (1+eps)t' probe and the recast found nothing
TERMINATION_NAMES = {MISS: "miss", HIT: "hit", OUT_OF_STEPS: "out of steps", INVALIDATED: "invalidated"}


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
        debug: extras (e.g. ``"bracket"`` (B, 2, H, W) the interval left after bisection (not the coarser one
            the march found), ``"invalidated"`` mask).
        state: what the caster carries to the next frame, to be passed back as ``state=`` (the progressive
            method's :class:`~ssbench.passes.implicit.progressive.ProgressiveState`); ``None`` for the stateless
            casters.
    """

    t: torch.Tensor
    hit: torch.Tensor
    evaluations: torch.Tensor
    steps: torch.Tensor
    termination: torch.Tensor
    normal: torch.Tensor
    object_index: torch.Tensor
    debug: dict = field(default_factory=dict)
    state: Optional[Any] = None


# ---------------------------------------------------------------------------------------------------------
# Helpers shared by the marchers (analytic / fixed-step / sphere tracing / progressive) and the G-buffer.
# They work on *flat* ray lists: ``origin``/``direction`` (n, 3), ``t`` (n,), with n = B·H·W.


def as_rays(camera, jitter: Optional[torch.Tensor] = None, dtype: Optional[torch.dtype] = None, device=None,
            batch: int = 1) -> CameraRays:
    """``camera`` if it is already a :class:`CameraRays`, else :func:`camera_rays` of a :class:`Camera`
    (``dtype`` default float32)."""
    if isinstance(camera, CameraRays):
        if jitter is not None:
            raise ValueError("jitter: pass the jitter to camera_rays(), not with ready-made CameraRays")
        return camera
    if not isinstance(camera, Camera):
        raise TypeError(f"camera: expected a Camera or CameraRays, got {type(camera).__name__}")
    return camera_rays(camera, batch=batch, jitter=jitter, dtype=dtype or torch.float32, device=device)


def check_stateless(state, caster: str) -> None:
    """``ValueError`` naming ``state`` unless it is ``None``: ``caster`` keeps nothing between frames (the
    argument is there so every caster takes the same call)."""
    if state is not None:
        raise ValueError(f"state: {caster} is stateless and takes state=None, got {type(state).__name__}")


def check_surface(surface, name: str = "surface") -> None:
    """Raise ``TypeError`` unless ``surface`` has the protocol's callable ``f``."""
    if not callable(getattr(surface, "f", None)):
        raise TypeError(f"{name}: expected an object with f(p) (the surface protocol), "
                        f"got {type(surface).__name__}")


def flat(x: torch.Tensor) -> torch.Tensor:
    """:math:`(B, C, H, W)` → :math:`(B·H·W, C)` (row order b, y, x)."""
    return x.permute(0, 2, 3, 1).reshape(-1, x.shape[1])


def unflat(x: torch.Tensor, shape: tuple[int, int, int]) -> torch.Tensor:
    """:math:`(B·H·W,)` or :math:`(B·H·W, C)` → :math:`(B, C, H, W)`; ``shape = (B, H, W)``."""
    B, H, W = shape
    x = x.reshape(B * H * W, -1)
    return x.reshape(B, H, W, x.shape[1]).permute(0, 3, 1, 2).contiguous()


def bisect(surface, origin: torch.Tensor, direction: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor,
           iterations: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Bisection of brackets ``f(lo) ≥ 0 > f(hi)`` along rays (n, 3), keeping the bracket (progressive-tracing article,
    二分法による絞込み): ``iterations`` evaluations per ray; returns the final ``(lo, hi)``."""
    for _ in range(iterations):
        if lo.numel() == 0:
            break
        mid = 0.5 * (lo + hi)
        outside = surface.f(origin + mid.unsqueeze(-1) * direction) >= 0
        lo, hi = torch.where(outside, mid, lo), torch.where(outside, hi, mid)
    return lo, hi


def finish(shape: tuple[int, int, int], *, origin: torch.Tensor, direction: torch.Tensor, t_far: torch.Tensor,
           surface, hit: torch.Tensor, t: torch.Tensor, evaluations: torch.Tensor, steps: torch.Tensor,
           termination: torch.Tensor, debug: Optional[dict] = None) -> ImplicitResult:
    """Build an :class:`ImplicitResult` from flat per-ray values: shades the hits (one gradient evaluation
    each, added to ``evaluations``), puts ``t_far`` where no hit and reshapes to :math:`(B, C, H, W)`."""
    n = origin.shape[0]
    normal = origin.new_zeros(n, 3)
    obj = torch.full((n,), -1, dtype=torch.int32, device=origin.device)
    if surface is not None:
        h = flat_nonzero(hit)
        normal[h], obj[h] = shade_hits(surface, origin[h] + t[h].unsqueeze(-1) * direction[h])
        evaluations = evaluations + hit.to(evaluations.dtype)
    t = torch.where(hit, t, t_far)
    return ImplicitResult(t=unflat(t, shape), hit=unflat(hit, shape), evaluations=unflat(evaluations, shape),
                          steps=unflat(steps, shape), termination=unflat(termination, shape),
                          normal=unflat(normal, shape), object_index=unflat(obj, shape), debug=debug or {})


class FunctionSurface:
    """The surface protocol from plain torch callables (for tests, doctests and quick experiments).

    Args:
        f: callable on (..., 3) world points returning (...) values, f > 0 outside.
        lipschitz: declared bound on |∇f| (None: not declared).
        bounds: world AABB ``((x0, y0, z0), (x1, y1, z1))`` outside which f > 0 (default: unbounded).
        parts: optional callables whose minimum is ``f``; :meth:`object_index` is their argmin.

    Example:
        >>> ball = FunctionSurface(lambda p: p.norm(dim=-1) - 1.0, lipschitz=1.0)
        >>> ball.f(torch.tensor([[0.0, 0.0, 2.0]])).tolist()
        [1.0]
    """

    def __init__(self, f, lipschitz: Optional[float] = None, bounds=None, parts=None) -> None:
        if not callable(f):
            raise TypeError(f"f: expected a callable, got {type(f).__name__}")
        self._f, self.lipschitz, self.parts = f, lipschitz, tuple(parts or ())
        self.bounds = bounds if bounds is not None else ((-float("inf"),) * 3, (float("inf"),) * 3)

    def f(self, p: torch.Tensor) -> torch.Tensor:
        return self._f(p)

    def f_and_grad(self, p: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        with torch.enable_grad():
            q = p.detach().requires_grad_(True)
            v = self._f(q)
            g = torch.autograd.grad(v.sum(), q, allow_unused=True)[0] if v.requires_grad else None
        return v.detach(), torch.zeros_like(q) if g is None else g.detach()

    def object_index(self, p: torch.Tensor) -> torch.Tensor:
        if len(self.parts) < 2:
            return torch.zeros(p.shape[:-1], dtype=torch.long, device=p.device)
        return torch.stack([g(p) for g in self.parts], -1).argmin(-1)
