"""Property-based fuzzing of implicit scenes and their certified reference, with hypothesis.

Random expression texts — well-formed trees over ``x y z p`` with every function of the grammar, and malformed
ones (stray characters, unbalanced brackets, unknown names, wrong arity, attribute access) — go through the
scene loader and, when accepted, through :func:`ssbench.reference.implicit.implicit` at 12×9 with exits.
Contract: the loader either accepts or raises ``SceneError`` naming ``file:line`` / the field; the reference
ends within :data:`MAX_ITERATIONS` (torch engine: lock-step iterations; Dr.Jit engine: segments of one ray) — the
budget: a NaN, zero or tangent region is crossed, and such rays are not certified — never raises, never reports a
hit outside the clipped range.
"""
from __future__ import annotations

import math

import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ssbench.implicit.scene import load
from ssbench.reference.implicit import engine_of, implicit
from ssbench.scenes import SceneError

EXAMPLES = 200
MAX_ITERATIONS = {"torch": 1500, "drjit": 8000}
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])

LEAVES = ("x", "y", "z", "length(p)", "1", "0.5", "0", "pi", "1e30", "1e-30", "r")
UNARY = ("abs", "sqrt", "exp", "log", "sin", "cos", "square", "-")
BINARY = ("+", "-", "*", "/", "^")
NARY = ("min", "max", "union", "intersect")


def trees(depth: int = 4):
    return st.recursive(
        st.sampled_from(LEAVES),
        lambda sub: st.one_of(
            st.tuples(st.sampled_from(UNARY), sub).map(lambda t: f"-({t[1]})" if t[0] == "-" else f"{t[0]}({t[1]})"),
            st.tuples(sub, st.sampled_from(BINARY), sub).map(lambda t: f"({t[0]}) {t[1]} ({t[2]})"),
            st.tuples(st.sampled_from(NARY), sub, sub).map(lambda t: f"{t[0]}({t[1]}, {t[2]})"),
            st.tuples(sub, sub).map(lambda t: f"smin({t[0]}, {t[1]}, 0.1)"),
            st.tuples(sub, sub).map(lambda t: f"subtract({t[0]}, {t[1]})"),
            st.tuples(sub, sub, sub).map(lambda t: f"length(vec3({t[0]}, {t[1]}, {t[2]}))"),
        ), max_leaves=12)


MALFORMED = st.one_of(
    st.text(alphabet="xyzp()+-*/^,.0123456789eE _[]{}'\"#;:!@$%&|<>=?\\`~ab", max_size=40),
    trees().map(lambda t: t + ")"), trees().map(lambda t: "(" + t),
    trees().map(lambda t: f"frobnicate({t})"), trees().map(lambda t: f"min({t})"),
    trees().map(lambda t: f"{t}.__class__"), trees().map(lambda t: f"__import__('os')"),
    st.just(""), st.just("x" * 30_000))


@st.composite
def expressions(draw):
    if draw(st.integers(0, 3)) == 0:
        return draw(MALFORMED), False
    return draw(trees()), True


def _scene(f: str) -> dict:
    return {"name": "fuzz", "params": {"r": 0.7},
            "camera": {"eye": [0, 1.5, 4], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 40, "width": 12,
                       "height": 9, "near": 0.1, "far": 10},
            # max(…, length(p) − 1): f > 0 on the bounds whenever the expression is a number there
            "implicit": [{"id": "a", "f": f"max({f}, length(p) - 1)", "bounds": [[-1.3] * 3, [1.3] * 3]}]}


@pytest.mark.slow
def test_expressions_load_cleanly_and_the_reference_ends_within_budget():
    seen = {"refused": 0, "traced": 0, "malformed_accepted": 0}

    @FUZZ
    @given(expressions())
    def prop(case):
        text, well_formed = case
        try:
            sc = load(_scene(text))
        except SceneError as e:
            assert "implicit[0]" in str(e) or "fuzz" in str(e), str(e)
            seen["refused"] += 1
            return
        seen["traced" if well_formed else "malformed_accepted"] += 1
        ref = implicit(sc.surface(0), sc.camera_at(0), exits=True, use_cache=False)
        assert ref.iterations <= MAX_ITERATIONS[engine_of(sc.surface(0))], (text, ref.iterations)
        assert not bool(ref.unfinished.any()), text
        t, hit = ref.t[ref.hit], ref.hit
        assert bool(torch.isfinite(t).all()), text
        assert bool(((ref.t >= ref.t_start - 1e-9) & (ref.t <= ref.t_end + 1e-9))[hit].all()), text
        assert bool(torch.isfinite(ref.normal).all()), text
        assert not math.isnan(ref.seconds)
    prop()
    print(f"fuzz implicit: {seen}")
    assert seen["refused"] > 0 and seen["traced"] > 20, seen
