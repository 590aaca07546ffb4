"""The Dr.Jit evaluator agrees with the torch float64 evaluator (every op, full surfaces, symbolic loops)."""
import math

import numpy as np
import pytest
import torch

from ssbench.implicit.ast import BINARY_OPS, UNARY_OPS, Binary, PowI, Unary, Var
from ssbench.implicit.expression import parse
from ssbench.implicit.parser import parse_node
from ssbench.implicit.torch_eval import evaluate
from ssbench.reference import backend

pytestmark = pytest.mark.mitsuba
X, Y = Var("x"), Var("y")
PHI = (1 + math.sqrt(5)) / 2
SURFACES = {
    "torus": ("(sqrt(x^2 + z^2) - R)^2 + y^2 - r^2", {"R": 1.2, "r": 0.4}),
    "torus_sdf": ("length(vec3(length(vec3(x, 0, z)) - R, y, 0)) - r", {"R": 1.2, "r": 0.4}),
    "gyroid": ("sin(k*x)*cos(k*y) + sin(k*y)*cos(k*z) + sin(k*z)*cos(k*x)", {"k": 9.0}),
    "barth": ("4*(f^2*x^2 - y^2)*(f^2*y^2 - z^2)*(f^2*z^2 - x^2) - (1 + 2*f)*(x^2 + y^2 + z^2 - 1)^2",
              {"f": PHI}),
    "box_smin": ("smin(length(max(abs(p) - vec3(1, 0.5, 0.5), 0)) - 0.1, length(p - c) - 0.7, 0.3)", {}),
    "powers": ("abs(x)^0.5 + abs(y)^1.5 + pow(abs(z) + 0.1, -2.5) + x^-3 + clamp(y, -1, 1)^5 - exp(-z) + log(x^2)",
               {}),
}
DEFS = {"c": "vec3(0.5, 0.2, -0.1)"}


@pytest.fixture(scope="module")
def dr():
    backend.mitsuba()
    import drjit
    return drjit


@pytest.fixture(scope="module")
def pts():
    g = torch.Generator().manual_seed(3)
    return torch.rand(1000, 3, generator=g, dtype=torch.float64) * 4 - 2


def run(dr, node, p, params=None, jit=None):
    """Dr.Jit values at the rows of ``p`` as a numpy array (Float64 arrays when JIT works, else Python floats)."""
    jit = backend.is_jit() if jit is None else jit
    cols = p.numpy().T
    if jit:
        from drjit.llvm import Float64
        return np.asarray(evaluate_drjit(node, *(Float64(c) for c in cols), params))
    return np.array([evaluate_drjit(node, float(a), float(b), float(c), params) for a, b, c in zip(*cols)])


def evaluate_drjit(*a, **k):
    from ssbench.implicit.drjit_eval import evaluate_drjit as f
    return f(*a, **k)


def check(dr, node, p, params=None, rtol=1e-12, jit=None):
    want = evaluate(node, p, params).numpy()
    got = run(dr, node, p, params, jit)
    assert got.shape == want.shape
    scale = np.nanmax(np.abs(want[np.isfinite(want)]), initial=1.0)
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale, equal_nan=True)


@pytest.mark.parametrize("op", UNARY_OPS)
def test_each_unary_op(dr, pts, op):
    check(dr, Unary(op, X), pts * 3)


@pytest.mark.parametrize("op", BINARY_OPS)
def test_each_binary_op(dr, pts, op):
    check(dr, Binary(op, X, Y), pts)
    check(dr, Binary(op, X, Y), pts[:50], jit=False)          # Python floats take a separate path


@pytest.mark.parametrize("n", [-64, -5, -2, -1, 0, 1, 2, 3, 7, 32, 64])
def test_integer_powers(dr, pts, n):
    check(dr, PowI(X, n), pts / 2)


