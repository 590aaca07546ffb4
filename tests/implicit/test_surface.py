"""ImplicitObject / ImplicitSurface: transforms against closed forms, the union, gradients, sound intervals."""
import math

import pytest
import torch

from ssbench.implicit.expression import parse
from ssbench.implicit.surface import ImplicitObject
from ssbench.implicit.union import ImplicitSurface
from ssbench.scenes.model import Material
from ssbench.scenes.transforms import rotate4

F64 = torch.float64


def obj(text, oid="o", **kw):
    kw.setdefault("bounds", ((-1.5, -1.5, -1.5), (1.5, 1.5, 1.5)))
    return ImplicitObject(oid, parse(text), **kw)


def field_only(text, oid="o", **kw):
    """An object whose field is unbounded (``x``, ``sqrt(x) - 1``): for field algebra, never traced."""
    return obj(text, oid, verify_bounds=False, **kw)


def rot(euler):
    return torch.tensor(rotate4(euler), dtype=F64)[:3, :3]


def test_untransformed_object_is_its_expression_exactly():
    p = torch.randn(100, 3, dtype=F64) * 2
    o = obj("length(p) - 1")
    assert torch.equal(o.f(p), o.expression(p)) and torch.allclose(o.f(p), p.norm(dim=-1) - 1, atol=1e-15)


def test_translated_rotated_scaled_sphere_equals_closed_form():
    o = obj("length(p) - 1", translate=(1, 2, -3), rotate=(30, 45, 60), scale=0.5, lipschitz=1.0)
    p = torch.randn(1000, 3, dtype=F64) * 2 + torch.tensor([1, 2, -3], dtype=F64)
    want = (p - torch.tensor([1, 2, -3], dtype=F64)).norm(dim=-1) - 0.5
    assert torch.allclose(o.f(p), want, atol=1e-12)
    assert o.lipschitz == 1.0                  # uniform scale keeps the bound


def test_world_field_is_scaled_local_field_at_the_inverse_point():
    """f_world(T + s·R·q) = s·f_local(q) with R from the scene transforms (Rz·Ry·Rx, degrees)."""
    text = "max(abs(x) - 0.3, abs(y) - 0.6, abs(z) - 0.9) + 0.1*x*y"
    local, world = obj(text), obj(text, translate=(0.5, -1, 2), rotate=(10, -70, 125), scale=2.5)
    q = torch.rand(2000, 3, dtype=F64) * 3 - 1.5
    p = torch.tensor([0.5, -1, 2], dtype=F64) + 2.5 * q @ rot((10, -70, 125)).T
    assert torch.allclose(world.f(p), 2.5 * local.f(q), atol=1e-12)
    assert torch.allclose(world.to_local(p), q, atol=1e-12)


def test_rotation_convention_matches_scene_transforms():
    # Ry(90°) takes local +z to world +x: a small ball at local (0, 0, 1) sits at world (1, 0, 0).
    o = obj("length(p - vec3(0, 0, 1)) - 0.1", rotate=(0, 90, 0))
    assert o.f(torch.tensor([[1.0, 0, 0]], dtype=F64)).item() == pytest.approx(-0.1, abs=1e-12)


def test_world_bounds_are_the_transformed_box():
    o = obj("length(p) - 1", bounds=((-1.1, -2, -3), (1.1, 2, 3)), translate=(10, 0, 0), rotate=(0, 0, 90),
            scale=2)
    lo, hi = o.world_bounds                    # z-rotation by 90°: x extent <- y extent
    assert lo == pytest.approx((6, -2.2, -6)) and hi == pytest.approx((14, 2.2, 6))
    assert all(a <= b for a, b in zip(lo, (6, -2.2, -6))) and all(a >= b for a, b in zip(hi, (14, 2.2, 6)))


def test_union_object_index_bounds_lipschitz_translated():
    a = obj("length(p) - 1", "a", translate=(-2, 0, 0), lipschitz=1.0)
    b = obj("length(p) - 0.5", "b", translate=(2, 0, 0), lipschitz=2.0)
    s = ImplicitSurface((a, b))
    p = torch.tensor([[-2.0, 0, 0], [2.2, 0, 0], [0.1, 0, 0]], dtype=F64)
    assert s.f(p).tolist() == pytest.approx([-1.0, -0.3, 1.1])
    assert s.object_index(p).tolist() == [0, 1, 0] and s.object_index(p).dtype == torch.long
    (lo, hi), want_lo, want_hi = s.bounds, (-3.5, -1.5, -1.5), (3.5, 1.5, 1.5)
    assert lo == pytest.approx(want_lo, abs=1e-12) and hi == pytest.approx(want_hi, abs=1e-12)
    assert all(a <= b for a, b in zip(lo, want_lo)) and all(a >= b for a, b in zip(hi, want_hi))
    assert s.lipschitz == 2.0
    assert ImplicitSurface((a, field_only("x", "c"))).lipschitz is None
    moved = s.translated("b", (0, 1, 0))
    assert moved.objects[1].translate == (2, 1, 0) and s.objects[1].translate == (2, 0, 0)
    assert moved.f(torch.tensor([[2.0, 1, 0]], dtype=F64)).item() == pytest.approx(-0.5)
    with pytest.raises(KeyError, match="obj_id"):
        s.translated("zz", (0, 0, 0))
    assert s.ids == ("a", "b") and s.index("b") == 1
    assert moved.cache_key() != s.cache_key() == ImplicitSurface((a, b)).cache_key()
    shiny = ImplicitSurface((a, ImplicitObject("b", b.expression, b.bounds, Material(roughness=0.1),
                                                lipschitz=2.0, translate=(2, 0, 0))))
    assert shiny.cache_key() == s.cache_key()                  # the geometry key ignores materials


