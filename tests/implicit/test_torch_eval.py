"""The torch evaluator and :class:`Expression`: closed forms, analytic gradients, semantics, deep trees."""
import math
import sys
import types

import pytest
import torch

from ssbench.implicit.ast import BINARY_OPS, UNARY_OPS, Binary, Num, Param, PowI, Unary, Var
from ssbench.implicit.expression import Expression, ExpressionError, parse
from ssbench.implicit.parser import parse_node
from ssbench.implicit.torch_eval import evaluate, f_and_grad

X, Y = Var("x"), Var("y")
F64 = torch.float64
TORUS = "(sqrt(x^2 + z^2) - R)^2 + y^2 - r^2"
TORUS_SDF = "length(vec3(length(vec3(x, 0, z)) - R, y, 0)) - r"


@pytest.fixture(scope="module")
def pts():
    g = torch.Generator().manual_seed(11)
    return torch.rand(1000, 3, generator=g, dtype=F64) * 6 - 3


_TORCH_UNARY = {"neg": torch.neg, "abs": torch.abs, "sqrt": torch.sqrt, "exp": torch.exp, "log": torch.log,
                "sin": torch.sin, "cos": torch.cos, "square": lambda a: a * a}
_TORCH_BINARY = {"add": torch.add, "sub": torch.sub, "mul": torch.mul, "div": torch.div, "min": torch.minimum,
                 "max": torch.maximum, "pow": torch.pow}


@pytest.mark.parametrize("op", UNARY_OPS)
def test_each_unary_op(op, pts):
    x = pts[:, 0]
    torch.testing.assert_close(evaluate(Unary(op, X), pts), _TORCH_UNARY[op](x), equal_nan=True, rtol=0, atol=0)


@pytest.mark.parametrize("op", BINARY_OPS)
def test_each_binary_op(op, pts):
    x, y = pts[:, 0], pts[:, 1]
    torch.testing.assert_close(evaluate(Binary(op, X, Y), pts), _TORCH_BINARY[op](x, y), equal_nan=True,
                               rtol=0, atol=0)


@pytest.mark.parametrize("n", [-64, -7, -2, -1, 0, 1, 2, 3, 5, 17, 63, 64])
def test_integer_powers(n, pts):
    x = pts[:, 0] / 2.9            # |x| <= 1.04: no overflow at n = ±64 except near 0
    torch.testing.assert_close(evaluate(PowI(X, n), pts / 2.9), torch.pow(x, n), rtol=1e-13, atol=0)


