"""Interval arithmetic over the scalar tree (:mod:`ssbench.implicit.ast`): a sound range of f over a box.

A fixed-step marcher can step over a thin piece of surface (the article's punch-through). Interval
arithmetic (Mitchell 1990, Knoll et al. 2009) evaluates f on a whole box or ray segment and returns
``[lo, hi]`` that *provably* contains every value f takes there: if ``0 ∉ [lo, hi]`` the box holds no surface,
otherwise it is split. The proof holds only if every rule below is sound.

**Contract.** An :class:`Interval` is a pair of float64 tensors, ``lo <= hi``. Values are extended reals: a
bound ±inf means "unbounded" and ±inf may itself be a value (``exp(+inf) = +inf``). An op's result encloses
every value it takes at points of its input boxes **in exact arithmetic** (hence also the float64 pointwise
value, under the libm assumption below). The parser's decimal → float conversion and constant folding are
not covered: ``Num(0.1)`` is enclosed as the float it holds.

**Outward rounding.** torch has no rounding modes: each bound is computed to nearest and moved one float
outward with :func:`torch.nextafter` *only where* the exact value may lie outside it (TwoSum for ``+ −``, a
mantissa TwoProduct for ``· /``: :mod:`ssbench.implicit.interval_ops`). Exact results stay exact
(``[1,1] + [2,2] = [3,3]``, a 0 factor gives 0) and sums of non-negative lower bounds stay ``>= 0``, so
``sqrt(x²+y²+z²)`` never turns NaN through rounding. **Library functions:** ``sqrt`` is widened 1 float unless
exact — enough for a *faithful* result (one of the two floats around the exact root), which is what torch's
vectorised float64 ``sqrt`` on the CPU gives: 1.3 % of 2·10⁵ random arguments came out 1 ulp from the correctly
rounded ``math.sqrt`` (never more; short tensors matched), so IEEE 754's correct rounding is not relied on; torch's ``exp log sin cos pow`` (glibc / SLEEF ``u10``)
are only faithful: we *assume* an error ≤ 1 ulp and widen 2 floats (one more, for binade edges), except at
exact points (``exp 0``, ``log 1``, ``sin 0``, ``cos 0``, ``x⁰``, ``1ʸ``), then clamp to the function's range
(``exp sqrt pow >= 0``, trig ``[-1, 1]``): a fact about the function, not a cosmetic clamp.

**NaN = "may be undefined".** If a domain error or an IEEE NaN (``inf − inf``, ``0·inf``, ``0/0``,
``inf/inf``, ``sin(±inf)``) is possible *anywhere* in the box, both bounds are NaN (fidget PR #43); a NaN
input stays NaN through every op, ``min``/``max`` included. No bound is clamped to look nice (MPR's ``log``
returned lower bound 0 for ``lo <= 0``: not an enclosure, and even ``lo > hi``).

==========  ==============================================  ==========================================
op          rule (X = [a, b], Y = [c, d])                   NaN when possible (besides a NaN input)
==========  ==============================================  ==========================================
add, sub    [a+c, b+d], [a−d, b−c]; TwoSum rounding         ``inf − inf``
mul         min / max of the four corner products           ``0·inf`` (0 ∈ one, ±inf end in the other)
div         0 ∉ Y: corners a/c .. b/d; 0 ∈ Y: [−inf, inf]   0 ∈ X and 0 ∈ Y; ±inf ends in both
neg, abs_   [−b, −a]; abs straddling 0: [0, max(−a, b)]     —
square      [0, max(a², b²)] if a ≤ 0 ≤ b, else monotone    —
powi(X, n)  odd n monotone; even n like square; n < 0:      —
            1 / X^|n| (div rule); n = 0: [1, 1]
sqrt, log   monotone; log [0, b] = [−inf, log b]            a < 0
exp         monotone; exp(−inf) = 0, exp(inf) = inf         —
sin, cos    endpoints, ±1 if a crest / trough is in         an infinite end
            [a−m, b+m]; width ≥ 2π or |x| > 1e15: [−1, 1]
pow_        min / max of x^y at the four corners (monotone  a ≤ 0 (a real exponent needs x > 0)
            in x and in y separately when x > 0)
min, max    [min(a, c), min(b, d)], [max(a, c), max(b, d)]  —
==========  ==============================================  ==========================================

Division by an interval containing 0 gives the whole line (as MPR) rather than a ray: with signed zeros
``1/[0, 1]`` is already −inf at −0.0. **sin/cos:** float π is inexact, so a crest ``π/2 + 2kπ`` (sin) or
``2kπ`` (cos) is looked for in the interval widened by ``m = 4ε(max|x| + 2π)``, more than the error of the
float test: a crest just outside loosens the bound, none is missed. **min/max choice:** for disjoint
intervals one operand decides the result on the whole box; ``minimum(x, y, return_choice=True)`` also
returns int8 0/1/2 (left/right/both), which MPR uses to prune the other CSG branch from the tape.

>>> x = as_interval(-1.0, 2.0)
>>> square(x).lo.item(), square(x).hi.item(), mul(x, x).lo.item()   # square knows both factors are equal
(0.0, 4.0, -2.0)
>>> log(as_interval(0.0, 1.0)).lo.item(), log(as_interval(-1.0, 1.0)).lo.item()
(-inf, nan)
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

import torch
from torch import Tensor

from .ast import Binary, Num, Param, PowI, Unary, Var, VARIABLES, children
from .interval_ops import (INF, corners, down, finish, has0, has_inf, ipow_bound, is_exact_root, lower, nan_in,
                           pow_corners, prod_dir, quot_dir, sum_dir, trig_bounds, up, upper)


class Interval(NamedTuple):
    """``[lo, hi]`` elementwise, float64 tensors of one (broadcastable) shape; NaN in both = may be undefined."""
    lo: Tensor
    hi: Tensor


def as_interval(lo, hi=None) -> Interval:
    """Cast to float64, broadcast, check ``lo <= hi``; a NaN in either bound makes both NaN.

    >>> as_interval(1.0).hi.item(), as_interval([0.0, 1.0], 2.0).lo.tolist()
    (1.0, [0.0, 1.0])
    """
    lo = torch.as_tensor(lo, dtype=torch.float64)
    hi = lo if hi is None else torch.as_tensor(hi, dtype=torch.float64)
    lo, hi = torch.broadcast_tensors(lo, hi)
    if bool((lo > hi).any()):
        raise ValueError(f"lo: must be <= hi (lo > hi at {int((lo > hi).sum())} of {lo.numel()} entries)")
    return Interval(*finish(lo, hi, torch.zeros_like(lo, dtype=torch.bool)))


def add(x: Interval, y: Interval) -> Interval:
    """``[a+c, b+d]``, each end rounded only toward where the exact sum lies.

    >>> add(as_interval(1.0), as_interval(2.0))      # exact: not widened
    Interval(lo=tensor(3., dtype=torch.float64), hi=tensor(3., dtype=torch.float64))
    """
    s, below, _ = sum_dir(x.lo, y.lo)
    t, _, above = sum_dir(x.hi, y.hi)
    inf_minus_inf = ((x.lo == -INF) & (y.hi == INF)) | ((x.hi == INF) & (y.lo == -INF))
    return Interval(*finish(lower(s, below), upper(t, above), inf_minus_inf | nan_in(x, y)))


def neg(x: Interval) -> Interval:
    """``[−b, −a]`` (exact)."""
    return Interval(-x.hi, -x.lo)


def sub(x: Interval, y: Interval) -> Interval:
    """``[a−d, b−c]`` = ``add(x, neg(y))`` (negation is exact)."""
    return add(x, neg(y))


def mul(x: Interval, y: Interval) -> Interval:
    """Min / max of ``ac, ad, bc, bd``; NaN where ``0·inf`` is possible.

    >>> mul(as_interval(2.0, 3.0), as_interval(-5.0, 4.0)).lo.item()
    -15.0
    """
    lo, hi = corners(prod_dir, x, y)
    zero_inf = (has0(x) & has_inf(y)) | (has0(y) & has_inf(x))
    return Interval(*finish(lo, hi, zero_inf | nan_in(x, y)))


def div(x: Interval, y: Interval) -> Interval:
    """Corner quotients if ``0 ∉ Y``; the whole line if ``0 ∈ Y`` and ``0 ∉ X``; NaN if ``0/0`` or ``inf/inf``.

    >>> one = as_interval(1.0)
    >>> div(one, as_interval(4.0)).hi.item(), div(one, as_interval(-1.0, 1.0)).lo.item()
    (0.25, -inf)
    """
    y_safe = Interval(*(torch.where(has0(y), torch.ones_like(v), v) for v in torch.broadcast_tensors(*y)))
    lo, hi = corners(quot_dir, x, y_safe)
    whole = has0(y)
    lo, hi = torch.where(whole, -INF, lo), torch.where(whole, INF, hi)
    bad = (has0(x) & has0(y)) | (has_inf(x) & has_inf(y)) | nan_in(x, y)
    return Interval(*finish(lo, hi, bad))


def abs_(x: Interval) -> Interval:
    """``|X|``: ``[0, max(−a, b)]`` when ``a < 0 < b``, else ``X`` or ``−X`` (exact)."""
    lo = torch.where(x.lo >= 0, x.lo, torch.where(x.hi <= 0, -x.hi, torch.zeros_like(x.lo)))
    hi = torch.maximum(x.lo.abs(), x.hi.abs())
    return Interval(*finish(lo, hi, nan_in(x)))


def powi(x: Interval, n: int) -> Interval:
    """``X**n`` for an integer ``n``: odd monotone, even like :func:`square`, negative ``1 / X**|n|``.

    >>> powi(as_interval(-2.0, 1.0), 3).lo.item(), powi(as_interval(-2.0, 1.0), 2).hi.item()
    (-8.0, 4.0)
    """
    n = int(n)
    if n < 0:
        return div(Interval(x.lo.new_tensor(1.0), x.lo.new_tensor(1.0)), powi(x, -n))
    if n == 0:
        return Interval(*finish(torch.ones_like(x.lo), torch.ones_like(x.hi), nan_in(x)))
    if n % 2:
        mlo, mhi = x.lo.abs(), x.hi.abs()
        lo = torch.where(x.lo >= 0, ipow_bound(mlo, n, False), -ipow_bound(mlo, n, True))
        hi = torch.where(x.hi >= 0, ipow_bound(mhi, n, True), -ipow_bound(mhi, n, False))
        return Interval(*finish(lo, hi, nan_in(x)))
    m = abs_(x)
    return Interval(*finish(ipow_bound(m.lo, n, False), ipow_bound(m.hi, n, True), nan_in(x)))


def square(x: Interval) -> Interval:
    """``X²`` = ``[0, max(a², b²)]`` when ``a <= 0 <= b`` — tighter than ``mul(x, x)``, which forgets that both
    factors are the same point."""
    return powi(x, 2)


def sqrt(x: Interval) -> Interval:
    """Monotone; NaN if ``a < 0``; exact squares (``sqrt 4 = 2``) are not widened."""
    rl, rh = torch.sqrt(x.lo), torch.sqrt(x.hi)
    lo = down(rl, 1, is_exact_root(rl, x.lo)).clamp_min(0.0)
    return Interval(*finish(lo, up(rh, 1, is_exact_root(rh, x.hi)), (x.lo < 0) | nan_in(x)))


def exp(x: Interval) -> Interval:
    """Monotone, widened 2 floats (libm assumption), ``>= 0``."""
    ea, eb = (x.lo == 0) | torch.isinf(x.lo), (x.hi == 0) | torch.isinf(x.hi)
    lo = down(torch.exp(x.lo), 2, ea).clamp_min(0.0)
    return Interval(*finish(lo, up(torch.exp(x.hi), 2, eb), nan_in(x)))


def log(x: Interval) -> Interval:
    """Monotone; NaN if ``a < 0``; ``log [0, b] = [−inf, log b]`` (never a clamped lower bound)."""
    ea = (x.lo == 1) | (x.lo == 0) | torch.isinf(x.lo)
    eb = (x.hi == 1) | (x.hi == 0) | torch.isinf(x.hi)
    lo = down(torch.log(x.lo), 2, ea)
    return Interval(*finish(lo, up(torch.log(x.hi), 2, eb), (x.lo < 0) | nan_in(x)))


def sin(x: Interval) -> Interval:
    """Endpoint values, plus 1 / −1 if a crest ``π/2 + 2kπ`` / trough ``−π/2 + 2kπ`` may lie inside."""
    lo, hi = trig_bounds(x.lo, x.hi, torch.sin, math.pi / 2, -math.pi / 2)
    return Interval(*finish(lo, hi, has_inf(x) | nan_in(x)))


def cos(x: Interval) -> Interval:
    """Endpoint values, plus 1 / −1 if a crest ``2kπ`` / trough ``π + 2kπ`` may lie inside.

    >>> c = cos(as_interval(-0.1, 0.1)); c.hi.item(), round(c.lo.item(), 6)
    (1.0, 0.995004)
    """
    lo, hi = trig_bounds(x.lo, x.hi, torch.cos, 0.0, math.pi)
    return Interval(*finish(lo, hi, has_inf(x) | nan_in(x)))


def pow_(x: Interval, y: Interval) -> Interval:
    """``X**Y`` for a real exponent: corners of ``x^y`` (monotone in each argument for ``x > 0``); NaN if
    ``a <= 0``."""
    lo, hi = pow_corners(x, y)
    return Interval(*finish(lo, hi, (x.lo <= 0) | nan_in(x, y)))


def _minmax(x: Interval, y: Interval, fn, left: Tensor, right: Tensor, return_choice: bool):
    bad = nan_in(x, y)
    out = Interval(*finish(fn(x.lo, y.lo), fn(x.hi, y.hi), bad))
    if not return_choice:
        return out
    choice = torch.where(left, 0, torch.where(right, 1, 2)).to(torch.int8)
    choice = torch.where(bad, torch.tensor(2, dtype=torch.int8), choice)
    return out, torch.broadcast_to(choice, out.lo.shape)


def minimum(x: Interval, y: Interval, return_choice: bool = False):
    """``[min(a, c), min(b, d)]``; ``return_choice``: also int8 0 (X ≤ Y on the whole box), 1 (Y ≤ X), 2 (both).

    >>> minimum(as_interval(0.0, 1.0), as_interval(2.0, 3.0), return_choice=True)[1].item()
    0
    """
    return _minmax(x, y, torch.minimum, x.hi <= y.lo, y.hi <= x.lo, return_choice)


def maximum(x: Interval, y: Interval, return_choice: bool = False):
    """``[max(a, c), max(b, d)]``; ``return_choice`` as in :func:`minimum` (0: X ≥ Y on the whole box)."""
    return _minmax(x, y, torch.maximum, x.lo >= y.hi, y.lo >= x.hi, return_choice)


UNARY = {"neg": neg, "abs": abs_, "sqrt": sqrt, "exp": exp, "log": log, "sin": sin, "cos": cos,
         "square": square}
BINARY = {"add": add, "sub": sub, "mul": mul, "div": div, "min": minimum, "max": maximum, "pow": pow_}


def interval_eval(node, lo, hi, params: Mapping[str, float] | None = None) -> tuple[Tensor, Tensor]:
    """Range of the tree ``node`` over boxes ``[lo, hi]`` (``(..., 3)``: x, y, z corners) → ``(flo, fhi)``.

    Iterative post-order walk (trees may be deep), memoised by ``id(node)`` so a shared sub-tree is evaluated
    once (nodes are never hashed: hashing a frozen dataclass recurses). ``params`` are plain floats.

    >>> from ssbench.implicit.ast import Binary, Num, Unary, Var
    >>> f = Binary("sub", Unary("square", Var("x")), Num(1.0))           # x² − 1
    >>> flo, fhi = interval_eval(f, torch.tensor([-1.0, 0, 0]), torch.tensor([2.0, 0, 0]))
    >>> flo.item(), fhi.item()
    (-1.0, 3.0)
    """
    lo, hi = torch.broadcast_tensors(torch.as_tensor(lo, dtype=torch.float64),
                                     torch.as_tensor(hi, dtype=torch.float64))
    if lo.dim() == 0 or lo.shape[-1] != 3:
        raise ValueError(f"lo: must have shape (..., 3) (x, y, z), got {tuple(lo.shape)}")
    box = as_interval(lo, hi)
    params = {} if params is None else params
    memo: dict[int, Interval] = {}
    stack = [(node, False)]
    while stack:
        cur, ready = stack.pop()
        if id(cur) in memo:
            continue
        kids = children(cur)
        if kids and not ready:
            stack.append((cur, True))
            stack.extend((k, False) for k in kids if id(k) not in memo)
            continue
        memo[id(cur)] = _leaf_or_op(cur, [memo[id(k)] for k in kids], box, params)
    out = memo[id(node)]
    shape = lo.shape[:-1]
    return out.lo.expand(shape).clone(), out.hi.expand(shape).clone()


def _leaf_or_op(node, args, box: Interval, params) -> Interval:
    if isinstance(node, Num):
        v = box.lo.new_tensor(float(node.value))
        return Interval(v, v)
    if isinstance(node, Var):
        if node.name not in VARIABLES:
            raise ValueError(f"Var: unknown variable {node.name!r} (expected one of {VARIABLES})")
        return Interval(box.lo[..., VARIABLES.index(node.name)], box.hi[..., VARIABLES.index(node.name)])
    if isinstance(node, Param):
        if node.name not in params:
            raise ValueError(f"params: missing value for parameter {node.name!r}")
        try:
            v = box.lo.new_tensor(float(params[node.name]))
        except (TypeError, ValueError) as e:
            raise ValueError(f"params: {node.name!r} must be a float, got {params[node.name]!r}") from e
        return Interval(v, v)
    if isinstance(node, Unary) and node.op in UNARY:
        return UNARY[node.op](*args)
    if isinstance(node, Binary) and node.op in BINARY:
        return BINARY[node.op](*args)
    if isinstance(node, PowI):
        return powi(args[0], node.n)
    raise ValueError(f"node: unsupported {type(node).__name__} (op {getattr(node, 'op', None)!r})")
