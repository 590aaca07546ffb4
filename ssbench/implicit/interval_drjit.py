"""Interval arithmetic on Dr.Jit arrays: a sound range of f over boxes, traceable inside one Dr.Jit kernel.

The same contract as :mod:`ssbench.implicit.interval` (``[lo, hi]`` float64 pairs, ±inf allowed, NaN in both
bounds = "may be undefined", NaN wherever a domain error is possible) with a simpler rounding rule, so that a
whole interval march (:mod:`ssbench.reference.implicit_drjit`) can be one symbolic Dr.Jit loop with no
Python branching on values:

* **Basic operations** (``+ − · /``, ``sqrt``) are IEEE 754 correctly rounded (error ≤ ½ ulp, i.e. ≤ 2⁻⁵³
  relative, or ≤ 2⁻¹⁰⁷⁵ absolute for a subnormal result). Every computed bound ``r`` is moved outward by
  ``|r|·2⁻⁴⁸ + 2⁻¹⁰²⁰`` (:func:`down`, :func:`up`) — 16–32 ulps and more than a flushed subnormal — instead of
  finding, as the torch evaluator does, whether the exact value lies on the far side of ``r``. Bounds are
  therefore a few ulps looser, never tighter. ±inf bounds stay (``down(+inf)`` is the largest float: an exact
  value can be finite after an overflow).
* **Signs that are known exactly stay exact**: a sum of non-negative lower bounds, a product or quotient whose
  computed corner is ≥ 0 (rounding keeps signs), a square, ``sqrt``, ``exp`` are clamped at 0, so
  ``sqrt(x² + y² + z²)`` never turns NaN through the widening.
* **Denormals**: Dr.Jit runs a large kernel on worker threads that flush subnormal results to zero and read
  subnormal inputs as zero (measured: ``1e-310 · 1e300`` gives 0 there, 1e-10 on one thread). A flushed result
  is off by < 2⁻¹⁰²² (inside the ``2⁻¹⁰²⁰`` widening); signs are taken from the operands, never from a result
  that may be a flushed ±0; box bounds are moved outward off the subnormal range first
  (:func:`flush_outward`), and trees with a subnormal constant are left to the torch evaluator.
* **Library functions**: Dr.Jit's own float64 ``exp log sin cos`` (measured ≤ 1.6 ulp on 3000 random
  arguments each against 120-bit mpmath, ``benchmarks``-style check in the tests) are widened by
  ``|r|·2⁻⁴⁴ + 2⁻⁵⁰`` (≥ 256 ulps); ``sin``/``cos`` with an argument beyond ``±TRIG_LIMIT`` return [−1, 1];
  Dr.Jit's ``exp`` overflows early (``inf`` at 709.6, where the value is 1.5e308), so a lower bound uses
  ``exp(min(a, 709))``.
  The real power ``pow`` is not offered here: :func:`supported` says so and the caller uses the torch march.

>>> from ssbench.reference import backend; _ = backend.mitsuba()
>>> from drjit.llvm import Float64
>>> from ssbench.implicit.parser import parse_node
>>> lo, hi = interval_drjit(parse_node("sqrt(x^2 + y^2) - 1"), (Float64(0.0), Float64(0.0), Float64(0.0)),
...                         (Float64(1.0), Float64(1.0), Float64(0.0)))
>>> float(lo[0]) < -1.0 < float(lo[0]) + 1e-12, 0.414 < float(hi[0]) < 0.4143     # −1 widened by a few ulps
(True, True)
"""
from __future__ import annotations

import math
from typing import Mapping, Optional

from .ast import Binary, Num, Param, PowI, Unary, Var
from .torch_eval import missing_param, pow_abs_int, schedule

__all__ = ["interval_drjit", "object_interval_drjit", "surface_interval_drjit", "supported", "subnormal",
           "flush_outward", "TRIG_LIMIT"]

REL = 2.0 ** -48           # widening of a correctly rounded result (error ≤ 2⁻⁵³ relative)
TINY = 2.0 ** -1020        # absolute floor: covers a subnormal result, flushed or not
LIB_REL, LIB_ABS = 2.0 ** -44, 2.0 ** -50    # exp, log, sin, cos (≤ 1.6 ulp measured)
MAX_LOW = 1.7976931348623157e308 * (1 - 2.0 ** -40)   # a lower bound of a float overflowed by a few roundings
MIN_NORMAL = 2.0 ** -1022
EXP_SAFE = 709.0           # exp below this never overflows (Dr.Jit's exp already gives inf at 709.6)
TRIG_LIMIT = 1.0e4         # |x| beyond which sin/cos give [−1, 1]


def _dr():
    import drjit
    return drjit


