"""The scalar expression tree shared by every evaluator (torch, interval, Dr.Jit).

The parser (``parser.py``) type-checks vector expressions (``p``, ``vec3(...)``, ``length``, ``dot``) and
*lowers* them to scalars, and lowers the helpers (``clamp``, ``smin``, ``union``, ...) to primitives, so an
evaluator only has to know the small, closed set of operations below. Nodes are frozen and hashable, so an
expression can key a cache.

Operations (``Unary.op`` / ``Binary.op``):

=========  ===============================  ================================================
kind       ops                              meaning
=========  ===============================  ================================================
Unary      ``neg abs sqrt exp log sin cos   −a, |a|, √a, eᵃ, ln a, sin a, cos a, a²
           square``
Binary     ``add sub mul div min max pow``  a+b, a−b, a·b, a/b, min, max, aᵇ (real b; a > 0)
PowI       integer power ``a ** n``         ``n`` a Python int, ``|n| <= MAX_INT_POWER``
=========  ===============================  ================================================

Domain rules every evaluator follows: ``sqrt``/``log`` of a negative number, ``log 0`` → −inf,
``pow`` follows ``torch.pow`` (C ``pow``: ``0^0.5 = 0``, ``(−2)^3.0 = −8``, ``(−2)^0.5 = NaN``), division by 0
→ ±inf/NaN as IEEE says. The interval
evaluator returns NaN bounds wherever a domain error is *possible* (never a clamped bound).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Union

#: variables of the scalar tree (``p`` is lowered to these)
VARIABLES = ("x", "y", "z")
UNARY_OPS = ("neg", "abs", "sqrt", "exp", "log", "sin", "cos", "square")
BINARY_OPS = ("add", "sub", "mul", "div", "min", "max", "pow")
#: largest |n| accepted for an integer power (``x^n``); larger exponents are refused by the parser
MAX_INT_POWER = 64


@dataclass(frozen=True)
class Num:
    """A finite float constant."""
    value: float


@dataclass(frozen=True)
class Var:
    """One of ``x``, ``y``, ``z`` (world-space coordinates of the evaluated point)."""
    name: str


@dataclass(frozen=True)
class Param:
    """A named parameter whose value is supplied at evaluation time (float or tensor)."""
    name: str


@dataclass(frozen=True)
class Unary:
    op: str
    arg: "Node"


@dataclass(frozen=True)
class Binary:
    op: str
    left: "Node"
    right: "Node"


@dataclass(frozen=True)
class PowI:
    """``arg ** n`` for a constant integer ``n`` (odd: monotone; even: like ``square``)."""
    arg: "Node"
    n: int


Node = Union[Num, Var, Param, Unary, Binary, PowI]


def children(node: Node) -> tuple:
    """The direct sub-nodes of ``node``."""
    if isinstance(node, Unary):
        return (node.arg,)
    if isinstance(node, Binary):
        return (node.left, node.right)
    if isinstance(node, PowI):
        return (node.arg,)
    return ()


def count_nodes(node: Node) -> int:
    """Number of nodes (operations + leaves) in the tree, iteratively (trees may be deep)."""
    n, stack = 0, [node]
    while stack:
        cur = stack.pop()
        n += 1
        stack.extend(children(cur))
    return n


def params_used(node: Node) -> frozenset:
    """Names of the :class:`Param` leaves in the tree."""
    out, stack = set(), [node]
    while stack:
        cur = stack.pop()
        if isinstance(cur, Param):
            out.add(cur.name)
        stack.extend(children(cur))
    return frozenset(out)
