"""Sphere tracing and Keinert's over-relaxation (progressive-tracing article, 背景: 距離場によるレイマーチング): convergence to
closed forms, fewer steps with ω > 1 where rays run along a surface, the fallback, overshoot with an invalid
λ, rays starting inside, the λ argument."""
from __future__ import annotations

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes.implicit.analytic import analytic_sphere
from ssbench.passes.implicit.common import HIT, MISS, OUT_OF_STEPS, FunctionSurface, camera_rays
from ssbench.passes.implicit.fixed import FixedStepParams, fixed_step
from ssbench.passes.implicit.sphere import SphereTrace, SphereTraceParams, sphere_trace


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def ball(center=(0.0, 0.0, 0.0), radius=1.0, lipschitz=1.0):
    c = torch.tensor(center, dtype=torch.float64)
    return FunctionSurface(lambda p: (p - c.to(p.dtype)).norm(dim=-1) - radius, lipschitz=lipschitz)


def torus_f(p, R=1.0, r=0.3):
    q = torch.stack([torch.sqrt(p[..., 0] ** 2 + p[..., 2] ** 2) - R, p[..., 1]], -1)
    return q.norm(dim=-1) - r


def cam(eye, target=(0, 0, 0), w=48, h=36, far=10.0, fovy=45.0):
    return Camera.from_look_at(eye, target, (0, 1, 0), fovy, w, h, 0.1, far)


def test_converges_to_the_closed_form():
    rays = camera_rays(cam((0.4, 0.5, 4.0)), dtype=torch.float64)
    eps = 1e-4
    truth = analytic_sphere(rays, (0, 0, 0), 1.0)
    res = sphere_trace(ball(), rays, SphereTraceParams(epsilon=eps))
    p = rays.origin + res.t * rays.direction
    dist = (p.norm(dim=1, keepdim=True) - 1.0)
    assert bool((dist[res.hit] >= 0).all()) and bool((dist[res.hit] < eps * res.t[res.hit]).all())
    o, d = rays.origin.permute(0, 2, 3, 1), rays.direction.permute(0, 2, 3, 1)
    perp = (o + (-(o * d).sum(-1, keepdim=True)) * d).norm(dim=-1).unsqueeze(1)     # centre-ray distance
    near_miss = (perp > 1) & (perp - 1 < eps * 5)
    assert torch.equal(res.hit | near_miss, truth.hit | near_miss)    # only ε-grazing rays may differ
    frontal = truth.hit & (perp < 0.9)
    cos = (1 - perp.clamp(max=1) ** 2).sqrt()                           # |cos| of the incidence angle
    assert bool(((res.t - truth.t).abs() <= eps * res.t / cos + 1e-12)[frontal].all())
    assert not bool(res.debug["overshoot"].any()) and (res.termination != OUT_OF_STEPS).all()
    assert torch.allclose(res.normal[:, :, frontal[0, 0]], truth.normal[:, :, frontal[0, 0]], atol=1e-3)


@pytest.mark.parametrize("name", ["ground sphere", "torus ring"])
def test_over_relaxation_takes_fewer_steps_and_stays_correct(name):
    if name == "ground sphere":          # a huge sphere as a floor: rays run along it at grazing angles
        surf, c = ball((0.0, -100.0, 0.0), 100.0), cam((0, 1, 0), (0, 0.6, -4), fovy=60.0, far=40.0)
    else:                                # from inside the ring of a torus: rays run along the tube
        surf, c = FunctionSurface(torus_f, lipschitz=1.0), cam((0, 0.35, 1.0), (0, 0.2, -1), fovy=60.0)
    base = sphere_trace(surf, c, SphereTraceParams(omega=1.0), dtype=torch.float64)
    relaxed = sphere_trace(surf, c, SphereTraceParams(omega=1.4), dtype=torch.float64)
    assert relaxed.steps.double().mean() < 0.95 * base.steps.double().mean()
    assert int(relaxed.debug["fallbacks"].sum()) > 0                   # the fallback was exercised
    assert torch.equal(relaxed.hit, base.hit)
    both = relaxed.hit & base.hit
    assert (relaxed.t - base.t).abs()[both].max().item() < 1e-2
    assert not bool(relaxed.debug["overshoot"].any())
    rays = camera_rays(c, dtype=torch.float64)
    f_hit = surf.f((rays.origin + relaxed.t * rays.direction).permute(0, 2, 3, 1))[relaxed.hit[:, 0]]
    assert bool((f_hit >= 0).all()) and bool((f_hit < 1e-4 * relaxed.t[relaxed.hit]).all())   # outside, within ε