def down(x, rel: float = REL, tiny: float = TINY):
    """A float ≤ every value within the error bound of ``x`` (``−inf`` stays, ``+inf`` → the largest float)."""
    dr = _dr()
    w = x - (dr.abs(x) * rel + tiny)
    return dr.select(dr.isinf(x), dr.select(x > 0, MAX_LOW, x), w)


def up(x, rel: float = REL, tiny: float = TINY):
    """A float ≥ every value within the error bound of ``x`` (``+inf`` stays, ``−inf`` → the smallest float)."""
    dr = _dr()
    w = x + (dr.abs(x) * rel + tiny)
    return dr.select(dr.isinf(x), dr.select(x < 0, -MAX_LOW, x), w)


def _finish(lo, hi, bad):
    dr = _dr()
    bad = bad | dr.isnan(lo) | dr.isnan(hi)
    return dr.select(bad, math.nan, lo), dr.select(bad, math.nan, hi)


def _nan(*xs):
    dr = _dr()
    out = dr.isnan(xs[0][0])
    for lo, hi in xs:
        out = out | dr.isnan(lo) | dr.isnan(hi)
    return out


def _has0(x):
    return (x[0] <= 0) & (x[1] >= 0)


def _has_inf(x):
    dr = _dr()
    return dr.isinf(x[0]) | dr.isinf(x[1])


def _add(x, y):
    dr = _dr()
    lo, hi = down(x[0] + y[0]), up(x[1] + y[1])
    lo = dr.select((x[0] >= 0) & (y[0] >= 0), dr.maximum(lo, 0.0), lo)       # exact sum ≥ 0
    hi = dr.select((x[1] <= 0) & (y[1] <= 0), dr.minimum(hi, 0.0), hi)
    inf_inf = ((x[0] == -math.inf) & (y[1] == math.inf)) | ((x[1] == math.inf) & (y[0] == -math.inf))
    return _finish(lo, hi, inf_inf | _nan(x, y))


def _neg(x):
    return -x[1], -x[0]


def _corners(x, y, op, nonneg, nonpos):
    """Widened min and max of ``op`` over the four corners, clamped at 0 where the operands' signs say the
    exact result is ≥ 0 (``nonneg``) or ≤ 0 (``nonpos``) — never where a computed corner merely is (a result
    flushed to ±0 keeps no sign)."""
    dr = _dr()
    c = [op(u, v) for u in x for v in y]
    mn, mx = c[0], c[0]
    for v in c[1:]:
        mn, mx = dr.minimum(mn, v), dr.maximum(mx, v)
    lo = dr.select(nonneg, dr.maximum(down(mn), 0.0), down(mn))
    hi = dr.select(nonpos, dr.minimum(up(mx), 0.0), up(mx))
    return lo, hi


def _mul(x, y):
    nonneg = ((x[0] >= 0) & (y[0] >= 0)) | ((x[1] <= 0) & (y[1] <= 0))
    nonpos = ((x[0] >= 0) & (y[1] <= 0)) | ((x[1] <= 0) & (y[0] >= 0))
    lo, hi = _corners(x, y, lambda u, v: u * v, nonneg, nonpos)
    zero_inf = (_has0(x) & _has_inf(y)) | (_has0(y) & _has_inf(x))
    return _finish(lo, hi, zero_inf | _nan(x, y))


def _div(x, y):
    dr = _dr()
    whole = _has0(y)
    ys = tuple(dr.select(whole, 1.0, v) for v in y)
    nonneg = ((x[0] >= 0) & (ys[0] > 0)) | ((x[1] <= 0) & (ys[1] < 0))
    nonpos = ((x[0] >= 0) & (ys[1] < 0)) | ((x[1] <= 0) & (ys[0] > 0))
    lo, hi = _corners(x, ys, lambda u, v: u / v, nonneg, nonpos)
    lo, hi = dr.select(whole, -math.inf, lo), dr.select(whole, math.inf, hi)
    bad = (_has0(x) & whole) | (_has_inf(x) & _has_inf(y)) | _nan(x, y)
    return _finish(lo, hi, bad)


def _abs(x):
    dr = _dr()
    lo = dr.select(x[0] >= 0, x[0], dr.select(x[1] <= 0, -x[1], 0.0))
    return _finish(lo, dr.maximum(dr.abs(x[0]), dr.abs(x[1])), _nan(x))


def _ipow(m, n: int):
    """``(m**n, multiplications)``: :func:`~ssbench.implicit.torch_eval.pow_abs_int` of ``m >= 0`` and how many
    products (each one rounding) its repeated squaring takes."""
    return pow_abs_int(m, n), n.bit_length() + bin(n).count("1") - 2


