"""Whitelist recursive-descent parser: expression text → scalar tree (:mod:`ssbench.implicit.ast`).

Nothing here calls ``eval``/``exec``/``compile``: the text is tokenised by hand (numbers, ASCII names,
``+ - * / ^ ** ( ) ,``) and any other character is an :class:`ExpressionError` naming it and its column.

Grammar, loosest first: ``+ -`` < ``* /`` < unary ``- +`` < ``^``/``**`` (right-associative), so
``-x^2 = -(x^2)`` and ``2^3^2 = 2^9``. Names: variables ``x y z``, the vector ``p = (x, y, z)``, the constant
``pi``, named parameters (kept as :class:`~ssbench.implicit.ast.Param`), definitions (name → text, scalar or
vector, parsed once and shared) and the functions in :data:`FUNCTIONS`. Values are scalars or 3-vectors;
vectors are lowered to three scalar trees here, so every evaluator sees scalars only. ``+ - * /``, unary
minus, ``abs sqrt exp log sin cos square min max clamp`` work elementwise and broadcast a scalar against a
vector; ``length``/``dot`` need vectors; ``^ pow smin union intersect subtract`` need scalars.

``smin(a, b, k)`` is the quadratic polynomial smooth minimum: ``h = max(k − |a−b|, 0)/k``,
``smin = min(a, b) − h²·k/4`` (equal to ``min`` when ``|a−b| ≥ k``; ``k`` must be > 0).
``union/intersect(a, b, ...)`` are ``min/max``; ``subtract(a, b) = max(a, −b)``.

A constant integer exponent ``n`` becomes ``square`` (n = 2) or ``PowI`` (|n| ≤ 64); a constant real one
``Binary pow`` (|e| ≤ 64); anything else ``Binary pow``. Constant subexpressions are folded when the result is
finite (``9^9^9`` folds ``9^9`` and then refuses the exponent 387420489). Limits: :data:`MAX_TEXT` characters,
:data:`MAX_DEPTH` nesting levels (an explicit counter, never a ``RecursionError``), :data:`MAX_NODES` tree
nodes after lowering (counted with repetition, so shared definitions cannot blow up an evaluator).

>>> parse_node("-x^2")
Unary(op='neg', arg=Unary(op='square', arg=Var(name='x')))
>>> parse_node("2^3^2")
Num(value=512.0)
>>> parse_node("x.__class__")
Traceback (most recent call last):
...
ssbench.implicit.lexer.ExpressionError: <expr>: column 2: attribute access is not allowed
  x.__class__
   ^
"""
from __future__ import annotations

import math
import re
from typing import Mapping, Optional

from .ast import VARIABLES, Node, Num, Param, Var
from .lexer import ExpressionError, tokenize
from .lowering import MAX_NODES, MAX_REAL_POWER, Lowering

__all__ = ["parse_node", "ExpressionError", "FUNCTIONS", "CONSTANTS", "MAX_TEXT", "MAX_DEPTH", "MAX_NODES",
           "MAX_REAL_POWER"]

MAX_TEXT = 20_000
MAX_DEPTH = 100
CONSTANTS = {"pi": math.pi}
#: name → (fewest, most) arguments; ``None``: any number
FUNCTIONS = {"abs": (1, 1), "sqrt": (1, 1), "exp": (1, 1), "log": (1, 1), "sin": (1, 1), "cos": (1, 1),
             "square": (1, 1), "min": (2, None), "max": (2, None), "pow": (2, 2), "length": (1, 1),
             "dot": (2, 2), "clamp": (3, 3), "smin": (3, 3), "vec3": (3, 3), "union": (2, None),
             "intersect": (2, None), "subtract": (2, 2)}
_ARITH = {"+": "add", "-": "sub", "*": "mul", "/": "div"}
class _Ctx:
    """State shared by the main text and the definitions it pulls in."""

    def __init__(self, params, defs, where):
        self.params, self.defs, self.where = {n: Param(n) for n in params}, dict(defs), where
        self.vars = {n: Var(n) for n in VARIABLES}
        self.cache, self.active, self.sizes, self.depth = {}, [], {}, 0


