"""Rays and vector lengths, shared by the passes, the references that check them and the metrics.

* :func:`length` — the Euclidean length of vector images, the fast way on the CPU;
* :func:`cross` — ``torch.linalg.cross``'s bits, the fast way on the CPU;
* :class:`CameraRays`, :func:`camera_rays` — world-space rays through every pixel centre of a
  :class:`~ssbench.camera.Camera` (plus optional sub-pixel jitter), with the distances to the near and far
  planes along each ray. Ray convention: a pixel's ray starts at the ``eye`` and runs along the **unit**
  world-space direction ``d``; ``t`` is the distance along it in world units; ``t_far = far / cos θ`` with
  ``cos θ = −d_view.z`` (the far distance ``d_f`` of progressive-tracing article), ``t_near = near / cos θ``.

They live below :mod:`ssbench.passes` so that ground truth (``ssbench.reference``) and metrics never import the
passes they score.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Optional

import numpy as np
import torch

from .camera import Camera

__all__ = ["length", "vector_norm", "component_dot", "component_norm", "cross", "cross_components", "CameraRays",
           "camera_rays"]


def length(x: torch.Tensor, dim: int = 1, keepdim: bool = True) -> torch.Tensor:
    """Euclidean length of the vectors along ``dim`` of ``x``, e.g. :math:`(B, 3, H, W) \to (B, 1, H, W)`.

    ``sqrt(sum(x²))``: on the CPU, ``Tensor.norm``/``torch.linalg.vector_norm`` over a dimension that is not
    the innermost is 40-70x slower (torch 2.13, one thread: 9.4 ms against 0.14 ms for a 320×240 vector
    image). The two agree to an ulp. When ``x`` needs a gradient this calls ``torch.linalg.vector_norm``,
    whose gradient at a zero vector is 0 (the square root's would be NaN). Squares overflow beyond
    :math:`|x| \approx 10^{19}` in float32, far from any scene's coordinates.

    Example:
        >>> length(torch.tensor([[[[3.0]], [[4.0]], [[0.0]]]])).flatten().tolist()
        [5.0]
    """
    if x.requires_grad:
        return torch.linalg.vector_norm(x, dim=dim, keepdim=keepdim)
    return (x * x).sum(dim=dim, keepdim=keepdim).sqrt()


def vector_norm(x: torch.Tensor, dim: int = 1, keepdim: bool = True) -> torch.Tensor:
    r"""``torch.linalg.vector_norm(x, dim=dim, keepdim=keepdim)``, bit for bit, without its slow CPU path.

    On the CPU, ATen reduces a dimension that is not the innermost one an element at a time (its
    ``binary_kernel_reduce``): over the channels of a :math:`(1, 3, 360, 640)` float32 image that takes 21 ms,
    against 0.3 ms for the same arithmetic as whole-tensor operations. That path adds the squares in order in the
    input's dtype, with no fused multiply-add, and takes a correctly rounded square root (``std::sqrt``). This
    function does the same: the squares summed in order by tensor operations, the root by ``numpy.sqrt``
    (correctly rounded, like ``std::sqrt``; torch's vectorised ``Tensor.sqrt`` is not: about 0.6 % of float32
    roots differ by an ulp). :func:`length` is the faster, ulp-level twin used where bits need not match.

    Everywhere else it calls ``torch.linalg.vector_norm``: off the CPU, for other dtypes, when ``x`` needs a
    gradient, inside ``torch.compile`` (which generates its own loop), and when ``dim`` is the innermost
    dimension in memory (ATen's vectorised path, which accumulates with fused multiply-adds).

    Example:
        >>> x = torch.randn(2, 3, 5, 7, generator=torch.Generator().manual_seed(0))
        >>> torch.equal(vector_norm(x), torch.linalg.vector_norm(x, dim=1, keepdim=True))
        True
    """
    dim = dim % x.dim() if x.dim() else dim
    if (x.device.type != "cpu" or x.dtype not in (torch.float32, torch.float64) or x.requires_grad
            or torch.compiler.is_compiling() or not x.is_contiguous() or x.shape[dim] == 0
            or math.prod(x.shape[dim + 1:]) <= 1):
        return torch.linalg.vector_norm(x, dim=dim, keepdim=keepdim)
    total = component_norm(*x.unbind(dim))
    return total.unsqueeze(dim) if keepdim else total


def component_dot(a, b) -> torch.Tensor:
    """The dot product of the vectors whose components are the tensors ``a`` and ``b`` (sequences of one length),
    summed in order: the bits of ``(torch.stack(a, 1) * torch.stack(b, 1)).sum(1)`` on the CPU (ATen sums a
    channel dimension in order), without stacking, so that a compiled loop stores no stack and no reduction.

    Example:
        >>> component_dot((torch.tensor([1.0]), torch.tensor([2.0])), (torch.tensor([3.0]), torch.tensor([4.0])))
        tensor([11.])
    """
    total = a[0] * b[0]
    for x, y in zip(a[1:], b[1:]):
        total = total + x * y
    return total


def component_norm(*parts: torch.Tensor) -> torch.Tensor:
    """The length of the vectors whose components are ``parts`` (tensors of one shape), without stacking them: on
    the CPU the bits of :func:`vector_norm` of the stacked vectors (squares summed in order, a correctly rounded
    root); elsewhere, with gradients or inside ``torch.compile`` (where it compiles to one loop, with no stored
    stack and no reduction), ``Tensor.sqrt`` of the same sum.

    Example:
        >>> component_norm(torch.tensor([3.0, 0.0]), torch.tensor([4.0, 0.0]), torch.tensor([0.0, 2.0])).tolist()
        [5.0, 2.0]
    """
    total = component_dot(parts, parts)
    if (total.device.type != "cpu" or total.dtype not in (torch.float32, torch.float64) or total.requires_grad
            or torch.compiler.is_compiling()):
        return total.sqrt()
    np.sqrt(total.numpy(), out=total.numpy())
    return total



def cross(a: torch.Tensor, b: torch.Tensor, dim: int = 1) -> torch.Tensor:
    """``torch.linalg.cross(a, b, dim=dim)``, bit for bit, without its slow CPU path.

    On the CPU ATen computes each component in a scalar loop as one fused multiply-add, ``fma(a₁, b₂, −(a₂·b₁))``
    (and cyclically): 5.8 ms for a :math:`(1, 3, 360, 640)` float32 image. ``torch.addcmul(−(a₂·b₁), a₁, b₂)`` is
    that FMA vectorised: the same bits in 1.1 ms (one thread; tested against ``torch.linalg.cross`` on odd sizes,
    rows and images, float32 and float64). Elsewhere — other devices or dtypes, inside ``torch.compile`` (whose
    C++ contracts nothing), with gradients — this is ``torch.linalg.cross`` itself.

    Example:
        >>> cross(torch.tensor([[1.0, 0.0, 0.0]]), torch.tensor([[0.0, 1.0, 0.0]])).tolist()
        [[0.0, 0.0, 1.0]]
    """
    if not _fma_is_aten(a, b):
        return torch.linalg.cross(a, b, dim=dim)
    return torch.stack(_fma_components(a.unbind(dim), b.unbind(dim)), dim)


def cross_components(a, b) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The ``(x, y, z)`` of ``a × b`` for vectors given as their components (tuples of three tensors of one shape),
    with :func:`cross`'s bits: ``torch.stack(cross_components(a.unbind(d), b.unbind(d)), d)`` is
    ``cross(a, b, dim=d)``. On the CPU (float32, float64, no gradients) the components are computed apart, with no
    stacked copy of either operand; inside ``torch.compile`` as ``a₁b₂ − a₂b₁`` …, the arithmetic inductor makes of
    ``torch.linalg.cross``, again with no stack (a compiled kernel stores a stack and reads it back a row at a time:
    three.js SSR's step ran 1.6× slower); elsewhere they are ``torch.linalg.cross``'s.

    Example:
        >>> [c.tolist() for c in cross_components(torch.eye(3)[0], torch.eye(3)[1])]
        [0.0, 0.0, 1.0]
    """
    if torch.compiler.is_compiling():
        (a0, a1, a2), (b0, b1, b2) = a, b
        return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
    if not all(_fma_is_aten(x, y) for x, y in zip(a, b)):
        return torch.linalg.cross(torch.stack(tuple(a), -1), torch.stack(tuple(b), -1), dim=-1).unbind(-1)
    return _fma_components(a, b)


def _fma_is_aten(x: torch.Tensor, y: torch.Tensor) -> bool:
    """Whether ``torch.addcmul`` gives ``torch.linalg.cross``'s bits for operands ``x``, ``y`` (see :func:`cross`):
    on the CPU, float32 or float64, the same shape, no gradients, outside ``torch.compile``."""
    return (x.device.type == "cpu" and x.dtype in (torch.float32, torch.float64) and y.dtype == x.dtype
            and x.shape == y.shape and not x.requires_grad and not y.requires_grad
            and not torch.compiler.is_compiling())


def _fma_components(a, b) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """ATen's CPU cross on components: each ``fma(a₁, b₂, −(a₂·b₁))`` (cyclically) as ``torch.addcmul``."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return (torch.addcmul(-(a2 * b1), a1, b2), torch.addcmul(-(a0 * b2), a2, b0), torch.addcmul(-(a1 * b0), a0, b1))


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
    v = v / length(v)
    cos_t = -v[:, 2:3]
    c2w = camera.camera_to_world(dtype=dtype, device=device)
    d = torch.einsum("ij,bjhw->bihw", c2w[:3, :3], v)
    d = d / length(d)
    eye = torch.tensor(camera.eye, dtype=dtype, device=device).view(1, 3, 1, 1)
    return CameraRays(origin=eye.expand_as(d), direction=d, t_near=camera.near / cos_t,
                      t_far=camera.far / cos_t, view_dir=v)
