"""Interval bugs known from other implicit ray casters (Knoll et al. 2009; POV-Ray, curv) as regression tests, plus
outward rounding, tightness and the ``interval_eval`` contract. The random-box properties are in
``test_interval.py``.
"""
import math
from decimal import Decimal, localcontext
from fractions import Fraction

import pytest
import torch

from ssbench.implicit import interval as ia
from ssbench.implicit.ast import Binary, Num, Param, Unary, Var

F64 = torch.float64
INF, NAN = math.inf, math.nan
I = ia.as_interval
X, Y, Z = Var("x"), Var("y"), Var("z")
R2 = Binary("add", Binary("add", Unary("square", X), Unary("square", Y)), Unary("square", Z))
UNARY = [ia.neg, ia.abs_, ia.sqrt, ia.exp, ia.log, ia.sin, ia.cos, ia.square]
BINARY = [ia.add, ia.sub, ia.mul, ia.div, ia.minimum, ia.maximum, ia.pow_]


def B(op, a, b):
    return Binary(op, a, b)


def test_log_lower_bound_not_clamped_mpr():
    r = ia.log(I([-1.0, 0.0, 0.5, -1e-300], [2.0, 2.0, 2.0, 1.0]))
    assert r.lo[0].isnan() and r.hi[0].isnan() and r.lo[3].isnan()    # domain error possible -> NaN
    assert r.lo[1].item() == -INF and r.hi[1].item() >= math.log(2)    # log 0 = -inf, not 0
    assert r.lo[2].item() <= math.log(0.5) <= r.hi[2].item() and r.lo[2] < 0


def test_cos_is_range_reduced_mpr():
    r = ia.cos(I(-0.1, 0.1))
    assert r.hi.item() == 1.0 and r.lo.item() <= math.cos(0.1) and r.lo.item() > 0.99


def test_min_max_endpoint_choice():
    x, y = I(0.0, 3.0), I(1.0, 2.0)
    assert (ia.minimum(x, y).lo.item(), ia.minimum(x, y).hi.item()) == (0.0, 2.0)
    assert (ia.maximum(x, y).lo.item(), ia.maximum(x, y).hi.item()) == (1.0, 3.0)
    a = I([0.0, 2.0, 0.0, 1.0, NAN], [1.0, 3.0, 3.0, 1.0, NAN])
    b = I([2.0, 0.0, 1.0, 1.0, 0.0], [3.0, 1.0, 2.0, 1.0, 1.0])
    r, choice = ia.minimum(a, b, return_choice=True)
    assert choice.dtype == torch.int8 and choice.tolist() == [0, 1, 2, 0, 2]
    assert r.lo[:4].tolist() == [0.0, 0.0, 0.0, 1.0] and r.hi[:4].tolist() == [1.0, 1.0, 2.0, 1.0]
    assert ia.maximum(a, b, return_choice=True)[1].tolist() == [1, 0, 2, 0, 2]


@pytest.mark.parametrize("op", UNARY + BINARY + [ia.powi], ids=lambda f: f.__name__)
def test_nan_is_never_lost(op):
    nan, ok = I(NAN), I(0.5, 2.0)
    if op is ia.powi:
        outs = [ia.powi(nan, n) for n in (-2, 0, 3)]                      # even x**0 (torch: NaN**0 = 1)
    elif op in UNARY:
        outs = [op(nan)]
    else:
        outs = [op(nan, ok), op(ok, nan), op(nan, nan)]
    assert all(r.lo.isnan() and r.hi.isnan() for r in outs)


