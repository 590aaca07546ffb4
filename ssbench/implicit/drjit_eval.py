"""Dr.Jit evaluation of the scalar tree: the same operations as :mod:`ssbench.implicit.torch_eval`.

``x, y, z`` may be Dr.Jit arrays of any floating type (``drjit.llvm.Float64``, ``mi.Float``, ...) or plain
Python floats (``drjit.scalar.Float`` *is* ``float``). There is no Python branching on array values, so
:func:`evaluate_drjit` can be traced inside ``dr.while_loop`` / ``dr.if_stmt`` symbolic code. Semantics match
the torch evaluator: ``sqrt`` of a negative number is NaN, ``log 0 = -inf``, ``min``/``max`` propagate NaN,
division follows IEEE (also for Python floats, which would otherwise raise), ``PowI`` uses the same repeated
squaring, and ``Binary pow`` follows C ``pow`` / ``torch.pow`` — on arrays ``dr.power`` is ``exp2(b·log2 a)``,
so the sign, zero, one and infinity cases are patched with ``dr.select``.

drjit is imported lazily, after :func:`ssbench.reference.backend.mitsuba` has chosen the libLLVM (unless
drjit was already imported by the caller).
"""
from __future__ import annotations

import math
import sys
from typing import Mapping, Optional

from .ast import Binary, Node, Num, Param, PowI, Unary, Var
from .torch_eval import missing_param, pow_abs_int, schedule


def _drjit():
    if "drjit" not in sys.modules:
        from ssbench.reference import backend
        backend.mitsuba()
    import drjit
    return drjit


def _div(dr, a, b):
    if dr.is_array_v(a) or dr.is_array_v(b):
        return a / b
    a, b = float(a), float(b)
    if b != 0.0:
        return a / b
    if a != a or a == 0.0:
        return math.nan
    return math.copysign(math.inf, a) * math.copysign(1.0, b)


def _pow(dr, a, b):
    """C ``pow(a, b)`` elementwise."""
    if not (dr.is_array_v(a) or dr.is_array_v(b)):
        return float(dr.power(float(a), float(b)))          # std::pow
    t = type(a) if dr.is_array_v(a) else type(b)
    a, b = t(a), t(b)
    m = dr.abs(a)
    r = dr.power(m, b)                                      # exact domain: m > 0, finite b
    is_int = dr.floor(b) == b
    odd = is_int & (dr.abs(b) < 2.0 ** 53) & (b - 2.0 * dr.floor(0.5 * b) == 1.0)
    r = dr.select(odd & (dr.copysign(t(1.0), a) < 0.0), -r, r)
    r = dr.select((a < 0.0) & dr.isfinite(a) & ~is_int, math.nan, r)
    return dr.select((b == 0.0) | (a == 1.0) | ((m == 1.0) & dr.isinf(b)), 1.0, r)


def _unary(dr, op, a):
    if op == "neg":
        return -a
    if op == "square":
        return a * a
    fn = {"abs": dr.abs, "sqrt": dr.sqrt, "exp": dr.exp, "log": dr.log, "sin": dr.sin, "cos": dr.cos}[op]
    return fn(a)


def _binary(dr, op, a, b):
    if op == "add":
        return a + b
    if op == "sub":
        return a - b
    if op == "mul":
        return a * b
    if op == "div":
        return _div(dr, a, b)
    if op == "min":
        return dr.minimum(a, b)
    if op == "max":
        return dr.maximum(a, b)
    if op == "pow":
        return _pow(dr, a, b)
    raise ValueError(f"unknown binary operation {op!r}")


def evaluate_drjit(node: Node, x, y, z, params: Optional[Mapping[str, object]] = None):
    """f at ``(x, y, z)`` with Dr.Jit operations; the result has the array type (and width) of the inputs.

    ``params`` maps names to floats or Dr.Jit arrays; a missing one is a ``ValueError`` naming it.
    """
    dr = _drjit()
    params = params or {}
    xyz = {"x": x, "y": y, "z": z}
    sched = schedule(node)
    vals = [None] * len(sched.nodes)
    for i, nd in enumerate(sched.nodes):
        a = [vals[j] for j in sched.args[i]]
        if isinstance(nd, Unary):
            v = _unary(dr, nd.op, a[0])
        elif isinstance(nd, Binary):
            v = _binary(dr, nd.op, a[0], a[1])
        elif isinstance(nd, PowI):
            one = type(a[0])(1.0) if dr.is_array_v(a[0]) else 1.0
            v = one if nd.n == 0 else pow_abs_int(a[0], nd.n)
            v = _div(dr, one, v) if nd.n < 0 else v
        elif isinstance(nd, Var):
            v = xyz[nd.name]
        elif isinstance(nd, Num):
            v = float(nd.value)
        elif isinstance(nd, Param):
            if nd.name not in params:
                raise missing_param(nd.name, params)
            w = params[nd.name]
            v = w if dr.is_array_v(w) else float(w)
        else:
            raise TypeError(f"not an expression node: {type(nd).__name__}")
        vals[i] = v
        for j in sched.free[i]:
            vals[j] = None
    out = vals[-1]
    arrays = [v for v in (x, y, z) if dr.is_array_v(v)]
    if arrays:
        width = max(dr.width(v) for v in arrays)
        if not dr.is_array_v(out):
            out = dr.full(type(arrays[0]), out, width)
        elif dr.width(out) != width:
            out = dr.zeros(type(out), width) + out
    elif not dr.is_array_v(out):
        out = float(out)
    return out