def test_invalid_lipschitz_overshoots_and_bisects_back():
    bumps = lambda p: torus_f(p, 1.0, 0.35) + 0.045 * torch.sin(20 * p[..., 0]) * torch.sin(    # noqa: E731
        20 * p[..., 1]) * torch.sin(20 * p[..., 2])
    surf = FunctionSurface(bumps, lipschitz=1.0)                       # wrong: max |∇f| ≈ 1.9
    c = cam((0, 2, 4))
    rays = camera_rays(c, dtype=torch.float64)
    res = sphere_trace(surf, rays)
    ov = res.debug["overshoot"]
    assert int(ov.sum()) > 10
    assert bool(res.hit[ov].all())
    lo = rays.origin + (res.t - 1e-5) * rays.direction                # the bracket is ≤ 5/2²⁰ wide
    hi = rays.origin + (res.t + 1e-5) * rays.direction
    f = lambda x: surf.f(x.permute(0, 2, 3, 1)).unsqueeze(1)          # noqa: E731
    assert bool((f(lo)[ov] >= 0).all()) and bool((f(hi)[ov] < 0).all())   # a true crossing, not inside
    ok = sphere_trace(surf, rays, SphereTraceParams(lipschitz=2.0))       # a valid bound: no overshoot
    assert not bool(ok.debug["overshoot"].any())
    dense = fixed_step(surf, rays, FixedStepParams(steps=4000))
    agree = ok.hit & dense.hit
    assert torch.equal(ok.hit, dense.hit) or (ok.hit != dense.hit).sum() <= 3
    assert ((ok.t - dense.t).abs()[agree] < 1e-2).float().mean() > 0.99


def test_plain_sphere_tracing_punches_through_where_the_safeguard_bisects_back():
    """safeguard=False is Hart's loop as published: with the invalid λ it steps through the bumps (progressive-tracing article's
    holes), so the first hit is missed or reported far behind on many pixels; with the safeguard none is."""
    bumps = lambda p: torus_f(p, 1.0, 0.35) + 0.045 * torch.sin(20 * p[..., 0]) * torch.sin(    # noqa: E731
        20 * p[..., 1]) * torch.sin(20 * p[..., 2])
    surf = FunctionSurface(bumps, lipschitz=1.0)                       # wrong: max |∇f| ≈ 1.9
    rays = camera_rays(cam((0, 2, 4)), dtype=torch.float64)
    guarded = sphere_trace(surf, rays)
    plain = sphere_trace(surf, rays, SphereTraceParams(safeguard=False))
    dense = fixed_step(surf, rays, FixedStepParams(steps=4000))        # the first crossing, densely sampled
    first = dense.hit
    late = lambda r: first & (~r.hit | (r.t > dense.t + 0.02))         # noqa: E731  missed or far behind
    assert int(late(guarded).sum()) <= 3
    assert int(late(plain).sum()) > 0.1 * int(first.sum())
    assert not bool(plain.debug["overshoot"].any()) and not torch.isnan(plain.t).any()
    valid = FunctionSurface(bumps, lipschitz=2.0)                       # with a valid λ both modes agree
    a, b = sphere_trace(valid, rays), sphere_trace(valid, rays, SphereTraceParams(safeguard=False))
    assert torch.equal(a.hit, b.hit) and torch.allclose(a.t, b.t, atol=1e-6)


def test_lipschitz_argument():
    c = cam((0, 0, 4), w=8, h=6)
    with pytest.raises(ValueError, match="lipschitz"):
        sphere_trace(ball(lipschitz=None), c)
    a = sphere_trace(ball(lipschitz=None), c, SphereTraceParams(lipschitz=1.0), dtype=torch.float64)
    b = sphere_trace(ball(lipschitz=1.0), c, dtype=torch.float64)
    assert torch.equal(a.t, b.t)
    slow = sphere_trace(ball(lipschitz=1.0), c, SphereTraceParams(lipschitz=4.0), dtype=torch.float64)
    assert torch.equal(slow.hit, b.hit) and slow.steps.sum() > b.steps.sum()