def test_undefined_somewhere_gives_nan_and_division_by_zero_the_whole_line():
    assert ia.add(I(-INF, 0.0), I(0.0, INF)).lo.isnan()                  # inf - inf possible
    assert ia.mul(I(-1.0, 1.0), I(1.0, INF)).lo.isnan()                   # 0 * inf possible
    assert ia.div(I(0.0, 1.0), I(-1.0, 1.0)).lo.isnan()                   # 0 / 0 possible
    assert ia.sqrt(I(-1e-300, 1.0)).hi.isnan() and ia.pow_(I(0.0, 1.0), I(2.0)).lo.isnan()
    assert ia.sin(I(0.0, INF)).lo.isnan()
    w = ia.div(I(1.0, 2.0), I([-1.0, 0.0], [1.0, 0.0]))
    assert w.lo.tolist() == [-INF, -INF] and w.hi.tolist() == [INF, INF]
    e = ia.exp(I([INF, -INF], [INF, 0.0]))
    assert e.lo.tolist() == [INF, 0.0] and e.hi.tolist() == [INF, 1.0]


def test_no_nan_on_finite_boxes_for_total_ops():
    g = torch.Generator().manual_seed(5)
    c = (torch.rand(10_000, generator=g, dtype=F64) - 0.5) * 10.0 ** torch.randint(-5, 300, (10_000,), generator=g).to(F64)
    x, y = I(c, c + c.abs() * torch.rand(10_000, generator=g, dtype=F64)), I(-2.0, 3.0)
    for r in (ia.add(x, y), ia.sub(x, y), ia.mul(x, y), ia.square(x), ia.abs_(x), ia.exp(x), ia.sin(x),
              ia.cos(x), ia.minimum(x, y), ia.maximum(x, y), ia.powi(x, 7)):
        assert not r.lo.isnan().any()


def test_sin_near_a_far_crest_is_sound():
    with localcontext() as ctx:
        ctx.prec = 60
        pi = Decimal("3.14159265358979323846264338327950288419716939937510582097494")
        crest = pi * Decimal(1_000_000) + pi / 2                          # pi/2 + 2*pi*500000
    steps = [float(crest)]
    for _ in range(4):
        steps = [math.nextafter(steps[0], -INF)] + steps + [math.nextafter(steps[-1], INF)]
    pairs = [(a, b) for i, a in enumerate(steps) for b in steps[i:]]
    r = ia.sin(I([a for a, _ in pairs], [b for _, b in pairs]))
    for (a, b), hi in zip(pairs, r.hi.tolist()):
        if Decimal(a) <= crest <= Decimal(b):
            assert hi == 1.0, (a, b)
    off = ia.sin(I(float(crest) + 1e-3, float(crest) + 2e-3))
    assert off.hi.item() < 1.0 and off.lo.item() > 0.99                   # tight, not [-1, 1]


def test_outward_rounding_widens_inexact_and_keeps_exact():
    r = ia.add(I(0.1), I(0.2))
    assert Fraction(r.lo.item()) < Fraction(3, 10) < Fraction(r.hi.item())
    assert Fraction(r.lo.item()) <= Fraction(0.1) + Fraction(0.2) <= Fraction(r.hi.item())
    q = ia.div(I(1.0), I(3.0))
    assert Fraction(q.lo.item()) < Fraction(1, 3) < Fraction(q.hi.item())
    for r, want in ((ia.add(I(1.0), I(2.0)), (3.0, 3.0)), (ia.mul(I(2.0, 3.0), I(4.0, 5.0)), (8.0, 15.0)),
                    (ia.div(I(1.0), I(4.0)), (0.25, 0.25)), (ia.sqrt(I(4.0, 9.0)), (2.0, 3.0)),
                    (ia.sub(I(1.0), I(1.0)), (0.0, 0.0)), (ia.mul(I(0.0), I(0.1, 0.3)), (0.0, 0.0)),
                    (ia.powi(I(2.0), 10), (1024.0, 1024.0)), (ia.cos(I(0.0)), (1.0, 1.0))):
        assert (r.lo.item(), r.hi.item()) == want
    tiny = ia.mul(I(1e-200), I(1e-200))                                   # underflow keeps the sign
    assert tiny.lo.item() == 0.0 and tiny.hi.item() > 0.0