def test_special_values_match_torch(dr):
    nan, inf = math.nan, math.inf
    a = [-2.0, -2.0, 0.0, 0.0, 0.0, -8.0, inf, -inf, -inf, 1.0, -0.0, -0.0, nan, -1.0, 0.5, 3.0, -3.0, 2.0]
    b = [3.0, 0.5, 0.5, 0.0, -1.0, 1 / 3, -0.5, 3.0, 0.5, nan, -1.0, 2.0, 0.0, inf, -inf, inf, -2.0, nan]
    p = torch.tensor([a, b, [0.0] * len(a)], dtype=torch.float64).T
    for text in ("pow(x, y)", "x / y", "y / x", "min(x, y)", "max(x, y)", "sqrt(x)", "log(x)", "x^0", "x^-1",
                 "exp(y)", "x*y"):
        node = parse_node(text)
        want = evaluate(node, p).numpy()
        for jit in {False, backend.is_jit()}:
            got = run(dr, node, p, jit=jit)
            np.testing.assert_array_equal(np.signbit(got[got == 0]), np.signbit(want[want == 0]), err_msg=text)
            np.testing.assert_allclose(got, want, rtol=1e-15, atol=0, equal_nan=True, err_msg=f"{text} jit={jit}")


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_full_surfaces(dr, pts, name):
    text, params = SURFACES[name]
    e = parse(text, params=params, defs=DEFS if "c" in text else None)
    check(dr, e.node, pts, dict(e.params))
    if backend.is_jit():
        from drjit.llvm import Float64
        cols = [Float64(c) for c in pts.numpy().T]
        np.testing.assert_allclose(np.asarray(e.drjit(*cols)), e(pts).numpy(), rtol=1e-12, atol=1e-12 * 100,
                                   equal_nan=True)


def test_constants_parameters_and_widths(dr, pts):
    assert evaluate_drjit(parse_node("1/0 + x*0"), 2.0, 0.0, 0.0) == math.inf
    assert evaluate_drjit(parse_node("2 + 3"), 1.0, 2.0, 3.0) == 5.0
    with pytest.raises(ValueError, match="missing value for parameter 'r'"):
        evaluate_drjit(parse_node("x - r", {"r": 1}), 1.0, 2.0, 3.0)
    if not backend.is_jit():
        pytest.skip("array widths need a JIT backend")
    from drjit.llvm import Float64
    xs = Float64(pts[:, 0].numpy())
    out = evaluate_drjit(parse_node("2 + 3"), xs, xs, xs)
    assert isinstance(out, Float64) and dr.width(out) == 1000 and np.all(np.asarray(out) == 5.0)
    out = evaluate_drjit(parse_node("x^0 + r", {"r": 1}), xs, xs, xs, {"r": Float64(pts[:, 1].numpy())})
    np.testing.assert_allclose(np.asarray(out), 1 + pts[:, 1].numpy(), rtol=1e-15)


def test_usable_inside_a_symbolic_while_loop(dr):
    """A dense march inside ``dr.while_loop`` finds the sphere's first hit (no Python branching on values)."""
    if not backend.is_jit():
        pytest.skip("symbolic loops need a JIT backend")
    from drjit.llvm import Bool, Float64, UInt32
    e = parse("pow(x^2 + y^2 + (z - 4)^2, 0.5) - r", params={"r": 1.0})
    offsets = np.linspace(-0.9, 0.9, 64)
    ox, oy = Float64(offsets), Float64(0.3 * offsets)
    h = 1e-3

    def cond(t, i, hit):
        return (i < 6000) & ~hit

    def body(t, i, hit):
        f = e.drjit(ox, oy, t + h)
        hit = f < 0.0
        return dr.select(hit, t, t + h), i + 1, hit

    t, i, hit = dr.while_loop((Float64(np.zeros(64)), UInt32(0), Bool(False)), cond, body)
    t_true = 4.0 - np.sqrt(1.0 - offsets ** 2 - (0.3 * offsets) ** 2)
    assert np.all(np.asarray(hit))
    assert np.all(np.abs(np.asarray(t) - t_true) <= h)
