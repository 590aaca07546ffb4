"""Interval evaluator: enclosure on 10⁵ random boxes per operator and on whole trees.

Every property test draws seeded random intervals, evaluates the op *pointwise* in float64 torch at the box
corners and at random interior points, and checks ``lo <= value <= hi``. A NaN interval contains anything; a
NaN value needs a NaN interval (else NaN was lost); a bound is never NaN alone and never ``lo > hi``. That
float check cannot see a missing outward rounding, so a subsample is also checked against exact (mpmath)
values. Bugs known from other interval ray casters and the API contract are in ``test_interval_anchors.py``.
"""
import math

import pytest
import torch

from ssbench.implicit import interval as ia
from ssbench.implicit.ast import Binary, Num, Param, PowI, Unary, Var

N = 100_000
F64 = torch.float64
INF, NAN = math.inf, math.nan
I = ia.as_interval


def _u(g, n):
    return torch.rand(n, generator=g, dtype=F64)


def rand_intervals(g, n=N, special=True):
    """Mixture: general / huge / straddling 0 / near sin-cos crests / degenerate / 0 endpoint, and with
    ``special`` also infinite ends and NaN intervals (1/40 of the boxes)."""
    kind = torch.randint(0, 7 if special else 6, (n,), generator=g)
    sign = torch.where(_u(g, n) < 0.5, -1.0, 1.0)
    c = sign * 10 ** (_u(g, n) * 8 - 4)                                   # general: |c| in 1e-4..1e4
    w = c.abs() * 10 ** (_u(g, n) * 12 - 12)
    lo, hi = c - w, c + w
    big = sign * 10 ** (_u(g, n) * 300)                                   # huge: up to 1e300
    sel = kind == 1
    lo, hi = torch.where(sel, big, lo), torch.where(sel, big + big.abs() * 10 ** (_u(g, n) * 11 - 10), hi)
    sel = kind == 2                                                       # straddling zero
    lo, hi = torch.where(sel, -(10 ** (_u(g, n) * 9 - 6)), lo), torch.where(sel, 10 ** (_u(g, n) * 9 - 6), hi)
    j = torch.where(_u(g, n) < 0.5, torch.randint(-8, 9, (n,), generator=g),
                    torch.randint(-10**7, 10**7, (n,), generator=g)).to(F64)
    crest = j * (math.pi / 2) + (_u(g, n) - 0.5) * 1e-9 * j.abs().clamp_min(1)    # near k·π/2
    hw = 10 ** (_u(g, n) * 14 - 16) * j.abs().clamp_min(1)
    sel = kind == 3
    lo, hi = torch.where(sel, crest - hw, lo), torch.where(sel, crest + hw, hi)
    sel = kind == 4                                                       # degenerate [a, a], some a = 0
    a = torch.where(_u(g, n) < 0.2, 0.0, torch.where(_u(g, n) < 0.5, big, c))
    lo, hi = torch.where(sel, a, lo), torch.where(sel, a, hi)
    sel = kind == 5                                                       # [0, b] or [-b, 0]
    lo, hi = torch.where(sel, torch.clamp(c, max=0.0), lo), torch.where(sel, torch.clamp(c, min=0.0), hi)
    if special:                                                           # [a, inf], [-inf, b], [-inf, inf], ...
        sel, r = kind == 6, _u(g, n)
        lo = torch.where(sel & ((r < 0.3) | (r > 0.9)), -INF, torch.where(sel & (r > 0.8), INF, lo))
        hi = torch.where(sel & ((r > 0.3) & (r < 0.6) | (r > 0.8)), INF, hi)
        hi = torch.where(sel & (r > 0.9) & (r < 0.95), -INF, hi)
    lo, hi = torch.minimum(lo, hi), torch.maximum(lo, hi)
    if special:
        nan = _u(g, n) < 1 / 40
        lo, hi = lo.masked_fill(nan, NAN), hi.masked_fill(nan, NAN)
    return I(lo, hi)


def rand_positive(g, n=N, special=True):
    """Half the boxes made non-negative (with ``abs_``) so sqrt/log/pow see their domain too."""
    x, m = rand_intervals(g, n, special), ia.abs_(rand_intervals(g, n, special))
    pick = _u(g, n) < 0.5
    return I(torch.where(pick, m.lo, x.lo), torch.where(pick, m.hi, x.hi))