def test_sqrt_of_sum_of_squares_touching_zero_is_not_nan():
    x, y = I(0.0, 1e-3), I(-1e-3, 0.0)
    r = ia.sqrt(ia.add(ia.square(x), ia.square(y)))
    assert r.lo.item() == 0.0 and r.hi.item() >= math.hypot(1e-3, 1e-3)
    box = torch.tensor([-1.0, 0.0, -0.5]), torch.tensor([1.0, 0.2, 0.0])
    flo, fhi = ia.interval_eval(Unary("sqrt", R2), *box)
    assert flo.item() == 0.0 and not fhi.isnan()


def test_tightness_square_and_sin():
    x = I(-1.0, 2.0)
    assert (ia.square(x).lo.item(), ia.square(x).hi.item()) == (0.0, 4.0)
    assert ia.mul(x, x).lo.item() == -2.0 and ia.abs_(x).lo.item() == 0.0
    s = ia.sin(I(1.0, 1.0 + 1e-9))
    assert s.hi.item() - s.lo.item() == pytest.approx(1e-9 * math.cos(1.0), rel=1e-5)


def test_interval_eval_api():
    lo, hi = torch.zeros(2, 5, 3), torch.ones(2, 5, 3)
    flo, fhi = ia.interval_eval(Num(2.0), lo, hi)
    assert flo.shape == (2, 5) and flo.dtype == F64 and fhi.eq(2.0).all()
    flo, fhi = ia.interval_eval(B("mul", Param("s"), X), lo, hi, {"s": -3})
    assert flo.eq(-3.0).all() and fhi.eq(0.0).all()
    with pytest.raises(ValueError, match="lo: must be <= hi"):
        ia.interval_eval(X, hi, lo)
    with pytest.raises(ValueError, match="'s'"):
        ia.interval_eval(B("mul", Param("s"), X), lo, hi)
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        ia.interval_eval(X, torch.zeros(4, 2), torch.ones(4, 2))
    with pytest.raises(ValueError, match="unsupported"):
        ia.interval_eval(Unary("tan", X), lo, hi)


def test_interval_eval_memoises_shared_nodes_and_walks_deep_trees():
    f = X
    for _ in range(200):                                                  # a DAG with 2**200 paths
        f = B("add", f, f)
    flo, fhi = ia.interval_eval(f, torch.tensor([1.0, 0, 0]), torch.tensor([1.0, 0, 0]))
    assert flo.item() == fhi.item() == 2.0 ** 200
    g = X
    for _ in range(20_000):                                               # deeper than the recursion limit
        g = Unary("neg", g)
    flo, fhi = ia.interval_eval(g, torch.tensor([1.0, 0, 0]), torch.tensor([2.0, 0, 0]))
    assert (flo.item(), fhi.item()) == (1.0, 2.0)


def test_sin_cos_crests_of_large_arguments_are_found():
    """For |k| up to 1e14 the float nearest a crest ``c + 2kπ`` is off by up to 1e-2 rad; the crest test
    must still see it in the two-float interval around it (this fails without the crest margin)."""
    mpmath = pytest.importorskip("mpmath")
    g = torch.Generator().manual_seed(7)
    u = torch.rand(2, 300, generator=g, dtype=F64)
    ks = (10 ** (u[0] * 14)).round() * torch.where(u[1] < 0.5, -1.0, 1.0)
    cases = ((ia.sin, 0.5, True), (ia.sin, -0.5, False), (ia.cos, 0.0, True), (ia.cos, 1.0, False))
    for fn, offset, crest in cases:                                       # crest/trough at pi*(offset + 2k)
        lo, hi = [], []
        with mpmath.workprec(300):
            for k in ks.tolist():
                t = mpmath.pi * (offset + 2 * int(k))
                c = float(t)
                step = math.nextafter(c, INF if t > c else -INF)
                lo.append(min(c, step))
                hi.append(max(c, step))
        r = fn(I(lo, hi))
        assert (r.hi == 1.0).all() if crest else (r.lo == -1.0).all()
