"""Typed lowering of parsed values to scalar trees (:mod:`ssbench.implicit.ast`): what the functions and operators of
the expression language *mean*, apart from the grammar that reads them (:mod:`ssbench.implicit.parser`).

A value is a scalar node or a 3-tuple of them (a vector). :class:`Lowering` applies operators elementwise with
scalar broadcasting (``lift1``/``lift2``), type-checks vector-only and scalar-only functions, expands
``length``, ``dot``, ``clamp``, ``subtract`` and the quadratic ``smin`` into scalar trees, picks the power node
(``square``, ``PowI``, ``Binary pow``) and folds constant subexpressions when the result is finite. Every node it
makes is counted with repetition (``mk``), so a tree over :data:`MAX_NODES` — shared definitions expanded — is
refused. It is a mixin: the host (the parser) provides ``err(col, message)`` (raises) and ``ctx.sizes``.
"""
from __future__ import annotations

import math

from .ast import MAX_INT_POWER, Binary, Num, PowI, Unary, children

__all__ = ["Lowering", "MAX_NODES", "MAX_REAL_POWER"]

MAX_NODES = 100_000
MAX_REAL_POWER = 64.0
_ELEMENTWISE = ("abs", "sqrt", "exp", "log", "sin", "cos", "square")
_FOLD = {"neg": lambda a: -a, "abs": abs, "sqrt": math.sqrt, "exp": math.exp, "log": math.log, "sin": math.sin,
         "cos": math.cos, "square": lambda a: a * a, "add": lambda a, b: a + b, "sub": lambda a, b: a - b,
         "mul": lambda a, b: a * b, "div": lambda a, b: a / b, "min": min, "max": max, "pow": math.pow}


def _fold(op, *vals):
    try:
        r = _FOLD[op](*vals) if isinstance(op, str) else op(*vals)
    except (ArithmeticError, ValueError):
        return None
    return float(r) if isinstance(r, (int, float)) and math.isfinite(r) else None


class Lowering:
    """Mixin: typed, folded, counted construction of scalar trees (see the module docstring)."""

    def scalar(self, v, f, col, k=None):
        if isinstance(v, tuple):
            self.err(col, f"{f}: expected a scalar, got a vector" + (f" (argument {k})" if k else ""))
        return v

    def vector(self, v, f, col, k=None):
        if not isinstance(v, tuple):
            self.err(col, f"{f}: expected a vector, got a scalar" + (f" (argument {k})" if k else ""))
        return v

    def apply(self, f, a, col):
        if f in _ELEMENTWISE:
            return self.lift1(f, a[0], col)
        if f in ("min", "max", "union", "intersect"):
            op = "min" if f in ("min", "union") else "max"
            if f in ("union", "intersect"):
                a = [self.scalar(v, f, col, k + 1) for k, v in enumerate(a)]
            v = a[0]
            for b in a[1:]:
                v = self.lift2(op, v, b, col)
            return v
        if f == "clamp":
            return self.lift2("min", self.lift2("max", a[0], a[1], col), a[2], col)
        if f == "pow":
            return self.power(a[0], a[1], col, "pow")
        if f == "vec3":
            return tuple(self.scalar(v, f, col, k + 1) for k, v in enumerate(a))
        if f == "length":
            v = self.vector(a[0], f, col)
            return self.un("sqrt", self.sum3([self.un("square", c, col) for c in v], col), col)
        if f == "dot":
            u, v = self.vector(a[0], f, col, 1), self.vector(a[1], f, col, 2)
            return self.sum3([self.bin("mul", s, t, col) for s, t in zip(u, v)], col)
        s = [self.scalar(v, f, col, k + 1) for k, v in enumerate(a)]
        if f == "subtract":
            return self.bin("max", s[0], self.un("neg", s[1], col), col)
        x, y, k = s        # smin
        if isinstance(k, Num) and not k.value > 0:
            self.err(col, f"smin: k must be > 0, got {k.value:g}")
        h = self.bin("div", self.bin("max", self.bin("sub", k, self.un("abs", self.bin("sub", x, y, col), col), col),
                                     self.mk(Num(0.0), col), col), k, col)
        corr = self.bin("mul", self.bin("mul", self.un("square", h, col), k, col), self.mk(Num(0.25), col), col)
        return self.bin("sub", self.bin("min", x, y, col), corr, col)

    def sum3(self, terms, col):
        return self.bin("add", self.bin("add", terms[0], terms[1], col), terms[2], col)

    def power(self, base, e, col, sym):
        if isinstance(base, tuple) or isinstance(e, tuple):
            self.err(col, f"{sym}: expected scalars, got a vector")
        if isinstance(e, Num):
            v = e.value
            if v == int(v):
                n = int(v)
                if abs(n) > MAX_INT_POWER:
                    self.err(col, f"exponent too large: {v:.17g} (integer powers are limited to ±{MAX_INT_POWER})")
                if isinstance(base, Num) and (r := _fold(lambda a: a ** n, base.value)) is not None:
                    return self.mk(Num(r), col)
                return self.un("square", base, col) if n == 2 else self.mk(PowI(base, n), col)
            if abs(v) > MAX_REAL_POWER:
                self.err(col, f"exponent too large: {v:g} (real powers are limited to ±{MAX_REAL_POWER:g})")
        return self.bin("pow", base, e, col)

    def lift1(self, op, a, col):
        return tuple(self.un(op, c, col) for c in a) if isinstance(a, tuple) else self.un(op, a, col)

    def lift2(self, op, a, b, col):
        if isinstance(a, tuple) or isinstance(b, tuple):
            a3 = a if isinstance(a, tuple) else (a, a, a)
            b3 = b if isinstance(b, tuple) else (b, b, b)
            return tuple(self.bin(op, u, v, col) for u, v in zip(a3, b3))
        return self.bin(op, a, b, col)

    def un(self, op, a, col):
        if isinstance(a, Num) and (r := _fold(op, a.value)) is not None:
            return self.mk(Num(r), col)
        return self.mk(Unary(op, a), col)

    def bin(self, op, a, b, col):
        if isinstance(a, Num) and isinstance(b, Num) and (r := _fold(op, a.value, b.value)) is not None:
            return self.mk(Num(r), col)
        return self.mk(Binary(op, a, b), col)

    def mk(self, node, col):
        sizes = self.ctx.sizes      # id -> (node, tree size); holding the node keeps its id unique
        size = 1 + sum(sizes.get(id(c), (None, 1))[1] for c in children(node))
        if size > MAX_NODES:
            self.err(col, f"expression too large (more than {MAX_NODES} nodes once vectors and definitions "
                          "are expanded)")
        sizes[id(node)] = (node, size)
        return node
