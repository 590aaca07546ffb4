"""Batched PyTorch evaluation of the scalar tree (values, and gradients by autograd).

The tree is flattened once into a :class:`Schedule` (post-order, iterative, shared sub-trees visited once, keyed
by ``id(node)`` — nodes are never hashed, which would be quadratic on deep trees) and each slot is freed after
its last use. Semantics are torch's, in ``p``'s dtype and device: ``sqrt`` of a negative number is NaN,
``log 0 = -inf``, ``min``/``max`` propagate NaN, ``Binary pow`` is ``torch.pow`` (C ``pow``: ``0^0.5 = 0``,
``(-2)^3.0 = -8``, ``(-2)^0.5 = NaN``), ``PowI`` is repeated squaring (``x^0 = 1``, ``x^-n = 1/x^n``).

>>> from ssbench.implicit.parser import parse_node
>>> p = torch.tensor([[3.0, 4.0, 0.0], [0.0, 0.0, 2.0]], dtype=torch.float64)
>>> evaluate(parse_node("sqrt(x^2 + y^2 + z^2) - r", params={"r": 1}), p, {"r": 1.0})
tensor([4., 1.], dtype=torch.float64)
>>> f, g = f_and_grad(parse_node("x*y + z^3"), p)
>>> g
tensor([[ 4.,  3.,  0.],
        [ 0.,  0., 12.]], dtype=torch.float64)
"""
from __future__ import annotations

from typing import Mapping, NamedTuple, Optional

import torch

from .ast import Binary, Node, Num, Param, PowI, Unary, Var, children


class Schedule(NamedTuple):
    """Post-order list of the distinct nodes; ``args[i]`` are the slots of node i's children, ``free[i]`` the
    slots whose last use is node i. The root is the last slot."""
    nodes: tuple
    args: tuple
    free: tuple


_SCHEDULES: dict = {}      # id(root) -> (root, Schedule); holding root keeps the id valid


def schedule(node: Node) -> Schedule:
    """Flatten ``node`` (iteratively; memoised per root object)."""
    hit = _SCHEDULES.get(id(node))
    if hit is not None and hit[0] is node:
        return hit[1]
    index, order, args = {}, [], []
    stack = [(node, False)]
    while stack:
        cur, ready = stack.pop()
        if id(cur) in index:
            continue
        kids = children(cur)
        if ready:
            index[id(cur)] = len(order)
            order.append(cur)
            args.append(tuple(index[id(c)] for c in kids))
        else:
            stack.append((cur, True))
            stack.extend((c, False) for c in reversed(kids) if id(c) not in index)
    last = [-1] * len(order)
    for i, a in enumerate(args):
        for j in a:
            last[j] = i
    free = [[] for _ in order]
    for j, i in enumerate(last):
        if i >= 0:
            free[i].append(j)
    out = Schedule(tuple(order), tuple(args), tuple(tuple(f) for f in free))
    if len(_SCHEDULES) >= 256:
        _SCHEDULES.clear()
    _SCHEDULES[id(node)] = (node, out)
    return out


def pow_abs_int(a, n: int):
    """``a ** |n|`` by repeated squaring with ``*`` only (the same multiplications in every evaluator)."""
    m, result, base = abs(n), None, a
    while m:
        if m & 1:
            result = base if result is None else result * base
        m >>= 1
        if m:
            base = base * base
    return result


_UNARY = {"neg": torch.neg, "abs": torch.abs, "sqrt": torch.sqrt, "exp": torch.exp, "log": torch.log,
          "sin": torch.sin, "cos": torch.cos, "square": torch.square}
_BINARY = {"add": torch.add, "sub": torch.sub, "mul": torch.mul, "div": torch.div, "min": torch.minimum,
           "max": torch.maximum, "pow": torch.pow}


def missing_param(name: str, params: Mapping) -> ValueError:
    given = ", ".join(sorted(params)) or "none"
    return ValueError(f"missing value for parameter {name!r} (given: {given})")


def evaluate(node: Node, p: torch.Tensor, params: Optional[Mapping[str, object]] = None) -> torch.Tensor:
    """f at points ``p`` (shape ``(..., 3)``) → shape ``(...)``, in ``p``'s dtype and device.

    ``params`` maps names to floats or tensors (broadcast against ``p[..., 0]``; gradients flow into tensors
    that require them). A parameter the tree uses but ``params`` lacks is a ``ValueError`` naming it.
    """
    if not isinstance(p, torch.Tensor) or p.dim() == 0 or p.shape[-1] != 3:
        raise ValueError(f"p must be a tensor of shape (..., 3), got {getattr(p, 'shape', type(p).__name__)}")
    if not p.is_floating_point():
        raise TypeError(f"p must be a floating-point tensor, got {p.dtype}")
    params = params or {}
    opts = {"dtype": p.dtype, "device": p.device}
    xyz = dict(zip(("x", "y", "z"), p.unbind(-1)))
    sched = schedule(node)
    vals = [None] * len(sched.nodes)
    for i, nd in enumerate(sched.nodes):
        a = [vals[j] for j in sched.args[i]]
        if isinstance(nd, Unary):
            v = _UNARY[nd.op](a[0])
        elif isinstance(nd, Binary):
            v = _BINARY[nd.op](a[0], a[1])
        elif isinstance(nd, PowI):
            v = torch.ones_like(a[0]) if nd.n == 0 else pow_abs_int(a[0], nd.n)
            v = torch.reciprocal(v) if nd.n < 0 else v
        elif isinstance(nd, Var):
            v = xyz[nd.name]
        elif isinstance(nd, Num):
            v = torch.tensor(float(nd.value), **opts)
        elif isinstance(nd, Param):
            if nd.name not in params:
                raise missing_param(nd.name, params)
            w = params[nd.name]
            v = w.to(**opts) if isinstance(w, torch.Tensor) else torch.tensor(float(w), **opts)
        else:
            raise TypeError(f"not an expression node: {type(nd).__name__}")
        vals[i] = v
        for j in sched.free[i]:
            vals[j] = None
    out, shape = vals[-1], p.shape[:-1]
    if out.shape != shape:
        out = out.expand(torch.broadcast_shapes(out.shape, shape)).clone()
    return out


def f_and_grad(node: Node, p: torch.Tensor, params: Optional[Mapping[str, object]] = None
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """``(f(p), ∇f(p))`` with ∇ taken with respect to ``p`` by autograd; works under ``torch.no_grad()``.

    Both results are detached (no graph is kept). Where f does not depend on p the gradient is 0.
    """
    if isinstance(p, torch.Tensor) and not p.is_floating_point():
        raise TypeError(f"p must be a floating-point tensor, got {p.dtype}")
    with torch.enable_grad():
        q = p.detach().requires_grad_(True)
        f = evaluate(node, q, params)
        g = None
        if f.requires_grad:
            (g,) = torch.autograd.grad(f.sum(), q, allow_unused=True)
    return f.detach(), (torch.zeros_like(q) if g is None else g).detach()