def test_eye_inside_exits_without_hit_then_finds_the_next_object():
    inside = ball(radius=5.0)                                          # the eye (distance 4) is inside
    rays = camera_rays(cam((0, 0, 4), w=16, h=12, far=20.0), dtype=torch.float64)
    res = sphere_trace(inside, rays)
    assert not bool(res.hit.any()) and bool((res.termination == MISS).all())
    two = FunctionSurface(lambda p: torch.minimum((p - torch.tensor([0, 0, 4.0], dtype=p.dtype)).norm(dim=-1)
                                                  - 0.5, p.norm(dim=-1) - 1.0), lipschitz=1.0)
    res = sphere_trace(two, rays)
    truth = analytic_sphere(rays, (0, 0, 0), 1.0)
    assert torch.equal(res.hit, truth.hit)                             # the ball around the eye is left
    assert (res.t - truth.t).abs()[truth.hit].max().item() < 0.05
    for x in (res.t, res.normal):
        assert bool(torch.isfinite(x).all())


def test_out_of_steps_is_not_a_hit_and_no_nan():
    c = cam((0, 0, 4), w=16, h=12)
    res = sphere_trace(ball(), c, SphereTraceParams(max_steps=1), dtype=torch.float64)
    oos = res.termination == OUT_OF_STEPS
    assert bool(oos.any()) and not bool(res.hit[oos].any())
    assert torch.equal(res.t[oos], camera_rays(c, dtype=torch.float64).t_far[oos])
    nan = FunctionSurface(lambda p: torch.sqrt(p.norm(dim=-1) - 2.0), lipschitz=1.0)   # NaN near the ball
    for r in (sphere_trace(nan, c), sphere_trace(ball(), c, SphereTraceParams(omega=1.9))):
        assert bool(torch.isfinite(r.t).all()) and bool(torch.isfinite(r.normal).all())


def test_grazing_rays_along_the_tangent_plane():
    c = cam((0, 1, 3.5), (0, 1, 0), w=32, h=24, fovy=6.0)               # the eye in the plane tangent to the top
    rays = camera_rays(c, dtype=torch.float64)
    truth = analytic_sphere(rays, (0, 0, 0), 1.0)
    res = sphere_trace(ball(), rays, SphereTraceParams(max_steps=64))
    assert bool(torch.isfinite(res.t).all()) and bool(torch.isfinite(res.normal).all())
    assert bool(truth.hit.any()) and bool((~truth.hit).any())
    p = rays.origin + res.t * rays.direction
    dist = p.norm(dim=1, keepdim=True) - 1
    assert bool((dist[res.hit].abs() < 1e-4 * res.t[res.hit]).all())    # every hit is on the surface
    oos = res.termination == OUT_OF_STEPS                               # grazing rays may run out of steps ...
    assert not bool(res.hit[oos].any())                                 # ... and then they are not hits
    assert bool(res.hit[truth.hit & (truth.debug["roots"][:, 1:] - truth.t > 0.2)].all())


def test_float32_and_module():
    c = cam((0.3, 0.5, 3.5), w=24, h=18)
    a = sphere_trace(ball(), c, dtype=torch.float64)
    b = sphere_trace(ball(), c, dtype=torch.float32)
    assert (a.hit != b.hit).sum() <= 2
    both = a.hit & b.hit
    assert torch.allclose(a.t[both].float(), b.t[both], rtol=1e-3)
    assert torch.equal(SphereTrace()(ball(), camera_rays(c, dtype=torch.float64)).t, a.t)
    assert (a.termination[a.hit] == HIT).all()


def test_bad_params():
    for kw, name in (({"omega": 2.0}, "omega"), ({"omega": 0.5}, "omega"), ({"max_steps": 0}, "max_steps"),
                     ({"epsilon": 0.0}, "epsilon"), ({"lipschitz": -1.0}, "lipschitz"),
                     ({"safeguard": 1}, "safeguard")):
        with pytest.raises(ValueError, match=name):
            SphereTraceParams(**kw)