def interior(g, x, k):
    """``k`` random points in each box (finite ones where an end is infinite; 0 now and then), shape (k, n)."""
    lo, hi = x.lo.expand(k, -1), x.hi.expand(k, -1)
    t = torch.rand(lo.shape, generator=g, dtype=F64)
    jump = 10 ** (torch.rand(lo.shape, generator=g, dtype=F64) * 303 - 3)
    p = lo * (1 - t) + hi * t
    p = torch.where(torch.isinf(lo) & torch.isfinite(hi), hi - jump, p)
    p = torch.where(torch.isfinite(lo) & torch.isinf(hi), lo + jump, p)
    p = torch.where(torch.isinf(lo) & torch.isinf(hi), torch.where(t < 0.5, -jump, jump), p)
    p = torch.minimum(torch.maximum(p, lo), hi)
    zero = (torch.rand(lo.shape, generator=g) < 0.1) & (lo <= 0) & (hi >= 0)  # the point 0 itself, sometimes
    return torch.where(lo == hi, lo, torch.where(zero, 0.0, p))


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """Medium-sized elementwise work: one thread is faster than two on a shared, busy machine."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


_POOLS = {}


def pool(name):
    """Shared seeded samples (drawing 10⁵ boxes costs more than most ops): ``(interval, interior points)``."""
    if name not in _POOLS:
        g = torch.Generator().manual_seed({"a": 11, "b": 12, "pos": 13}[name])
        x = rand_positive(g) if name == "pos" else rand_intervals(g)
        _POOLS[name] = x, interior(g, x, 3)
    return _POOLS[name]


def assert_encloses(r, vals, what):
    lo, hi = r
    assert torch.equal(lo.isnan(), hi.isnan()), f"{what}: a single NaN bound"
    nan_iv = lo.isnan()
    assert (nan_iv | (lo <= hi)).all(), f"{what}: lo > hi (an interval bug like MPR's log)"
    bad = ~(nan_iv | ((vals >= lo) & (vals <= hi)))                        # NaN value + finite interval: lost
    if bad.any():
        i = bad.nonzero()[0].tolist()
        col = i[-1]
        raise AssertionError(f"{what}: {int(bad.sum())} values escape, e.g. value {vals[tuple(i)].item()!r} "
                             f"not in [{lo[col].item()!r}, {hi[col].item()!r}]")


UNARY_CASES = {  # name: (interval op, float64 pointwise op, sample pool)
    "neg": (ia.neg, torch.neg, "a"), "abs": (ia.abs_, torch.abs, "a"), "sqrt": (ia.sqrt, torch.sqrt, "pos"),
    "exp": (ia.exp, torch.exp, "a"), "log": (ia.log, torch.log, "pos"), "sin": (ia.sin, torch.sin, "a"),
    "cos": (ia.cos, torch.cos, "a"), "square": (ia.square, torch.square, "a"),
}
BINARY_CASES = {
    "add": (ia.add, torch.add, "a"), "sub": (ia.sub, torch.sub, "a"), "mul": (ia.mul, torch.mul, "a"),
    "div": (ia.div, torch.div, "a"), "min": (ia.minimum, torch.minimum, "a"),
    "max": (ia.maximum, torch.maximum, "a"), "pow": (ia.pow_, torch.pow, "pos"),
}


@pytest.mark.parametrize("name", sorted(UNARY_CASES))
def test_unary_encloses_random_points(name):
    op, f, which = UNARY_CASES[name]
    x, inner = pool(which)
    assert_encloses(op(x), f(torch.cat([torch.stack([x.lo, x.hi]), inner])), name)


@pytest.mark.parametrize("name", sorted(BINARY_CASES))
def test_binary_encloses_random_points(name):
    op, f, which = BINARY_CASES[name]
    (x, xin), (y, yin) = pool(which), pool("b")
    if name == "pow":                                                     # moderate exponents for half the boxes
        half = torch.arange(N) % 2 == 0
        y = I(torch.where(half, y.lo.clamp(-4, 4), y.lo), torch.where(half, y.hi.clamp(-4, 4), y.hi))
        yin = torch.where(half, yin.clamp(-4, 4), yin)
    px = torch.cat([torch.stack([x.lo, x.lo, x.hi, x.hi]), xin])
    py = torch.cat([torch.stack([y.lo, y.hi, y.lo, y.hi]), yin])
    assert_encloses(op(x, y), f(px, py), name)


@pytest.mark.parametrize("n", [-3, -2, 0, 1, 2, 3, 8])
def test_powi_encloses_random_points(n):
    x, inner = pool("a")
    assert_encloses(ia.powi(x, n), torch.pow(torch.cat([torch.stack([x.lo, x.hi]), inner]), n), f"powi {n}")


MP_OPS = {"neg": lambda a: -a, "abs": abs, "square": lambda a: a * a, "add": lambda a, b: a + b,
          "sub": lambda a, b: a - b, "mul": lambda a, b: a * b, "min": min, "max": max}


def _mp_value(name, mp, *a):
    """Exact value (mpmath); domain errors as NaN, a huge ``exp`` by a proxy that no double separates."""
    if name in ("sin", "cos"):
        return getattr(mp, name)(a[0])
    if name == "sqrt":
        return mp.nan if a[0] < 0 else mp.sqrt(a[0])
    if name == "log":
        return mp.nan if a[0] < 0 else -mp.inf if a[0] == 0 else mp.log(a[0])
    if name == "exp":                                                     # beyond ±2000 no double lies between
        return mp.exp(a[0]) if abs(a[0]) < 2000 else mp.mpf(2) ** (3000 if a[0] > 0 else -3000)
    if name == "div":
        return a[0] / a[1] if a[1] != 0 else (mp.nan if a[0] == 0 else mp.inf)
    if name == "pow":
        return mp.nan if a[0] <= 0 else mp.power(a[0], a[1])
    return MP_OPS[name](*a)


@pytest.mark.parametrize("name", sorted(UNARY_CASES) + sorted(BINARY_CASES))
def test_encloses_the_exact_value(name):
    """The float64 pointwise check cannot see missing outward rounding (the float op rounds the same way as
    the bound); this one compares with the exact value (mpmath, 128 bits) on 1000 finite boxes."""
    mpmath = pytest.importorskip("mpmath")
    g, n = torch.Generator().manual_seed(6000 + sorted(UNARY_CASES | BINARY_CASES).index(name)), 1000
    unary = name in UNARY_CASES
    op, _, which = (UNARY_CASES if unary else BINARY_CASES)[name]
    x = (rand_positive if which == "pos" else rand_intervals)(g, n, special=False)
    xs = [x] if unary else [x, rand_intervals(g, n, special=False)]
    if name == "pow":
        xs[1] = I(xs[1].lo.clamp(-50, 50), xs[1].hi.clamp(-50, 50))
    r = op(*xs)
    inner = [interior(g, v, 1)[0] for v in xs]
    pts = [[v.lo, v.hi, p] for v, p in zip(xs, inner)]
    combos = [(0,), (1,), (2,)] if unary else [(0, 0), (0, 1), (1, 0), (1, 1), (2, 2)]
    mpf = mpmath.mpf
    with mpmath.workprec(128):
        for i in range(n):
            lo, hi = r.lo[i].item(), r.hi[i].item()
            if math.isnan(lo):
                continue
            for c in combos:
                v = _mp_value(name, mpmath.mp, *(mpf(pts[k][j][i].item()) for k, j in enumerate(c)))
                assert not mpmath.isnan(v) and mpf(lo) <= v <= mpf(hi), (name, i, c, lo, hi, v)


X, Y, Z = Var("x"), Var("y"), Var("z")


def B(op, a, b):
    return Binary(op, a if not isinstance(a, (int, float)) else Num(float(a)),
                  b if not isinstance(b, (int, float)) else Num(float(b)))


def sq(a):
    return Unary("square", a)


def _sum(*xs):
    out = xs[0]
    for x in xs[1:]:
        out = B("add", out, x)
    return out


PHI = (1 + 5 ** 0.5) / 2
R2 = _sum(sq(X), sq(Y), sq(Z))
EXPRESSIONS = {
    "torus": B("sub", B("add", sq(B("sub", Unary("sqrt", B("add", sq(X), sq(Y))), Param("R"))), sq(Z)),
               sq(Param("r"))),
    "gyroid": _sum(*(B("mul", Unary("sin", B("mul", Param("k"), u)), Unary("cos", B("mul", Param("k"), v)))
                     for u, v in ((X, Y), (Y, Z), (Z, X)))),
    "barth": B("sub", B("mul", 4, B("mul", B("mul", B("sub", B("mul", PHI**2, sq(X)), sq(Y)),
                                               B("sub", B("mul", PHI**2, sq(Y)), sq(Z))),
                                         B("sub", B("mul", PHI**2, sq(Z)), sq(X)))),
               B("mul", 1 + 2 * PHI, PowI(B("sub", R2, 1), 2))),
    "scaled_sphere": B("mul", 1000, B("sub", R2, 1)),
    "thin_shell": B("sub", Unary("abs", B("sub", Unary("sqrt", R2), 1)), 1e-3),
    "soup": B("max", B("min", B("div", Unary("log", B("add", 1, sq(X))), B("sub", Y, 0.3)),
                       B("pow", Unary("exp", Unary("neg", Z)), B("add", X, 0.5))),
              B("add", PowI(Unary("cos", B("mul", X, Z)), -3), PowI(Y, 5))),
}
PARAMS = {"R": 1.0, "r": 0.25, "k": 10.0}
POINT_OPS = {"neg": torch.neg, "abs": torch.abs, "sqrt": torch.sqrt, "exp": torch.exp, "log": torch.log,
             "sin": torch.sin, "cos": torch.cos, "square": torch.square, "add": torch.add, "sub": torch.sub,
             "mul": torch.mul, "div": torch.div, "min": torch.minimum, "max": torch.maximum, "pow": torch.pow}


def point_eval(node, p):
    """Plain float64 pointwise evaluation (recursive; test trees are shallow)."""
    if isinstance(node, Num):
        return torch.full(p.shape[:-1], node.value, dtype=F64)
    if isinstance(node, Var):
        return p[..., "xyz".index(node.name)]
    if isinstance(node, Param):
        return torch.full(p.shape[:-1], PARAMS[node.name], dtype=F64)
    if isinstance(node, PowI):
        return torch.pow(point_eval(node.arg, p), node.n)
    if isinstance(node, Unary):
        return POINT_OPS[node.op](point_eval(node.arg, p))
    return POINT_OPS[node.op](point_eval(node.left, p), point_eval(node.right, p))


@pytest.mark.parametrize("name", sorted(EXPRESSIONS))
def test_expression_encloses_random_points(name):
    g, n = torch.Generator().manual_seed(4000 + sorted(EXPRESSIONS).index(name)), 20_000
    c = torch.rand(n, 3, generator=g, dtype=F64) * 4 - 2
    hw = 10 ** (torch.rand(n, 3, generator=g, dtype=F64) * 9 - 9) * (torch.rand(n, 3, generator=g) < 0.9)
    lo, hi = c - hw, c + hw
    lo = torch.where(torch.rand(n, 3, generator=g) < 0.1, torch.minimum(lo, torch.zeros(())), lo)  # touch 0
    flo, fhi = ia.interval_eval(EXPRESSIONS[name], lo, hi, PARAMS)
    t = torch.rand(4, n, 3, generator=g, dtype=F64)
    pts = torch.cat([torch.stack([lo, hi]), torch.minimum(torch.maximum(lo * (1 - t) + hi * t, lo), hi)])
    assert_encloses((flo, fhi), point_eval(EXPRESSIONS[name], pts), name)
    if name != "soup":                                                    # no domain error possible there
        assert not flo.isnan().any()


PARSED = {  # text, params: the same hard cases through the parser, against the torch evaluator
    "torus": ("(sqrt(x^2 + y^2) - R)^2 + z^2 - r^2", {"R": 1.0, "r": 0.25}),
    "barth": ("4*(f^2*x^2 - y^2)*(f^2*y^2 - z^2)*(f^2*z^2 - x^2) - (1 + 2*f)*(x^2 + y^2 + z^2 - 1)^2",
              {"f": PHI}),
    "double_root": ("(length(p) - 1)^2", {}),
    "blend": ("smin(length(p) - 1, abs(z) - 0.01, 0.2) + clamp(x, -0.5, 0.5) / (1 + y^-2)", {}),
}


@pytest.mark.parametrize("name", sorted(PARSED))
def test_parsed_expression_encloses_torch_evaluator(name):
    expression = pytest.importorskip("ssbench.implicit.expression")
    text, params = PARSED[name]
    e = expression.parse(text, params=params)
    g, n = torch.Generator().manual_seed(8000 + len(name)), 20_000
    lo = torch.rand(n, 3, generator=g, dtype=F64) * 4 - 2
    hi = lo + 10 ** (torch.rand(n, 3, generator=g, dtype=F64) * 8 - 8) * (torch.rand(n, 3, generator=g) < 0.9)
    flo, fhi = e.interval(lo, hi)
    t = torch.rand(3, n, 3, generator=g, dtype=F64)
    pts = torch.cat([torch.stack([lo, hi]), torch.minimum(torch.maximum(lo * (1 - t) + hi * t, lo), hi)])
    assert_encloses((flo, fhi), e(pts), name)
