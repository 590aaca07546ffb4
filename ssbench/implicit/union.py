"""The union of implicit objects, ``f = min_i f_i``: the surface protocol of :mod:`ssbench.passes.implicit.common`
that every implicit ray caster and the certified reference consume.

Evaluation count convention: one call of :meth:`ImplicitSurface.f` on ``n`` points counts as ``n``
evaluations, whatever the number of objects (the union is one function of ``p``); a gradient counts as one.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Optional, Sequence

import torch

from ..scenes.model import Material
from .surface import Box, ImplicitObject

__all__ = ["ImplicitSurface"]


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
