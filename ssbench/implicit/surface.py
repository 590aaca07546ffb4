"""Implicit objects: one expression placed in the world, the building block of the surfaces every implicit ray
caster and the reference consume (their union: :class:`ssbench.implicit.union.ImplicitSurface`).

An :class:`ImplicitObject` is a parsed expression ``f_local`` with a local-space box outside which
``f_local > 0``, a material, an optional declared Lipschitz bound and a similarity transform (translate,
rotate as Euler degrees ``R = Rz·Ry·Rx`` exactly as :mod:`ssbench.scenes.transforms`, uniform scale
``s > 0``). Its world field is::

    f_world(p) = s · f_local(Rᵀ (p − T) / s)

A uniform scale keeps a distance bound a distance bound, so the declared λ holds unchanged in world space.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Optional, Sequence

import torch

from ..scenes.model import Material
from ..vec3 import Vec3, vec3
from .bounds import check_bounds
from ..scenes.transforms import rotate4

Box = tuple[Vec3, Vec3]


def expression_key(expr: Any) -> str:
    """A canonical string for an expression: its scalar tree and parameter values (not its spelling)."""
    node = getattr(expr, "node", None)
    if node is None:
        return repr(expr)
    return repr(node) + "|" + repr(sorted((str(k), float(v)) for k, v in dict(getattr(expr, "params", ())).items()))


def _down(x: torch.Tensor) -> torch.Tensor:
    return torch.nextafter(x, torch.full_like(x, -math.inf))


def _up(x: torch.Tensor) -> torch.Tensor:
    return torch.nextafter(x, torch.full_like(x, math.inf))


@dataclass(frozen=True)
class ImplicitObject:
    """One implicit object (see the module docstring for its world field).

    Attributes:
        expression: ``f_local``, a parsed :class:`~ssbench.implicit.expression.Expression` (or anything with
            ``__call__``, ``interval`` and ``drjit``).
        bounds: local AABB ``((x0, y0, z0), (x1, y1, z1))``, ``lo < hi``, outside which ``f_local > 0``;
            f > 0 on its faces is proved at construction (:func:`~ssbench.implicit.bounds.check_bounds`,
            :class:`~ssbench.implicit.bounds.BoundsError` otherwise).
        lipschitz: declared bound on ``|∇f|`` (None: none declared); unchanged by the uniform scale.
        translate, rotate, scale: ``T``, Euler degrees of ``R = Rz·Ry·Rx``, uniform ``s > 0``.
        where: ``file:line`` of the definition (not compared).
        verify_bounds: prove ``bounds`` honest at construction (default). ``False`` only for fields that are
            never traced (unit tests of the field algebra on unbounded fields such as ``x``); scene files and
            the catalog always verify.

    Example:
        >>> from ssbench.implicit.expression import parse
        >>> ball = ImplicitObject("ball", parse("length(p) - 1"), bounds=((-1.2, -1.2, -1.2), (1.2, 1.2, 1.2)),
        ...                       lipschitz=1.0, translate=(2, 0, 0), scale=0.5)      # radius 0.5 at x = 2
        >>> ball.f(torch.tensor([[2.0, 0.0, 0.0], [3.0, 0.0, 0.0]], dtype=torch.float64)).tolist()
        [-0.5, 0.5]
        >>> [[round(v, 12) for v in corner] for corner in ball.world_bounds]    # padded by ~1e-15 outward
        [[1.4, -0.6, -0.6], [2.6, 0.6, 0.6]]
    """

    id: str
    expression: Any
    bounds: Box
    material: Material = Material()
    lipschitz: Optional[float] = None
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate: Vec3 = (0.0, 0.0, 0.0)
    scale: float = 1.0
    where: str = field(default="", compare=False)
    verify_bounds: bool = field(default=True, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.bounds, (tuple, list)) or len(self.bounds) != 2:
            raise ValueError(f"bounds: expected ((x0, y0, z0), (x1, y1, z1)), got {self.bounds!r}")
        lo, hi = (vec3(b, "bounds") for b in self.bounds)
        if not all(a < b for a, b in zip(lo, hi)):
            raise ValueError(f"bounds: every lower corner component must be < the upper one, got {lo}, {hi}")
        object.__setattr__(self, "bounds", (lo, hi))
        object.__setattr__(self, "translate", vec3(self.translate, "translate"))
        object.__setattr__(self, "rotate", vec3(self.rotate, "rotate"))
        s = float(self.scale)
        if not (math.isfinite(s) and s > 0):
            raise ValueError(f"scale: must be a finite number > 0 (uniform scale), got {self.scale!r}")
        object.__setattr__(self, "scale", s)
        if self.lipschitz is not None:
            lam = float(self.lipschitz)
            if not (math.isfinite(lam) and lam > 0):
                raise ValueError(f"lipschitz: must be a finite number > 0 or None, got {self.lipschitz!r}")
            object.__setattr__(self, "lipschitz", lam)
        if self.verify_bounds:
            check_bounds(self.expression, self.bounds, self.id)      # f > 0 on the box faces, or BoundsError

    # ------------------------------------------------------------------ transform
    @cached_property
    def rotation(self) -> tuple[Vec3, Vec3, Vec3]:
        """The 3×3 rotation ``R`` (rows), local → world."""
        m = rotate4(self.rotate)
        return tuple(tuple(float(m[i][j]) for j in range(3)) for i in range(3))  # type: ignore[return-value]

    @property
    def _rotated(self) -> bool:
        return any(a != 0.0 for a in self.rotate)

    def to_local(self, p: torch.Tensor) -> torch.Tensor:
        """Local coordinates ``Rᵀ (p − T) / s`` of world points ``p`` (..., 3)."""
        q = p
        if any(self.translate):
            q = q - torch.tensor(self.translate, dtype=p.dtype, device=p.device)
        if self._rotated:
            q = q @ torch.tensor(self.rotation, dtype=p.dtype, device=p.device)   # row vector · R = (Rᵀ q)ᵀ
        return q / self.scale if self.scale != 1.0 else q

    def f(self, p: torch.Tensor) -> torch.Tensor:
        """World field ``s · f_local(to_local(p))`` of shape ``p.shape[:-1]``."""
        v = self.expression(self.to_local(p))
        return v * self.scale if self.scale != 1.0 else v

    def interval(self, lo: torch.Tensor, hi: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """float64 enclosure of the world field over boxes ``[lo, hi]`` (..., 3); NaN bounds mean unknown.

        The box is mapped to local space by interval arithmetic (``p − T``, then ``Rᵀ·``, then ``/ s``), each
        operation rounded outward with ``nextafter``; a zero matrix entry contributes exactly 0.
        """
        lo, hi = lo.to(torch.float64), hi.to(torch.float64)
        if any(self.translate):
            t = torch.tensor(self.translate, dtype=torch.float64, device=lo.device)
            lo, hi = _down(lo - t), _up(hi - t)
        if self._rotated:
            qlo, qhi = [], []
            for j in range(3):                     # q_j = sum_i R[i][j] d_i
                alo = ahi = None
                for i in range(3):
                    r = self.rotation[i][j]
                    if r == 0.0:
                        continue
                    a, b = (lo[..., i] * r, hi[..., i] * r) if r > 0 else (hi[..., i] * r, lo[..., i] * r)
                    a, b = _down(a), _up(b)
                    alo, ahi = (a, b) if alo is None else (_down(alo + a), _up(ahi + b))
                qlo.append(alo if alo is not None else torch.zeros_like(lo[..., 0]))
                qhi.append(ahi if ahi is not None else torch.zeros_like(lo[..., 0]))
            lo, hi = torch.stack(qlo, -1), torch.stack(qhi, -1)
        if self.scale != 1.0:
            lo, hi = _down(lo / self.scale), _up(hi / self.scale)
        flo, fhi = self.expression.interval(lo, hi)
        if self.scale != 1.0:
            flo, fhi = _down(flo * self.scale), _up(fhi * self.scale)
        return flo, fhi

    def drjit_f(self, x, y, z):
        """The world field on Dr.Jit arrays (same transform, the expression's Dr.Jit evaluator)."""
        if any(self.translate):
            import drjit as dr
            t = [dr.opaque(type(x), v) if dr.is_array_v(x) else v for v in self.translate]   # a moved object:
            x, y, z = x - t[0], y - t[1], z - t[2]                                           # the same kernel
        if self._rotated:
            r = self.rotation
            x, y, z = (r[0][0] * x + r[1][0] * y + r[2][0] * z, r[0][1] * x + r[1][1] * y + r[2][1] * z,
                       r[0][2] * x + r[1][2] * y + r[2][2] * z)
        if self.scale != 1.0:
            x, y, z = x / self.scale, y / self.scale, z / self.scale
        v = self.expression.drjit(x, y, z)
        return v * self.scale if self.scale != 1.0 else v

    @cached_property
    def world_bounds(self) -> Box:
        """AABB of the transformed local box (its 8 corners), padded by a bound on the rounding error."""
        if not self._rotated and self.scale == 1.0 and not any(self.translate):
            return self.bounds
        (x0, y0, z0), (x1, y1, z1) = self.bounds
        r, s, t = self.rotation, self.scale, self.translate
        corners = [(a, b, e) for a in (x0, x1) for b in (y0, y1) for e in (z0, z1)]
        pts = [[t[i] + s * sum(r[i][k] * c[k] for k in range(3)) for i in range(3)] for c in corners]
        pad = [8 * 2.0 ** -52 * max(abs(t[i]) + s * sum(abs(r[i][k] * c[k]) for k in range(3)) for c in corners)
               for i in range(3)]
        lo = tuple(min(q[i] for q in pts) - pad[i] for i in range(3))
        hi = tuple(max(q[i] for q in pts) + pad[i] for i in range(3))
        return lo, hi  # type: ignore[return-value]

    def key_data(self) -> dict:
        """Everything but the material and ``where`` that defines the object, as JSON-able data."""
        return {"id": self.id, "f": expression_key(self.expression), "bounds": self.bounds,
                "lipschitz": self.lipschitz, "translate": self.translate, "rotate": self.rotate, "scale": self.scale}

    def translated(self, offset: Sequence[float]) -> "ImplicitObject":
        """The same object moved by ``offset`` (world units)."""
        o = vec3(offset, "offset")
        return replace(self, translate=tuple(a + b for a, b in zip(self.translate, o)))