def _full(like, value: float):
    """``value`` as an array as wide as ``like`` (never ``like · 0 + value``: NaN where ``like`` is infinite)."""
    dr = _dr()
    return dr.full(type(like), value, dr.width(like))


def _powi(x, n: int):
    dr = _dr()
    if n < 0:
        one = _full(x[0], 1.0)
        return _div((one, one), _powi(x, -n))
    if n == 0:
        one = _full(x[0], 1.0)
        return _finish(one, one, _nan(x))
    if n % 2:
        (pl, k), (ph, _) = _ipow(dr.abs(x[0]), n), _ipow(dr.abs(x[1]), n)
        rel = (k + 1) * REL                    # k roundings of ≤ 2⁻⁵³ each, 32× margin
        lo = dr.select(x[0] >= 0, dr.maximum(down(pl, rel), 0.0), -up(pl, rel))
        hi = dr.select(x[1] >= 0, up(ph, rel), -dr.maximum(down(ph, rel), 0.0))
        return _finish(lo, hi, _nan(x))
    m = _abs(x)
    (pl, k), (ph, _) = _ipow(m[0], n), _ipow(m[1], n)
    rel = (k + 1) * REL
    return _finish(dr.maximum(down(pl, rel), 0.0), up(ph, rel), _nan(x))


def _sqrt(x):
    dr = _dr()
    lo = dr.maximum(down(dr.sqrt(dr.maximum(x[0], 0.0))), 0.0)
    return _finish(lo, up(dr.sqrt(dr.maximum(x[1], 0.0))), (x[0] < 0) | _nan(x))


def _exp(x):
    dr = _dr()
    lo = dr.maximum(down(dr.exp(dr.minimum(x[0], EXP_SAFE)), LIB_REL, LIB_ABS), 0.0)    # exp is monotone
    return _finish(lo, up(dr.exp(x[1]), LIB_REL, LIB_ABS), _nan(x))


def _log(x):
    dr = _dr()
    lo = down(dr.log(dr.maximum(x[0], 0.0)), LIB_REL, LIB_ABS)
    return _finish(lo, up(dr.log(dr.maximum(x[1], 0.0)), LIB_REL, LIB_ABS), (x[0] < 0) | _nan(x))


def _trig(x, fn, crest: float, trough: float):
    """Endpoint values widened, then 1 (−1) if a crest (trough) ``+ 2kπ`` may lie in the interval."""
    dr = _dr()
    a, b = x
    fa, fb = fn(a), fn(b)
    lo = dr.minimum(down(fa, LIB_REL, LIB_ABS), down(fb, LIB_REL, LIB_ABS))
    hi = dr.maximum(up(fa, LIB_REL, LIB_ABS), up(fb, LIB_REL, LIB_ABS))
    mag = dr.maximum(dr.abs(a), dr.abs(b))
    m = 1e-12 * (mag + 2 * math.pi)                       # ≫ the error of the float crest test
    two_pi = 2 * math.pi

    def contains(offset):
        return dr.floor((b + m - offset) / two_pi) > dr.floor((a - m - offset) / two_pi)

    huge = mag > TRIG_LIMIT
    hi = dr.clip(dr.select(contains(crest) | huge, 1.0, hi), -1.0, 1.0)
    lo = dr.clip(dr.select(contains(trough) | huge, -1.0, lo), -1.0, 1.0)
    return _finish(lo, hi, _has_inf(x) | _nan(x))


def _minmax(x, y, fn):
    return _finish(fn(x[0], y[0]), fn(x[1], y[1]), _nan(x, y))


def _unary(op, a):
    dr = _dr()
    table = {"neg": _neg, "abs": _abs, "sqrt": _sqrt, "exp": _exp, "log": _log,
             "square": lambda v: _powi(v, 2),
             "sin": lambda v: _trig(v, dr.sin, math.pi / 2, -math.pi / 2),
             "cos": lambda v: _trig(v, dr.cos, 0.0, math.pi)}
    return table[op](a)


def _binary(op, a, b):
    dr = _dr()
    table = {"add": _add, "sub": lambda u, v: _add(u, _neg(v)), "mul": _mul, "div": _div,
             "min": lambda u, v: _minmax(u, v, dr.minimum), "max": lambda u, v: _minmax(u, v, dr.maximum)}
    return table[op](a, b)


def subnormal(v: float) -> bool:
    """Whether a Python float is subnormal (a kernel would read it as 0)."""
    return 0.0 < abs(v) < MIN_NORMAL


def supported(node, params: Optional[Mapping[str, float]] = None) -> bool:
    """Whether :func:`interval_drjit` can evaluate the tree: no real power ``pow``, no subnormal constant."""
    nodes = schedule(node).nodes
    if any(isinstance(nd, Binary) and nd.op == "pow" for nd in nodes):
        return False
    values = [nd.value for nd in nodes if isinstance(nd, Num)] + list((params or {}).values())
    return not any(subnormal(float(v)) for v in values)