def test_domain_semantics():
    nan, inf = math.nan, math.inf
    p = torch.tensor([[-1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [nan, 1.0, 0.0]], dtype=F64)
    assert torch.isnan(evaluate(parse_node("sqrt(x)"), p)[0])
    assert evaluate(parse_node("log(y)"), p)[1] == -inf and torch.isnan(evaluate(parse_node("log(x)"), p)[0])
    assert evaluate(parse_node("1/y"), p)[1] == inf and torch.isnan(evaluate(parse_node("y/y"), p)[1])
    assert torch.isnan(evaluate(parse_node("min(x, y)"), p)[2]) and torch.isnan(evaluate(parse_node("max(y, x)"), p)[2])
    assert evaluate(parse_node("x^0"), p)[2] == 1.0                     # like torch.pow(nan, 0)
    assert evaluate(parse_node("y^-1"), p)[1] == inf
    a = torch.tensor([-2.0, -2.0, 0.0, 0.0, 0.0, -8.0, inf, -inf, 1.0, -0.0], dtype=F64)
    b = torch.tensor([3.0, 0.5, 0.5, 0.0, -1.0, 1 / 3, -0.5, 3.0, nan, -1.0], dtype=F64)
    got = evaluate(Binary("pow", X, Y), torch.stack([a, b, 0 * a], -1))
    torch.testing.assert_close(got, torch.pow(a, b), equal_nan=True, rtol=0, atol=0)


def test_sphere_and_torus_closed_forms(pts):
    x, y, z = pts.unbind(-1)
    R, r = 1.5, 0.4
    q = torch.sqrt(x * x + z * z)
    torch.testing.assert_close(evaluate(parse_node(TORUS, {"R": 1, "r": 1}), pts, {"R": R, "r": r}),
                               (q - R) ** 2 + y * y - r * r, rtol=1e-13, atol=1e-13)
    d = torch.sqrt((q - R) ** 2 + y * y)
    f, g = f_and_grad(parse_node(TORUS_SDF, {"R": 1, "r": 1}), pts, {"R": R, "r": r})
    torch.testing.assert_close(f, d - r, rtol=1e-13, atol=1e-13)
    want = torch.stack([(q - R) / d * x / q, y / d, (q - R) / d * z / q], -1)
    torch.testing.assert_close(g, want, rtol=1e-12, atol=1e-12)
    f, g = f_and_grad(parse_node("length(p) - 1"), pts)
    torch.testing.assert_close(g, pts / pts.norm(dim=-1, keepdim=True), rtol=1e-13, atol=1e-13)


def test_gyroid_gradient_is_analytic(pts):
    k = 7.0
    node = parse_node("sin(k*x)*cos(k*y) + sin(k*y)*cos(k*z) + sin(k*z)*cos(k*x)", params={"k": k})
    x, y, z = (k * pts).unbind(-1)
    f, g = f_and_grad(node, pts, {"k": k})
    torch.testing.assert_close(f, x.sin() * y.cos() + y.sin() * z.cos() + z.sin() * x.cos(), rtol=1e-12, atol=1e-12)
    want = k * torch.stack([x.cos() * y.cos() - z.sin() * x.sin(), -x.sin() * y.sin() + y.cos() * z.cos(),
                            -y.sin() * z.sin() + z.cos() * x.cos()], -1)
    torch.testing.assert_close(g, want, rtol=1e-12, atol=1e-12)
    assert g.norm(dim=-1).max() <= 2 * math.sqrt(3) * k        # the Lipschitz bound of a gyroid


def test_gradients_flow_into_tensor_parameters(pts):
    r = torch.tensor(0.7, dtype=F64, requires_grad=True)
    f = evaluate(parse_node("x^2 + y^2 + z^2 - r^2", {"r": 1}), pts, {"r": r})
    f.sum().backward()
    torch.testing.assert_close(r.grad, torch.tensor(-2 * 0.7 * len(pts), dtype=F64))
    R = torch.tensor(1.5, dtype=torch.float32, requires_grad=True)        # other dtype: converted, grad kept
    f = evaluate(parse_node(TORUS_SDF, {"R": 1, "r": 1}), pts, {"R": R, "r": 0.3})
    (dR,) = torch.autograd.grad(f.sum(), R)
    q = pts[:, [0, 2]].norm(dim=-1)
    want = (-(q - 1.5) / torch.sqrt((q - 1.5) ** 2 + pts[:, 1] ** 2)).sum()
    torch.testing.assert_close(dR, want.float(), rtol=1e-5, atol=1e-4)


def test_missing_parameter_is_named(pts):
    with pytest.raises(ValueError, match="missing value for parameter 'r'"):
        evaluate(parse_node("x - r", {"r": 1}), pts)


def test_f_and_grad_under_no_grad_keeps_no_graph(pts):
    with torch.no_grad():
        f, g = f_and_grad(parse_node("x^3 + 2*y"), pts)
    assert not f.requires_grad and not g.requires_grad
    torch.testing.assert_close(g, torch.stack([3 * pts[:, 0] ** 2, 2 + 0 * pts[:, 0], 0 * pts[:, 0]], -1))
    f, g = f_and_grad(parse_node("2 + 3"), pts)
    assert torch.equal(f, torch.full((1000,), 5.0, dtype=F64)) and torch.equal(g, torch.zeros_like(pts))


def test_dtype_shape_and_input_checks():
    p = torch.rand(2, 4, 3)
    out = evaluate(parse_node("x + y*z + 1"), p)
    assert out.dtype == torch.float32 and out.shape == (2, 4)
    torch.testing.assert_close(out, p[..., 0] + p[..., 1] * p[..., 2] + 1)
    assert evaluate(parse_node("1 + 1"), p).shape == (2, 4)
    w = torch.arange(4, dtype=torch.float32)
    torch.testing.assert_close(evaluate(parse_node("x*w", {"w": 1}), p, {"w": w}), p[..., 0] * w)
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3\)"):
        evaluate(parse_node("x"), torch.zeros(4, 2))
    with pytest.raises(TypeError, match="floating-point"):
        evaluate(parse_node("x"), torch.zeros(4, 3, dtype=torch.int64))


