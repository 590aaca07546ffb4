"""Analytic ray–sphere (progressive-tracing article, 背景): the stable quadratic against a per-pixel Python loop, tangent and
far-away rays, rays starting inside, background, dtype agreement."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes.implicit.analytic import AnalyticSphere, AnalyticSphereParams, analytic_sphere, sphere_roots
from ssbench.passes.implicit.common import HIT, MISS, CameraRays, camera_rays


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    n = torch.get_num_threads()
    torch.set_num_threads(1)          # tiny tensors: intra-op threads only contend on shared cores
    yield
    torch.set_num_threads(n)


def cam(eye=(0.3, 0.4, 4.0), w=12, h=9, far=10.0):
    return Camera.from_look_at(eye, (0, 0, 0), (0, 1, 0), 50.0, w, h, 0.1, far)


def loop_first_root(o, d, c, r, t_min):
    """Per-pixel Python closed form (textbook quadratic in Python floats)."""
    m = [o[i] - c[i] for i in range(3)]
    b = sum(m[i] * d[i] for i in range(3))
    cc = sum(x * x for x in m) - r * r
    disc = b * b - cc
    if disc < 0:
        return None
    for t in (-b - math.sqrt(disc), -b + math.sqrt(disc)):
        if t >= t_min:
            return t
    return None


def rays_of(origins, directions, dtype=torch.float64, far=100.0):
    o = torch.tensor(origins, dtype=dtype).T.reshape(1, 3, 1, -1)
    d = torch.tensor(directions, dtype=dtype).T.reshape(1, 3, 1, -1)
    d = d / d.norm(dim=1, keepdim=True)
    one = torch.ones(1, 1, 1, o.shape[-1], dtype=dtype)
    return CameraRays(origin=o, direction=d, t_near=0.0 * one, t_far=far * one, view_dir=d)


@pytest.mark.parametrize("center,radius", [((0, 0, 0), 1.0), ((0.5, -0.2, 0.3), 0.7), ((0, 0, 1.0), 2.5)])
def test_matches_per_pixel_loop(center, radius):
    c = cam()
    r = camera_rays(c, dtype=torch.float64)
    res = analytic_sphere(r, center, radius)
    for y in range(c.height):
        for x in range(c.width):
            o, d = r.origin[0, :, y, x].tolist(), r.direction[0, :, y, x].tolist()
            t = loop_first_root(o, d, center, radius, r.t_near[0, 0, y, x].item())
            assert bool(res.hit[0, 0, y, x]) == (t is not None), (x, y)
            if t is not None:
                assert res.t[0, 0, y, x].item() == pytest.approx(t, rel=1e-12, abs=1e-12)
                p = torch.tensor(o, dtype=torch.float64) + t * torch.tensor(d, dtype=torch.float64)
                n = (p - torch.tensor(center, dtype=torch.float64)) / radius
                assert torch.allclose(res.normal[0, :, y, x], n, atol=1e-10)
                assert res.termination[0, 0, y, x] == HIT and res.object_index[0, 0, y, x] == 0
            else:
                assert res.t[0, 0, y, x] == r.t_far[0, 0, y, x] and res.object_index[0, 0, y, x] == -1
                assert res.termination[0, 0, y, x] == MISS and (res.normal[0, :, y, x] == 0).all()
    assert (res.evaluations == 0).all() and (res.steps == 0).all()


def test_tangent_ray_is_a_double_root_hit():
    r = rays_of([(1.0, 0.0, 5.0), (1.0 + 1e-9, 0.0, 5.0)], [(0, 0, -1), (0, 0, -1)])
    res = analytic_sphere(r, (0, 0, 0), 1.0)
    assert res.hit[0, 0, 0].tolist() == [True, False]
    assert res.t[0, 0, 0, 0].item() == pytest.approx(5.0, rel=4e-16)
    t0, t1 = res.debug["roots"][0, :, 0, 0].tolist()
    assert t0 == pytest.approx(5.0, rel=4e-16) and t1 == pytest.approx(5.0, rel=4e-16)


def test_stable_far_away_sphere_float32():
    # naive b² − c cancels in float32 (1e8 − (1e8 − 1) = 0 → a false tangent); the stable form keeps t = 9999
    r = rays_of([(0.0, 0.0, 1e4)], [(0, 0, -1)], dtype=torch.float32, far=2e4)
    res = analytic_sphere(r, (0, 0, 0), 1.0)
    assert res.t.item() == 9999.0
    assert res.debug["roots"][0, :, 0, 0].tolist() == [9999.0, 10001.0]
    t0, t1, ok = sphere_roots(torch.tensor([0.0, 0.0, 1e4]), torch.tensor([0.0, 0.0, -1.0]), torch.zeros(3), 1.0)
    assert (t0.item(), t1.item(), ok.item()) == (9999.0, 10001.0, True)


def test_ray_starting_inside_takes_the_exit_root_and_near_clipping():
    r = rays_of([(0.0, 0.0, 0.5), (0.0, 0.0, 3.0)], [(0, 0, -1), (0, 0, -1)])
    res = analytic_sphere(r, (0, 0, 0), 1.0)
    assert res.t[0, 0, 0].tolist() == [1.5, 2.0]
    near = CameraRays(r.origin, r.direction, r.t_near + 2.5, r.t_far, r.view_dir)
    res = analytic_sphere(near, (0, 0, 0), 1.0)       # roots (−0.5, 1.5) both < t_near; (2, 4) → exit root 4
    assert res.hit[0, 0, 0].tolist() == [False, True]
    assert res.t[0, 0, 0].tolist() == [100.0, 4.0]
    res = analytic_sphere(near, (0, 0, 0), 1.0, AnalyticSphereParams(use_near=False))
    assert res.t[0, 0, 0].tolist() == [1.5, 2.0]


def test_float32_matches_float64_and_module():
    c = cam(w=32, h=24)
    a = analytic_sphere(c, (0, 0, 0), 1.0, dtype=torch.float64)
    b = analytic_sphere(c, (0, 0, 0), 1.0, dtype=torch.float32)
    assert torch.equal(a.hit, b.hit)
    assert torch.allclose(a.t.float(), b.t, rtol=1e-5)
    m = AnalyticSphere((0, 0, 0), 1.0)(camera_rays(c, dtype=torch.float64))
    assert torch.equal(m.t, a.t)
    for x in (a.t, a.normal, b.t, b.normal):
        assert bool(torch.isfinite(x).all())


def test_bad_input():
    c = cam()
    with pytest.raises(ValueError, match="radius"):
        analytic_sphere(c, (0, 0, 0), 0.0)
    with pytest.raises(ValueError, match="center"):
        analytic_sphere(c, (0, 0), 1.0)
    with pytest.raises(TypeError, match="camera"):
        analytic_sphere("cam", (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="use_near"):
        AnalyticSphereParams(use_near=1)