def flush_outward(lo, hi):
    """Subnormal bounds moved outward to 0 or ±2⁻¹⁰²² (tested on the bits: a parallel Dr.Jit kernel runs with
    denormals-are-zero, so a comparison cannot see them); every other bound unchanged."""
    dr = _dr()
    import drjit.llvm as L

    def sub_neg(v):
        bits = dr.reinterpret_array(L.UInt64, v)
        return ((bits >> 52) & 0x7FF) == 0, (bits >> 63) != 0   # exponent 0: zero or subnormal

    (slo, nlo), (shi, nhi) = sub_neg(lo), sub_neg(hi)
    return dr.select(slo, dr.select(nlo, -MIN_NORMAL, 0.0), lo), dr.select(shi, dr.select(nhi, 0.0, MIN_NORMAL), hi)


def interval_drjit(node, lo, hi, params: Optional[Mapping[str, float]] = None):
    """``(flo, fhi)`` of the tree over the boxes ``[lo, hi]`` given as ``(x, y, z)`` Dr.Jit Float64 arrays."""
    params = params or {}
    lo, hi = zip(*(flush_outward(a, b) for a, b in zip(lo, hi)))
    box = {"x": (lo[0], hi[0]), "y": (lo[1], hi[1]), "z": (lo[2], hi[2])}
    sched = schedule(node)
    vals: list = [None] * len(sched.nodes)
    for i, nd in enumerate(sched.nodes):
        a = [vals[j] for j in sched.args[i]]
        if isinstance(nd, Var):
            v = box[nd.name]
        elif isinstance(nd, (Num, Param)):
            if isinstance(nd, Param) and nd.name not in params:
                raise missing_param(nd.name, params)
            c = _full(lo[0], float(nd.value if isinstance(nd, Num) else params[nd.name]))
            v = (c, c)
        elif isinstance(nd, Unary):
            v = _unary(nd.op, a[0])
        elif isinstance(nd, PowI):
            v = _powi(a[0], nd.n)
        elif isinstance(nd, Binary) and nd.op != "pow":
            v = _binary(nd.op, a[0], a[1])
        else:
            raise ValueError(f"node: unsupported by the Dr.Jit interval evaluator: {nd!r}")
        vals[i] = v
        for j in sched.free[i]:
            vals[j] = None
    return vals[-1]


def object_interval_drjit(obj, lo, hi):
    """The world field of an :class:`~ssbench.implicit.surface.ImplicitObject` over boxes: the box taken to local
    space (``p − T``, ``Rᵀ·``, ``/ s``, each bound widened), the expression's enclosure, times ``s``."""
    dr = _dr()
    lo, hi = list(lo), list(hi)
    if any(obj.translate):                              # opaque: an animated object reuses the kernel
        t = [dr.opaque(type(lo[0]), v) for v in obj.translate]
        lo = [down(v - c) for v, c in zip(lo, t)]
        hi = [up(v - c) for v, c in zip(hi, t)]
    if any(a != 0.0 for a in obj.rotate):
        R = obj.rotation
        qlo, qhi = [], []
        for j in range(3):                                  # q_j = Σ_i R[i][j] p_i
            slo = shi = _full(lo[0], 0.0)
            for i in range(3):
                r = R[i][j]
                if r != 0.0:
                    a, b = (lo[i] * r, hi[i] * r) if r > 0 else (hi[i] * r, lo[i] * r)
                    slo, shi = down(slo + down(a)), up(shi + up(b))
            qlo.append(slo)
            qhi.append(shi)
        lo, hi = qlo, qhi
    if obj.scale != 1.0:
        lo, hi = [down(v / obj.scale) for v in lo], [up(v / obj.scale) for v in hi]
    e = obj.expression
    flo, fhi = interval_drjit(e.node, lo, hi, dict(e.params))
    if obj.scale != 1.0:
        flo, fhi = down(flo * obj.scale), up(fhi * obj.scale)
    return _finish(flo, fhi, dr.isnan(flo) | dr.isnan(fhi))


def surface_interval_drjit(surface, lo, hi):
    """Enclosure of a union of objects (``surface.objects``): the minimum of the objects' enclosures."""
    dr = _dr()
    flo, fhi = object_interval_drjit(surface.objects[0], lo, hi)
    for o in surface.objects[1:]:
        a, b = object_interval_drjit(o, lo, hi)
        flo, fhi = _finish(dr.minimum(flo, a), dr.minimum(fhi, b), dr.isnan(a) | dr.isnan(flo))
    return flo, fhi