def test_deep_and_shared_trees_are_evaluated_iteratively():
    p = torch.tensor([[0.25, 2.0, -1.0]], dtype=F64)
    chain = parse_node("+".join(["x"] * 5000))               # left-deep tree of depth ~5000
    torch.testing.assert_close(evaluate(chain, p), torch.tensor([1250.0], dtype=F64))
    deep = X
    for _ in range(20_000):                                   # far beyond Python's recursion limit
        deep = Unary("neg", deep)
    assert evaluate(deep, p).item() == 0.25
    dag = X
    for _ in range(60):                                       # tree size 2^61: only a memo by id() copes
        dag = Binary("add", dag, dag)
    assert evaluate(dag, p).item() == 0.25 * 2.0 ** 60
    f, g = f_and_grad(dag, p)
    assert g[0, 0].item() == 2.0 ** 60


def test_expression_api(pts):
    e = parse(TORUS, params={"r": 0.5, "R": 2})
    assert e.params == (("R", 2.0), ("r", 0.5)) and e.defs == () and e.n_ops == 15
    assert e == parse(TORUS, params={"R": 2.0, "r": 0.5}) and hash(e) == hash(parse(TORUS, {"R": 2, "r": 0.5}))
    assert e != parse(TORUS, params={"R": 2.0, "r": 0.6}) and "node" not in repr(e)
    e2 = e.with_params(r=0.25)
    assert e2.node is e.node and dict(e2.params) == {"R": 2.0, "r": 0.25}
    x, y, z = pts.unbind(-1)
    torch.testing.assert_close(e2(pts), (torch.sqrt(x * x + z * z) - 2) ** 2 + y * y - 0.0625)
    torch.testing.assert_close(e(pts, {"r": 0.25}), e2(pts))
    f, g = e2.f_and_grad(pts)
    torch.testing.assert_close(f, e2(pts))
    with pytest.raises(ValueError, match="unknown parameter 'k'"):
        e.with_params(k=1.0)
    with pytest.raises(ValueError, match="unknown parameter 'k'"):
        e(pts, {"k": 1.0})
    with pytest.raises(ValueError, match="parameter 'r' must be finite"):
        parse(TORUS, params={"r": math.inf, "R": 1})
    with pytest.raises(ExpressionError, match="unknown name 'R'"):
        parse(TORUS, params={"r": 1})
    d = parse("length(p - c) - 1", defs={"c": "vec3(0, 1, 0)"})
    assert d.defs == (("c", "vec3(0, 1, 0)"),)
    assert isinstance(Expression, type) and isinstance(parse("x").node, Var)


def test_interval_delegates_with_merged_params(monkeypatch):
    calls = []
    fake = types.ModuleType("ssbench.implicit.interval")
    fake.interval_eval = lambda node, lo, hi, params=None: calls.append((node, lo, hi, params)) or (lo, hi)
    monkeypatch.setitem(sys.modules, "ssbench.implicit.interval", fake)
    e = parse("x - r", params={"r": 1.0, "s": 2.0})
    assert e.interval(-1.0, 1.0, {"r": 3.0}) == (-1.0, 1.0)
    assert calls == [(e.node, -1.0, 1.0, {"r": 3.0, "s": 2.0})]
    assert e.node == Binary("sub", X, Param("r")) and Num(1.0) != Num(2.0)