class _Parser(Lowering):
    """The grammar over :func:`~ssbench.implicit.lexer.tokenize`'s tokens; the values it builds go through
    :class:`~ssbench.implicit.lowering.Lowering` (typed, folded, counted)."""

    def __init__(self, text, where, ctx):
        self.text, self.where, self.ctx, self.i = text, where, ctx, 0
        if not isinstance(text, str):
            raise ExpressionError(f"expected a string, got {type(text).__name__}", where)
        if len(text) > MAX_TEXT:
            raise ExpressionError(f"expression too long ({len(text)} characters; the limit is {MAX_TEXT})", where)
        self.toks = tokenize(text)

    # -- tokens and errors -------------------------------------------------------------------------------
    def err(self, col, what):
        raise ExpressionError(what, self.where, col, self.text)

    def peek(self):
        t = self.toks[self.i]
        if t.kind == "bad":
            self.err(t.col, t.text)
        return t

    def is_op(self, *ops):
        t = self.peek()
        return t.kind == "op" and t.text in ops

    def take_op(self, *ops):
        if self.is_op(*ops):
            self.i += 1
            return self.toks[self.i - 1]
        return None

    def expect_close(self, open_col):
        if not self.take_op(")"):
            t = self.peek()
            got = "the end" if t.kind == "end" else repr(t.text)
            self.err(t.col, f"expected ')' to close the '(' at column {open_col}, got {got}")

    def enter(self, col):
        self.ctx.depth += 1
        if self.ctx.depth > MAX_DEPTH:
            self.err(col, f"nested too deeply (more than {MAX_DEPTH} levels of parentheses, calls, signs, "
                          "powers or definitions)")

    def leave(self):
        self.ctx.depth -= 1

    # -- grammar (few Python frames per nesting level: at most ~5 x MAX_DEPTH in all) ------------------
    def parse_all(self):
        v = self.expr()
        t = self.peek()
        if t.kind != "end":
            hint = " (implicit multiplication is not supported; write '*')" if t.kind != "op" or t.text == "(" else ""
            self.err(t.col, f"unexpected {t.text!r} after a complete expression{hint}")
        return v

    def expr(self):
        self.enter(self.peek().col)
        v = self.term()
        while t := self.take_op("+", "-"):
            v = self.lift2(_ARITH[t.text], v, self.term(), t.col)
        self.leave()
        return v

    def term(self):
        v = self.unary()
        while t := self.take_op("*", "/"):
            v = self.lift2(_ARITH[t.text], v, self.unary(), t.col)
        return v

    def unary(self):
        if t := self.take_op("-", "+"):
            self.enter(t.col)
            v = self.unary()
            self.leave()
            return self.lift1("neg", v, t.col) if t.text == "-" else v
        base = self.primary()
        if t := self.take_op("^", "**"):
            self.enter(t.col)
            e = self.unary()           # right-associative; the exponent may carry a sign: 2^-x^2 = 2^(-(x^2))
            self.leave()
            return self.power(base, e, t.col, t.text)
        return base

    def primary(self):
        t = self.peek()
        self.i += 1
        if t.kind == "num":
            return self.mk(Num(t.value), t.col)
        if t.kind == "name":
            if t.text.startswith("_"):
                self.err(t.col, f"names starting with '_' are not allowed ({t.text!r})")
            paren = self.take_op("(")
            return self.call(t, paren.col) if paren else self.name(t)
        if t.kind == "op" and t.text == "(":
            v = self.expr()
            self.expect_close(t.col)
            return v
        self.err(t.col, "expected a number, a name or '(', got " + ("the end" if t.kind == "end" else repr(t.text)))

    def known(self):
        groups = [("variables", "x, y, z, p"), ("constants", ", ".join(CONSTANTS)),
                  ("parameters", ", ".join(sorted(self.ctx.params))), ("definitions", ", ".join(sorted(self.ctx.defs))),
                  ("functions", ", ".join(sorted(FUNCTIONS)))]
        return "; ".join(f"{k}: {v}" for k, v in groups if v)

    def name(self, t):
        s, ctx = t.text, self.ctx
        if s in ctx.vars:
            return ctx.vars[s]
        if s == "p":
            return tuple(ctx.vars[n] for n in VARIABLES)
        if s in CONSTANTS:
            return self.mk(Num(CONSTANTS[s]), t.col)
        if s in ctx.params:
            return ctx.params[s]
        if s in ctx.defs:
            return self.definition(s, t.col)
        if s in FUNCTIONS:
            self.err(t.col, f"{s!r} is a function; call it as {s}(...)")
        self.err(t.col, f"unknown name {s!r}; known: {self.known()}")

    def definition(self, name, col):
        ctx = self.ctx
        if name in ctx.cache:
            return ctx.cache[name]
        if name in ctx.active:
            self.err(col, "definitions form a cycle: " + " -> ".join(ctx.active[ctx.active.index(name):] + [name]))
        ctx.active.append(name)
        self.enter(col)
        text = ctx.defs[name]
        v = _Parser(text, f"{ctx.where}: definition {name!r}", ctx).parse_all()
        self.leave()
        ctx.active.pop()
        ctx.cache[name] = v
        return v

    def call(self, t, open_col):
        f = t.text
        if f not in FUNCTIONS:
            if f in self.ctx.vars or f in ("p", *CONSTANTS) or f in self.ctx.params or f in self.ctx.defs:
                self.err(t.col, f"{f!r} is not a function")
            self.err(t.col, f"unknown function {f!r}; functions: {', '.join(sorted(FUNCTIONS))}")
        args = [] if self.is_op(")") else [self.expr()]
        while args and self.take_op(","):
            args.append(self.expr())
        self.expect_close(open_col)
        lo, hi = FUNCTIONS[f]
        if len(args) < lo or (hi is not None and len(args) > hi):
            want = f"{lo}" if lo == hi else f"at least {lo}"
            self.err(t.col, f"{f}: expected {want} argument{'s' if hi != 1 else ''}, got {len(args)}")
        return self.apply(f, args, t.col)