def test_f_and_grad_under_no_grad_keeps_no_graph():
    s = ImplicitSurface((obj("length(p) - 1", translate=(0.5, 0, 0), scale=2.0),))
    p = torch.randn(50, 3, dtype=F64)
    with torch.no_grad():
        v, g = s.f_and_grad(p)
    d = p - torch.tensor([0.5, 0, 0], dtype=F64)
    assert torch.allclose(v, d.norm(dim=-1) - 2) and torch.allclose(g, d / d.norm(dim=-1, keepdim=True))
    assert not v.requires_grad and not g.requires_grad and not p.requires_grad
    v, g = ImplicitSurface((obj("2"),)).f_and_grad(p)          # constant: zero gradient, no error
    assert torch.equal(g, torch.zeros_like(p))


def _random_boxes(n, lo, hi, gen):
    a = torch.rand(n, 3, dtype=F64, generator=gen) * (hi - lo) + lo
    w = torch.rand(n, 3, dtype=F64, generator=gen) ** 3 * (hi - lo)
    return a, a + w


def test_interval_encloses_points_of_transformed_objects():
    gen = torch.Generator().manual_seed(1)
    s = ImplicitSurface((field_only("x^2 - y*z + sin(3*x) - 0.5", "a", translate=(0.3, -0.2, 1), rotate=(20, 50, -80),
                             scale=1.7),
                         obj("abs(length(p) - 1) - 0.01", "b", rotate=(0, 90, 0), scale=0.5)))
    lo, hi = _random_boxes(4000, -3.0, 3.0, gen)
    flo, fhi = s.interval(lo, hi)
    assert flo.dtype == F64 and flo.shape == (4000,)
    u = torch.rand(4000, 32, 3, dtype=F64, generator=gen)
    pts = lo[:, None] + u * (hi - lo)[:, None]
    v = s.f(pts)
    known = ~(flo.isnan() | fhi.isnan())
    assert known.float().mean() > 0.99
    assert bool(((flo[:, None] <= v) & (v <= fhi[:, None]))[known].all())
    # a degenerate box [p, p] encloses f(p) itself
    p = lo[:100]
    a, b = s.interval(p, p)
    assert bool(((a <= s.f(p)) & (s.f(p) <= b)).all())


def test_interval_nan_means_unknown_and_propagates_through_the_union():
    s = ImplicitSurface((obj("length(p) - 1", "a"), field_only("sqrt(x) - 1", "b")))
    lo = torch.tensor([[-1.0, 0, 0], [0.5, 0, 0]], dtype=F64)
    hi = torch.tensor([[-0.5, 1, 1], [1.0, 1, 1]], dtype=F64)
    flo, fhi = s.interval(lo, hi)
    assert flo[0].isnan() and fhi[0].isnan() and not flo[1].isnan()
    nan_box = torch.full((1, 3), math.nan, dtype=F64)
    assert s.interval(nan_box, nan_box)[0].isnan().all()


@pytest.mark.parametrize("kw, match", [
    (dict(bounds=((0, 0, 0), (1, 0, 1))), "bounds"),
    (dict(scale=-1.0), "scale"), (dict(scale=0.0), "scale"),
    (dict(lipschitz=0.0), "lipschitz"), (dict(translate=(0, math.nan, 0)), "translate")])
def test_invalid_objects_are_refused(kw, match):
    with pytest.raises(ValueError, match=match):
        obj("length(p) - 1", **kw)


def test_surface_needs_unique_objects():
    with pytest.raises(ValueError, match="objects"):
        ImplicitSurface(())
    with pytest.raises(ValueError, match="duplicate"):
        ImplicitSurface((field_only("x", "a"), field_only("y", "a")))


@pytest.mark.mitsuba
def test_drjit_f_equals_torch_f():
    from ssbench.reference import backend
    backend.mitsuba()
    import drjit as dr
    Float = dr.llvm.Float64 if backend.is_jit() else None
    if Float is None:
        pytest.skip("scalar Mitsuba variant: no vectorised Dr.Jit arrays")
    s = ImplicitSurface((obj("length(p) - 1", "a", translate=(0.3, -0.2, 1), rotate=(20, 50, -80), scale=1.7),
                         obj("max(abs(x), abs(y), abs(z)) - 0.5 + 0.1*sin(5*x)", "b", rotate=(0, 0, 33))))
    p = torch.randn(500, 3, dtype=F64) * 2
    got = s.drjit_f(*(Float(p[:, i].tolist()) for i in range(3)))
    assert torch.allclose(torch.tensor(list(got), dtype=F64), s.f(p), atol=1e-12)
