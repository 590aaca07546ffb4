"""Dr.Jit interval evaluator: the same enclosure tests as the torch evaluator, on the same 10⁵ random boxes.

Every operator's Dr.Jit enclosure must hold the float64 values at the box corners and at random interior points
(NaN interval: may hold anything; a NaN value needs a NaN interval), and must contain the torch evaluator's
enclosure (an independent implementation with exact directed rounding: never tighter). The library functions'
accuracy that the widening relies on is measured against 120-bit mpmath. Catalog expressions are checked as
whole trees, through their object transforms and unions.
"""
import math

import pytest
import torch

from ssbench.implicit import interval as ia
from ssbench.implicit import interval_drjit as idr
from ssbench.implicit.parser import parse_node
from tests.implicit.test_interval import BINARY_CASES, N, UNARY_CASES, assert_encloses, pool

F64 = torch.float64


@pytest.fixture(scope="module")
def L():
    from ssbench.reference import backend
    if not backend.is_jit():
        pytest.skip("needs a vectorised Mitsuba variant (libllvm19)")
    import drjit.llvm as L
    return L


def dj(L, t):
    return L.Float64(t.contiguous().numpy())


def tt(v):
    return torch.from_numpy(v.numpy().copy())


def node_interval(L, node, *boxes):
    """The Dr.Jit enclosure of ``node`` (over variables x, y) on torch intervals ``boxes``."""
    zero = boxes[0].lo * 0
    lo = [dj(L, b.lo) for b in boxes] + [dj(L, zero)] * (3 - len(boxes))
    hi = [dj(L, b.hi) for b in boxes] + [dj(L, zero)] * (3 - len(boxes))
    flo, fhi = idr.interval_drjit(node, lo, hi)
    return tt(flo), tt(fhi)


def assert_contains(outer, inner, what):
    (olo, ohi), (ilo, ihi) = outer, inner
    ok = olo.isnan() | ((olo <= ilo) & (ohi >= ihi))          # a NaN torch bound: the Dr.Jit one must be NaN too
    assert bool(ok.all()), f"{what}: {int((~ok).sum())} Dr.Jit enclosures tighter than torch's"
    assert bool((~ilo.isnan() | olo.isnan()).all()), f"{what}: NaN lost"


X, Y = parse_node("x"), parse_node("y")


@pytest.mark.parametrize("name", sorted(set(UNARY_CASES) - {"neg"}))
def test_unary_encloses_random_points_and_the_torch_enclosure(L, name):
    op, f, which = UNARY_CASES[name]
    x, inner = pool(which)
    from ssbench.implicit.ast import Unary
    r = node_interval(L, Unary(name, X), x)
    assert_encloses(r, f(torch.cat([torch.stack([x.lo, x.hi]), inner])), name)
    assert_contains(r, tuple(op(x)), name)


@pytest.mark.parametrize("name", sorted(set(BINARY_CASES) - {"pow"}))
def test_binary_encloses_random_points_and_the_torch_enclosure(L, name):
    op, f, which = BINARY_CASES[name]
    (x, xin), (y, yin) = pool(which), pool("b")
    from ssbench.implicit.ast import Binary
    r = node_interval(L, Binary(name, X, Y), x, y)
    px = torch.cat([torch.stack([x.lo, x.lo, x.hi, x.hi]), xin])
    py = torch.cat([torch.stack([y.lo, y.hi, y.lo, y.hi]), yin])
    assert_encloses(r, f(px, py), name)
    assert_contains(r, tuple(op(x, y)), name)


@pytest.mark.parametrize("n", [-3, -2, 0, 1, 2, 3, 8])
def test_powi_encloses_random_points(L, n):
    x, inner = pool("a")
    from ssbench.implicit.ast import PowI
    r = node_interval(L, PowI(X, n), x)
    assert_encloses(r, torch.pow(torch.cat([torch.stack([x.lo, x.hi]), inner]), n), f"powi {n}")
    assert_contains(r, tuple(ia.powi(x, n)), f"powi {n}")