def _check_names(params, defs, where):
    for kind, names in (("parameter", params), ("definition", defs)):
        for n in names:
            if not isinstance(n, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", n):
                raise ExpressionError(f"{kind} name {n!r} is not a valid name", where)
            if n.startswith("_"):
                raise ExpressionError(f"{kind} name {n!r}: names starting with '_' are not allowed", where)
            clash = ("variable" if n in VARIABLES or n == "p" else "constant" if n in CONSTANTS
                     else "function" if n in FUNCTIONS else None)
            if clash:
                raise ExpressionError(f"{kind} name {n!r} shadows the {clash} {n!r}", where)
    both = sorted(set(params) & set(defs))
    if both:
        raise ExpressionError(f"{both[0]!r} is both a parameter and a definition", where)


def parse_node(text: str, params: Optional[Mapping[str, float]] = None, defs: Optional[Mapping[str, str]] = None,
               where: str = "<expr>") -> Node:
    """Parse ``text`` (which must be scalar-valued) to a scalar tree; raises :class:`ExpressionError`.

    Only the *names* of ``params`` matter here (they stay :class:`~ssbench.implicit.ast.Param` leaves).
    Every definition is parsed (once) and checked, used or not.
    """
    params, defs = dict(params or {}), dict(defs or {})
    _check_names(params, defs, where)
    ctx = _Ctx(params, defs, where)
    top = _Parser(text, where, ctx)
    value = top.parse_all()
    for name in sorted(defs):
        top.definition(name, 1)
    if isinstance(value, tuple):
        top.err(1, "the expression is a vector; f must be a scalar (e.g. length(...) or dot(...))")
    return value
