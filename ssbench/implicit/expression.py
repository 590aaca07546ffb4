"""A parsed expression with its parameters and the three evaluators (torch, interval, Dr.Jit).

>>> e = parse("x^2 + y^2 + z^2 - r^2", params={"r": 1.0})
>>> p = torch.tensor([[0.0, 0.0, 2.0], [0.5, 0.0, 0.0]], dtype=torch.float64)
>>> e(p)
tensor([ 3.0000, -0.7500], dtype=torch.float64)
>>> e.with_params(r=2.0)(p)
tensor([ 0.0000, -3.7500], dtype=torch.float64)
>>> f, g = e.f_and_grad(p)
>>> g[0]
tensor([0., 0., 4.], dtype=torch.float64)
>>> e.n_ops
11
>>> parse("length(p - c) - 1", defs={"c": "vec3(1, 0, 0)"})(p)
tensor([ 1.2361, -0.5000], dtype=torch.float64)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Mapping, Optional

from .ast import Node, count_nodes
from .parser import ExpressionError, parse_node
from .torch_eval import evaluate, f_and_grad

__all__ = ["Expression", "ExpressionError", "parse"]


@dataclass(frozen=True)
class Expression:
    """Text + parsed tree + default parameter values + definitions. Equal and hashed by
    ``(text, params, defs)``; ``params``/``defs`` are sorted ``(name, value)`` tuples."""
    text: str
    node: Node = field(compare=False, hash=False, repr=False)
    params: tuple = ()
    defs: tuple = ()

    def _params(self, overrides: Optional[Mapping[str, object]]) -> dict:
        merged = dict(self.params)
        for name, value in (overrides or {}).items():
            if name not in merged:
                raise ValueError(f"unknown parameter {name!r}; this expression has: "
                                 f"{', '.join(merged) or 'no parameters'}")
            merged[name] = value
        return merged

    def __call__(self, p, params: Optional[Mapping[str, object]] = None):
        """f at ``p`` (tensor ``(..., 3)``); ``params`` overrides the stored values (floats or tensors)."""
        return evaluate(self.node, p, self._params(params))

    def f_and_grad(self, p, params: Optional[Mapping[str, object]] = None):
        """``(f(p), ∇f(p))``, detached (see :func:`ssbench.implicit.torch_eval.f_and_grad`)."""
        return f_and_grad(self.node, p, self._params(params))

    def interval(self, lo, hi, params: Optional[Mapping[str, object]] = None):
        """Bounds of f over the boxes ``[lo, hi]``: :func:`ssbench.implicit.interval.interval_eval`."""
        from .interval import interval_eval
        return interval_eval(self.node, lo, hi, params=self._params(params))

    def drjit(self, x, y, z, params: Optional[Mapping[str, object]] = None):
        """f with Dr.Jit operations: :func:`ssbench.implicit.drjit_eval.evaluate_drjit`."""
        from .drjit_eval import evaluate_drjit
        return evaluate_drjit(self.node, x, y, z, self._params(params))

    def with_params(self, **values: float) -> "Expression":
        """A copy with some parameter values changed (no re-parse); an unknown name is a ``ValueError``."""
        merged = self._params(values)
        return replace(self, params=_clean_params(merged))

    @property
    def n_ops(self) -> int:
        """Nodes in the lowered tree (leaves included, shared definitions counted at every use)."""
        return count_nodes(self.node)


def _clean_params(params: Mapping[str, object]) -> tuple:
    out = []
    for name, value in params.items():
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"parameter {name!r} must be a number, got {value!r}") from None
        if not math.isfinite(v):
            raise ValueError(f"parameter {name!r} must be finite, got {v}")
        out.append((name, v))
    return tuple(sorted(out))


def parse(text: str, params: Optional[Mapping[str, float]] = None, defs: Optional[Mapping[str, str]] = None,
          where: str = "<expr>") -> Expression:
    """Parse ``text`` (see :mod:`ssbench.implicit.parser`) into an :class:`Expression`."""
    params, defs = dict(params or {}), dict(defs or {})
    node = parse_node(text, params, defs, where)
    return Expression(text, node, _clean_params(params), tuple(sorted(defs.items())))
