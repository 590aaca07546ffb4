"""The whitelist parser: precedence, lowering of vectors and helpers, definitions, limits, refusals."""
import builtins
import math

import pytest
import torch

from ssbench.implicit.ast import Binary, Num, Param, PowI, Unary, Var, count_nodes
from ssbench.implicit.parser import MAX_DEPTH, MAX_NODES, MAX_TEXT, ExpressionError, parse_node
from ssbench.implicit.torch_eval import evaluate

X, Y = Var("x"), Var("y")


@pytest.fixture(scope="module")
def pts():
    g = torch.Generator().manual_seed(5)
    return torch.rand(500, 3, generator=g, dtype=torch.float64) * 4 - 2


def ev(text, p, params=None, defs=None):
    return evaluate(parse_node(text, params, defs), p, params)


@pytest.mark.parametrize("text, want", [
    ("-x^2", lambda x, y, z: -(x ** 2)),
    ("-x**2", lambda x, y, z: -(x ** 2)),
    ("2^3^2 + 0*x", lambda x, y, z: 512.0 + 0 * x),
    ("2**3**2 + 0*x", lambda x, y, z: 512.0 + 0 * x),
    ("1 - 2 - 3 + x", lambda x, y, z: x - 4),
    ("8 / 4 / 2 * x", lambda x, y, z: x),
    ("2*3^2 - x", lambda x, y, z: 18 - x),
    ("-2^2 + x", lambda x, y, z: x - 4),
    ("2^-1 * x", lambda x, y, z: 0.5 * x),
    ("x - -y", lambda x, y, z: x + y),
    ("+x - +y", lambda x, y, z: x - y),
    ("2*-x", lambda x, y, z: -2 * x),
    ("x*y/z", lambda x, y, z: (x * y) / z),
    ("x/y*z", lambda x, y, z: (x / y) * z),
    ("x - y + z", lambda x, y, z: (x - y) + z),
    ("(1 + 2) * x", lambda x, y, z: 3 * x),
    ("abs(x)^abs(y)^0.5", lambda x, y, z: x.abs() ** (y.abs() ** 0.5)),
    ("x^3 - y*z^2", lambda x, y, z: x ** 3 - y * z ** 2),
    ("1e-3*x + .5 + 2.5E2 + 3.", lambda x, y, z: 1e-3 * x + 253.5),
    ("pi*x", lambda x, y, z: math.pi * x),
    ("-(-(x))", lambda x, y, z: x),
])
def test_precedence_and_associativity(text, want, pts):
    torch.testing.assert_close(ev(text, pts), want(*pts.unbind(-1)), rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("text, node", [
    ("x^2", Unary("square", X)),
    ("pow(x, 4/2)", Unary("square", X)),
    ("x^3", PowI(X, 3)),
    ("x^-3", PowI(X, -3)),
    ("x**(-64)", PowI(X, -64)),
    ("x^0", PowI(X, 0)),
    ("x^0.5", Binary("pow", X, Num(0.5))),
    ("x^-0.5", Binary("pow", X, Num(-0.5))),
    ("x^y", Binary("pow", X, Y)),
    ("2^x", Binary("pow", Num(2.0), X)),
    ("-3", Num(-3.0)),
    ("(((x)))", X),
    ("2*pi", Num(2 * math.pi)),
    ("log(0)", Unary("log", Num(0.0))),        # not folded: evaluates to -inf at run time
    ("1/0", Binary("div", Num(1.0), Num(0.0))),
    ("sqrt(4) + x", Binary("add", Num(2.0), X)),
    ("union(x, y)", Binary("min", X, Y)),
    ("intersect(x, y)", Binary("max", X, Y)),
    ("subtract(x, y)", Binary("max", X, Unary("neg", Y))),
    ("clamp(x, 0, 1)", Binary("min", Binary("max", X, Num(0.0)), Num(1.0))),
    ("min(x, y, 1)", Binary("min", Binary("min", X, Y), Num(1.0))),
])
def test_lowered_tree(text, node):
    assert parse_node(text) == node


def test_parameters_stay_leaves():
    node = parse_node("x - r^2", params={"r": 1.0})
    assert node == Binary("sub", X, Unary("square", Param("r")))


@pytest.mark.parametrize("text, want", [
    ("length(max(abs(p) - vec3(1, 1, 1), 0))",
     lambda p: torch.clamp(p.abs() - 1, min=0).norm(dim=-1)),
    ("length(p)", lambda p: p.norm(dim=-1)),
    ("dot(p, vec3(1, 2, 3))", lambda p: p @ torch.tensor([1.0, 2, 3], dtype=p.dtype)),
    ("length(p*2 - 1)", lambda p: (p * 2 - 1).norm(dim=-1)),
    ("length(2*p/3 + vec3(x, 0, 1))", lambda p: (2 * p / 3 + torch.stack(
        [p[:, 0], 0 * p[:, 0], 1 + 0 * p[:, 0]], -1)).norm(dim=-1)),
    ("length(-p) - length(p)", lambda p: 0 * p[:, 0]),
    ("length(min(p, 0.5))", lambda p: p.clamp(max=0.5).norm(dim=-1)),
    ("length(clamp(p, -0.5, 0.5))", lambda p: p.clamp(-0.5, 0.5).norm(dim=-1)),
    ("dot(abs(p), p)", lambda p: (p.abs() * p).sum(-1)),
    ("length(p*p)", lambda p: (p * p).norm(dim=-1)),
    ("length(1 / p)", lambda p: (1 / p).norm(dim=-1)),
    ("length(sqrt(abs(p)))", lambda p: p.abs().sqrt().norm(dim=-1)),
    ("dot(p - vec3(1, 0, 0), p + 1)", lambda p: ((p - torch.tensor([1.0, 0, 0], dtype=p.dtype)) * (p + 1)).sum(-1)),
])
def test_vector_lowering_matches_hand_computation(text, want, pts):
    torch.testing.assert_close(ev(text, pts), want(pts), rtol=1e-13, atol=1e-13)


def test_smin_is_the_quadratic_polynomial_smooth_min(pts):
    x, y, _ = pts.unbind(-1)
    k = 0.7
    h = torch.clamp(k - (x - y).abs(), min=0) / k
    want = torch.minimum(x, y) - h * h * k / 4
    torch.testing.assert_close(ev("smin(x, y, 0.7)", pts), want, rtol=1e-14, atol=1e-14)
    got = ev("smin(x, y, k)", pts, params={"k": k})
    torch.testing.assert_close(got, want, rtol=1e-14, atol=1e-14)
    far = (x - y).abs() >= k
    assert torch.equal(got[far], torch.minimum(x, y)[far])          # exactly min away from the seam
    assert torch.all(got <= torch.minimum(x, y))
    same = torch.tensor([[0.3, 0.3, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(ev("smin(x, y, 0.7)", same), torch.tensor([0.3 - 0.7 / 4], dtype=torch.float64))


def test_definitions_are_parsed_once_and_shared(pts):
    defs = {"c": "vec3(1, 0, 0)", "q": "p - c", "d": "length(q)"}
    node = parse_node("d*d - r", params={"r": 0.5}, defs=defs)
    assert node.left.left is node.left.right            # the same sqrt(...) object, not a copy
    want = ((pts - torch.tensor([1.0, 0, 0], dtype=pts.dtype)).norm(dim=-1)) ** 2 - 0.5
    torch.testing.assert_close(ev("d*d - r", pts, {"r": 0.5}, defs), want, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("defs, text, msg", [
    ({"a": "b + 1", "b": "a * 2"}, "a", "definitions form a cycle: a -> b -> a"),
    ({"a": "a + 1"}, "x", "definitions form a cycle: a -> a"),
    ({"a": "x +"}, "x", "definition 'a': column 4: expected a number, a name or '(', got the end"),
    ({"a": "sin(x"}, "a", "expected ')' to close the '(' at column 4"),
    ({"x": "1"}, "x", "definition name 'x' shadows the variable 'x'"),
    ({"sin": "1"}, "x", "definition name 'sin' shadows the function 'sin'"),
    ({"_a": "1"}, "x", "names starting with '_' are not allowed"),
    ({"v": "p"}, "v", "the expression is a vector"),
])
def test_definition_errors(defs, text, msg):
    with pytest.raises(ExpressionError, match=msg.replace("(", r"\(").replace(")", r"\)")):
        parse_node(text, defs=defs)


def test_parameter_name_errors():
    for params, msg in [({"p": 1}, "shadows the variable 'p'"), ({"pi": 1}, "shadows the constant 'pi'"),
                        ({"max": 1}, "shadows the function 'max'"), ({"2r": 1}, "is not a valid name")]:
        with pytest.raises(ExpressionError, match=msg):
            parse_node("x", params=params)
    with pytest.raises(ExpressionError, match="'r' is both a parameter and a definition"):
        parse_node("x", params={"r": 1}, defs={"r": "2"})


MALICIOUS = [
    ("__import__('os')", 1, "names starting with '_' are not allowed"),
    ("().__class__", 2, "expected a number, a name or '(', got ')'"),
    ("x.__class__", 2, "attribute access is not allowed"),
    ("(x).real", 4, "attribute access is not allowed"),
    ("lambda: 1", 7, "unexpected character ':'"),
    ("lambda x: x", 1, "unknown name 'lambda'"),
    ("open('f')", 1, "unknown function 'open'"),
    ("eval('1')", 1, "unknown function 'eval'"),
    ("x; import os", 2, "unexpected character ';'"),
    ("[x for x in y]", 1, "unexpected character '['"),
    ("{}", 1, "unexpected character '{'"),
    ("'x'", 1, "strings are not allowed"),
    ("x if 1 else y", 3, "unexpected 'if' after a complete expression"),
    ("9**9**9", 2, "exponent too large: 387420489"),
    ("9^9^9", 2, "exponent too large"),
    ("x^100000", 2, "exponent too large: 100000"),
    ("x^-65", 2, "exponent too large"),
    ("x^64.5", 2, "exponent too large"),
    ("1e999", 1, "number overflows"),
    ("x @ y", 3, "unexpected character '@'"),
    ("x = 1", 3, "unexpected character '='"),
    ("x + \u0663", 5, "unexpected character"),                # an Arabic-Indic digit is not a number here
]


@pytest.mark.parametrize("text, col, msg", MALICIOUS)
def test_malicious_strings_are_refused(text, col, msg):
    with pytest.raises(ExpressionError) as e:
        parse_node(text)
    assert e.value.column == col and msg in e.value.what, str(e.value)


@pytest.mark.parametrize("text", ["(" * 5000 + "x" + ")" * 5000, "-" * 10000 + "x", "sin(" * 3000 + "x" + ")" * 3000,
                                  "x" + "^x" * 5000, "2^" * 5000 + "2"])
def test_deep_nesting_is_an_expression_error_not_a_recursion_error(text):
    with pytest.raises(ExpressionError, match="nested too deeply"):
        parse_node(text)


def test_depth_limit_is_exact():
    assert parse_node("(" * (MAX_DEPTH - 1) + "x" + ")" * (MAX_DEPTH - 1)) == X
    assert isinstance(parse_node("sin(" * (MAX_DEPTH - 1) + "x" + ")" * (MAX_DEPTH - 1)), Unary)
    assert parse_node("x +\n\t y\r\n") == Binary("add", X, Y)
    with pytest.raises(ExpressionError, match="nested too deeply"):
        parse_node("(" * MAX_DEPTH + "x" + ")" * MAX_DEPTH)


def test_long_input_is_refused():
    with pytest.raises(ExpressionError, match=f"expression too long \\({MAX_TEXT + 1} characters"):
        parse_node("x" + " " * MAX_TEXT)
    node = parse_node("+".join(["x"] * 5000))               # long but flat: fine, and deep as a tree
    assert count_nodes(node) == 9999


def test_node_limit_counts_expanded_definitions():
    defs = {"a0": "x + y"}
    for i in range(1, 40):
        defs[f"a{i}"] = f"a{i - 1} * a{i - 1}"               # tree size doubles each level
    with pytest.raises(ExpressionError, match=f"more than {MAX_NODES} nodes") as e:
        parse_node("x", defs=defs)
    assert "definition 'a15'" in str(e.value)


def test_never_calls_eval_exec_or_compile(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("the parser must not execute text")
    for name in ("eval", "exec", "compile", "__import__"):
        monkeypatch.setattr(builtins, name, boom)
    node = parse_node("smin(length(p - c) - 1, x^2 + y^3 - z, 0.5) * s", params={"s": 2.0}, defs={"c": "vec3(1,2,3)"})
    assert isinstance(node, Binary)


@pytest.mark.parametrize("text, col, msg", [
    ("length(x)", 1, "length: expected a vector, got a scalar"),
    ("dot(p, 1)", 1, "dot: expected a vector, got a scalar (argument 2)"),
    ("vec3(p, 1, 2)", 1, "vec3: expected a scalar, got a vector (argument 1)"),
    ("x + smin(p, 1, 1)", 5, "smin: expected a scalar, got a vector (argument 1)"),
    ("union(x, p)", 1, "union: expected a scalar, got a vector (argument 2)"),
    ("p^2", 2, "^: expected scalars, got a vector"),
    ("pow(x, p)", 1, "pow: expected scalars, got a vector"),
    ("p * 2", 1, "the expression is a vector"),
    ("smin(x, y, 0)", 1, "smin: k must be > 0, got 0"),
    ("smin(x, y, -1)", 1, "smin: k must be > 0, got -1"),
    ("min(x)", 1, "min: expected at least 2 arguments, got 1"),
    ("sin(x, y)", 1, "sin: expected 1 argument, got 2"),
    ("clamp(x, 1)", 1, "clamp: expected 3 arguments, got 2"),
    ("sin", 1, "'sin' is a function; call it as sin(...)"),
    ("x(1)", 1, "'x' is not a function"),
    ("foo + 1", 1, "unknown name 'foo'; known: variables: x, y, z, p; constants: pi; parameters: r"),
    ("2x", 2, "unexpected 'x' after a complete expression (implicit multiplication is not supported"),
    ("x)", 2, "unexpected ')' after a complete expression"),
    ("(x", 3, "expected ')' to close the '(' at column 1, got the end"),
    ("max(x, y", 9, "expected ')' to close the '(' at column 4"),
    ("x ** ** 2", 6, "expected a number, a name or '(', got '**'"),
    ("", 1, "expected a number, a name or '(', got the end"),
    ("x + $", 5, "unexpected character '$'"),
])
def test_error_messages_name_the_problem_and_column(text, col, msg):
    with pytest.raises(ExpressionError) as e:
        parse_node(text, params={"r": 1.0})
    assert e.value.column == col and msg in e.value.what, str(e.value)


def test_error_format_with_where_and_caret():
    with pytest.raises(ExpressionError) as e:
        parse_node("x + $ 2", where="scene.toml:7")
    lines = str(e.value).splitlines()
    assert lines[0] == "scene.toml:7: column 5: unexpected character '$'"
    assert lines[1] == "  x + $ 2" and lines[2] == "      ^"
    assert isinstance(e.value, ValueError)
    with pytest.raises(ExpressionError, match="expected a string, got int"):
        parse_node(3)