def test_domain_rules_and_known_signs(L):
    """NaN where a domain error is possible, the whole line for a divisor holding 0, exact zeros kept."""
    def box(lo, hi):
        return ia.Interval(torch.tensor([float(lo)], dtype=F64), torch.tensor([float(hi)], dtype=F64))

    def ev(text, *b):
        lo, hi = node_interval(L, parse_node(text), *b)
        return lo.item(), hi.item()

    assert all(math.isnan(v) for v in ev("sqrt(x)", box(-1, 1)) + ev("log(x)", box(-1, 1)))
    assert ev("log(x)", box(0, 1))[0] == -math.inf
    assert ev("1 / x", box(-1, 2)) == (-math.inf, math.inf)
    assert all(math.isnan(v) for v in ev("x / y", box(-1, 1), box(0, 1)) + ev("x * y", box(0, 1), box(1, math.inf)))
    assert ev("sqrt(x^2 + y^2)", box(-1, 1), box(-2, 3))[0] == 0.0          # not NaN through the widening
    assert all(math.isnan(v) for v in ev("min(x, y)", box(0, 1), box(math.nan, math.nan)))   # NaN propagates
    lo, hi = ev("sin(x)", box(1.0, 2.0))
    assert hi == 1.0 and math.sin(1.0) - 1e-12 < lo < math.sin(1.0)
    assert ev("cos(x)", box(1e5, 1e5 + 1e-9)) == (-1.0, 1.0)                 # beyond TRIG_LIMIT


@pytest.mark.parametrize("name", ["exp", "log", "sin", "cos"])
def test_library_functions_are_within_a_few_ulps(L, name):
    """The premise of the ``LIB_REL`` widening (2⁻⁴⁴ ≈ 256 ulps): Dr.Jit's float64 functions err ≤ 4 ulps."""
    mp = pytest.importorskip("mpmath")
    mp.mp.prec = 120
    g = torch.Generator().manual_seed(3)
    if name == "log":
        x = torch.exp(torch.rand(2000, generator=g, dtype=F64) * 1380 - 690)
    else:
        span = 700.0 if name == "exp" else idr.TRIG_LIMIT
        x = (torch.rand(2000, generator=g, dtype=F64) * 2 - 1) * span
    import drjit as dr
    got = getattr(dr, name)(dj(L, x)).numpy()
    worst = 0.0
    for xi, ri in zip(x.tolist(), got.tolist()):
        exact = getattr(mp, name)(mp.mpf(xi))
        worst = max(worst, float(abs(mp.mpf(ri) - exact) / math.ulp(float(exact))))
    assert worst <= 4.0, worst


@pytest.mark.parametrize("scene", ["torus", "thin_shell", "gyroid_sheet", "barth_sextic", "displaced_torus",
                                   "animated"])
def test_catalog_surfaces_enclose_sampled_values(L, scene):
    from ssbench.implicit.scene import load
    surf = load(scene).surface(0)
    g = torch.Generator().manual_seed(7)
    lo0, hi0 = (torch.tensor(b, dtype=F64) for b in surf.bounds)
    n = 20_000
    c = lo0 + (hi0 - lo0) * torch.rand(n, 3, generator=g, dtype=F64)
    w = (hi0 - lo0) * 0.05 * torch.rand(n, 3, generator=g, dtype=F64) ** 3
    lo, hi = c - w, c + w
    dlo, dhi = idr.surface_interval_drjit(surf, [dj(L, lo[:, k]) for k in range(3)],
                                          [dj(L, hi[:, k]) for k in range(3)])
    r = tt(dlo), tt(dhi)
    for _ in range(4):
        p = lo + (hi - lo) * torch.rand(n, 3, generator=g, dtype=F64)
        assert_encloses(r, surf.f(p), scene)
    assert_contains(r, surf.interval(lo, hi), scene)
    excluded = (r[0] > 0) | (r[1] < 0)
    assert int(excluded.sum()) > n // 2                                     # and it still excludes boxes


def test_pow_is_left_to_the_torch_evaluator():
    assert idr.supported(parse_node("sqrt(x^2 + 1) - sin(y)")) and not idr.supported(parse_node("x ^ 0.5"))
    assert N >= 10_000
