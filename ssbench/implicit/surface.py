"""Implicit objects and their union: the surface every implicit ray caster and the reference consume.

An :class:`ImplicitObject` is a parsed expression ``f_local`` with a local-space box outside which
``f_local > 0``, a material, an optional declared Lipschitz bound and a similarity transform (translate,
rotate as Euler degrees ``R = Rz·Ry·Rx`` exactly as :mod:`ssbench.scenes.transforms`, uniform scale
``s > 0``). Its world field is::

    f_world(p) = s · f_local(Rᵀ (p − T) / s)

A uniform scale keeps a distance bound a distance bound, so the declared λ holds unchanged in world space.
An :class:`ImplicitSurface` is the union ``f = min_i f_i`` and implements the surface protocol of
:mod:`ssbench.passes.implicit.common`.

Evaluation count convention: one call of :meth:`ImplicitSurface.f` on ``n`` points counts as ``n``
evaluations, whatever the number of objects (the union is one function of ``p``); a gradient counts as one.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Optional, Sequence

import torch

from ..scenes.model import Material
from .bounds import check_bounds
from ..scenes.transforms import rotate4

Vec3 = tuple[float, float, float]
Box = tuple[Vec3, Vec3]


def _vec3(v: Sequence[float], name: str) -> Vec3:
    out = tuple(float(x) for x in v)
    if len(out) != 3 or not all(math.isfinite(x) for x in out):
        raise ValueError(f"{name}: expected three finite numbers, got {v!r}")
    return out  # type: ignore[return-value]


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
        lo, hi = (_vec3(b, "bounds") for b in self.bounds)
        if not all(a < b for a, b in zip(lo, hi)):
            raise ValueError(f"bounds: every lower corner component must be < the upper one, got {lo}, {hi}")
        object.__setattr__(self, "bounds", (lo, hi))
        object.__setattr__(self, "translate", _vec3(self.translate, "translate"))
        object.__setattr__(self, "rotate", _vec3(self.rotate, "rotate"))
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
            x, y, z = x - self.translate[0], y - self.translate[1], z - self.translate[2]
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
        o = _vec3(offset, "offset")
        return replace(self, translate=tuple(a + b for a, b in zip(self.translate, o)))


@dataclass(frozen=True)
class ImplicitSurface:
    """The union ``f = min_i f_i`` of implicit objects (the protocol of ``ssbench.passes.implicit.common``).

    One :meth:`f` call on ``n`` points is ``n`` evaluations, whatever the number of objects.

    Example:
        >>> from ssbench.implicit.expression import parse
        >>> ball = lambda i, x: ImplicitObject(i, parse("length(p) - 1"), ((-1.5, -1.5, -1.5), (1.5, 1.5, 1.5)),
        ...                                    lipschitz=1.0, translate=(x, 0, 0))
        >>> s = ImplicitSurface((ball("a", -2.0), ball("b", 2.0)))
        >>> p = torch.tensor([[-2.0, 0, 0], [1.5, 0, 0]], dtype=torch.float64)
        >>> s.f(p).tolist(), s.object_index(p).tolist(), s.lipschitz
        ([-1.0, -0.5], [0, 1], 1.0)
        >>> [[round(v, 12) for v in corner] for corner in s.bounds]
        [[-3.5, -1.5, -1.5], [3.5, 1.5, 1.5]]
    """

    objects: tuple[ImplicitObject, ...]

    def __post_init__(self) -> None:
        objs = tuple(self.objects)
        if not objs or not all(isinstance(o, ImplicitObject) for o in objs):
            raise ValueError("objects: expected a non-empty sequence of ImplicitObject")
        ids = [o.id for o in objs]
        if len(set(ids)) != len(ids):
            raise ValueError(f"objects: duplicate object ids in {ids}")
        object.__setattr__(self, "objects", objs)

    def f(self, p: torch.Tensor) -> torch.Tensor:
        """``min_i f_i(p)``, shape ``p.shape[:-1]``."""
        out = self.objects[0].f(p)
        for o in self.objects[1:]:
            out = torch.minimum(out, o.f(p))
        return out

    def f_and_grad(self, p: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Value and ∇f by autograd; works under ``torch.no_grad()`` and keeps no graph."""
        with torch.enable_grad():
            q = p.detach().requires_grad_(True)
            v = self.f(q)
            if v.requires_grad:
                (g,) = torch.autograd.grad(v.sum(), q, allow_unused=True)
            else:
                g = None
        return v.detach(), (torch.zeros_like(q) if g is None else g.detach())

    def object_index(self, p: torch.Tensor) -> torch.Tensor:
        """Index (into :attr:`objects`) of the object with the smallest f at each point (LongTensor)."""
        if len(self.objects) == 1:
            return torch.zeros(p.shape[:-1], dtype=torch.long, device=p.device)
        return torch.stack([o.f(p) for o in self.objects], -1).argmin(-1)

    def interval(self, lo: torch.Tensor, hi: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """float64 enclosure ``(flo, fhi)`` of f over boxes ``[lo, hi]`` (..., 3); NaN = unknown (propagates)."""
        flo, fhi = self.objects[0].interval(lo, hi)
        for o in self.objects[1:]:
            a, b = o.interval(lo, hi)
            flo, fhi = torch.minimum(flo, a), torch.minimum(fhi, b)
        return flo, fhi

    def drjit_f(self, x, y, z):
        """f on Dr.Jit arrays (union via ``dr.minimum``)."""
        import drjit as dr
        out = self.objects[0].drjit_f(x, y, z)
        for o in self.objects[1:]:
            out = dr.minimum(out, o.drjit_f(x, y, z))
        return out

    @property
    def bounds(self) -> Box:
        """World AABB (union of the objects' world boxes) outside which f > 0."""
        bs = [o.world_bounds for o in self.objects]
        return (tuple(min(b[0][i] for b in bs) for i in range(3)),   # type: ignore[return-value]
                tuple(max(b[1][i] for b in bs) for i in range(3)))

    @property
    def lipschitz(self) -> Optional[float]:
        """Declared bound on |∇f| (max over objects), or None if any object declares none."""
        lams = [o.lipschitz for o in self.objects]
        return None if any(lam is None for lam in lams) else max(lams)  # type: ignore[type-var]

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(o.id for o in self.objects)

    @property
    def materials(self) -> tuple[Material, ...]:
        return tuple(o.material for o in self.objects)

    def index(self, obj_id: str) -> int:
        """Position of object ``obj_id`` in :attr:`objects` (the value :meth:`object_index` returns)."""
        for i, o in enumerate(self.objects):
            if o.id == obj_id:
                return i
        raise KeyError(f"obj_id: no implicit object named {obj_id!r} (objects: {', '.join(self.ids)})")

    def cache_key(self) -> str:
        """SHA-256 of the geometry (expressions, parameters, bounds, λ, transforms; not the materials)."""
        blob = json.dumps([o.key_data() for o in self.objects], sort_keys=True).encode()
        return hashlib.sha256(blob).hexdigest()

    def translated(self, obj_id: str, offset: Sequence[float]) -> "ImplicitSurface":
        """A new surface with object ``obj_id`` moved by ``offset`` (for animation)."""
        i = self.index(obj_id)
        objs = list(self.objects)
        objs[i] = objs[i].translated(offset)
        return ImplicitSurface(tuple(objs))
