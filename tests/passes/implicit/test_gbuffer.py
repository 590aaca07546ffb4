"""Implicit hits as a GBuffer: background FILL values exactly, view-space geometry, materials, Lambert colour,
AO/SSR passes running on it, supersampling (progressive-tracing article, 補足: アンチエイリアシング)."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes.implicit.analytic import analytic_sphere
from ssbench.passes.implicit.common import FunctionSurface, camera_rays
from ssbench.passes.implicit.fixed import FixedStepParams, fixed_step
from ssbench.passes.implicit.gbuffer import DEFAULT_MATERIAL, supersample, to_gbuffer

CAM = Camera.from_look_at((0.3, 0.6, 4), (0, 0, 0), (0, 1, 0), 45.0, 32, 24, 0.1, 10.0)


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def two_balls():
    a, b = torch.tensor([-0.7, 0.0, 0.0]), torch.tensor([0.8, 0.1, -0.5])
    fa = lambda p: (p - a.to(p.dtype)).norm(dim=-1) - 0.6               # noqa: E731
    fb = lambda p: (p - b.to(p.dtype)).norm(dim=-1) - 0.7               # noqa: E731
    return FunctionSurface(lambda p: torch.minimum(fa(p), fb(p)), lipschitz=1.0, parts=(fa, fb))


def test_background_holds_the_fill_values_and_hits_are_view_space():
    rays = camera_rays(CAM, dtype=torch.float64)
    res = analytic_sphere(rays, (0, 0, 0), 1.0)
    g = to_gbuffer(res, rays, CAM)
    bg = ~g.mask
    assert bool(bg.any()) and torch.equal(g.mask, res.hit)
    assert bool((g.view_z[bg] == -CAM.far).all())
    far_pos = CAM.uv_to_view(CAM.uv_grid(torch.float64), torch.full((1, 24, 32), -CAM.far, dtype=torch.float64),
                             dim=0).unsqueeze(0)
    assert torch.equal(g.position[bg.expand(-1, 3, -1, -1)], far_pos.expand(1, 3, 24, 32)[bg.expand(-1, 3, -1, -1)])
    for name, value in (("normal", 0.0), ("albedo", 0.0), ("roughness", 1.0), ("metallic", 0.0), ("color", 0.0)):
        t = getattr(g, name)
        assert bool((t[bg.expand_as(t)] == value).all()), name
    assert bool((g.shape_id[bg] == -1).all()) and g.shape_id.dtype == torch.int32
    world = rays.origin + res.t * rays.direction
    view = CAM.world_to_view(world)
    h3 = g.mask.expand(-1, 3, -1, -1)
    assert torch.allclose(g.position[h3], view[h3], atol=1e-12)
    assert torch.allclose(g.view_z[g.mask], view[:, 2:3][g.mask], atol=1e-12)
    n = g.normal
    assert torch.allclose(n.norm(dim=1)[g.mask[:, 0]], torch.ones(1, dtype=torch.float64))
    assert bool(((n * g.position).sum(1, keepdim=True) <= 0)[g.mask].all())          # facing the camera
    assert torch.allclose(n[h3], CAM.world_to_view_dir(res.normal)[h3], atol=1e-12)


def test_materials_and_lambert_colour():
    rays = camera_rays(CAM, dtype=torch.float64)
    res = fixed_step(two_balls(), rays, FixedStepParams(steps=200))
    mats = [{"albedo": (0.9, 0.1, 0.1), "roughness": 0.2, "metallic": 1.0},
            {"albedo": 0.5, "roughness": 0.7, "metallic": 0.0}]
    lights = [{"type": "directional", "direction": (0.0, -1.0, -1.0), "irradiance": math.pi}]
    g = to_gbuffer(res, rays, CAM, mats, lights, ambient=0.0)
    for k, m in enumerate(mats):
        sel = g.shape_id == k
        assert bool(sel.any())
        alb = torch.tensor(m["albedo"] if isinstance(m["albedo"], tuple) else (m["albedo"],) * 3,
                           dtype=torch.float64)
        assert torch.allclose(g.albedo.permute(0, 2, 3, 1)[sel[:, 0]], alb.expand(int(sel.sum()), 3))
        assert bool((g.roughness[sel] == m["roughness"]).all()) and bool((g.metallic[sel] == m["metallic"]).all())
    l = -torch.tensor([0.0, -1.0, -1.0], dtype=torch.float64) / math.sqrt(2)
    cos = (res.normal * l.view(1, 3, 1, 1)).sum(1, keepdim=True).clamp_min(0)     # outward normals face the eye
    expect = g.albedo * cos                                          # albedo/π · π · cos
    assert torch.allclose(g.color[g.mask.expand(-1, 3, -1, -1)], expect[g.mask.expand(-1, 3, -1, -1)], atol=1e-9)
    pt = [{"type": "point", "position": (0.0, 3.0, 3.0), "intensity": (2.0, 2.0, 2.0)},
          {"type": "environment", "radiance": 0.25}]
    g2 = to_gbuffer(res, rays, CAM, mats, pt, ambient=0.0)
    p = rays.origin + res.t * rays.direction
    v = torch.tensor([0.0, 3.0, 3.0], dtype=torch.float64).view(1, 3, 1, 1) - p
    r2 = (v * v).sum(1, keepdim=True)
    e = 2.0 * (res.normal * v).sum(1, keepdim=True).clamp_min(0) / r2.sqrt() / r2
    expect = g2.albedo / math.pi * e + 0.25 * g2.albedo
    h3 = g2.mask.expand(-1, 3, -1, -1)
    assert torch.allclose(g2.color[h3], expect[h3], atol=1e-9)
    assert bool((g2.color[~h3] == 0.25).all())                       # FILL: the environment radiance
    with pytest.raises(ValueError, match="materials"):
        to_gbuffer(res, rays, CAM, mats[:1])
    with pytest.raises(ValueError, match="lights"):
        to_gbuffer(res, rays, CAM, mats, [{"type": "spot"}])


def test_defaults_zero_gradient_and_headlight():
    rays = camera_rays(CAM, dtype=torch.float32)
    step = FunctionSurface(lambda p: torch.where(p.norm(dim=-1) < 1, -1.0, 1.0).to(p.dtype))   # ∇f = 0
    res = fixed_step(step, rays, FixedStepParams(steps=64))
    assert bool(res.hit.any()) and bool((res.normal == 0).all())
    g = to_gbuffer(res, rays, CAM)
    assert torch.allclose(g.normal.norm(dim=1)[g.mask[:, 0]], torch.ones(1))          # −view_dir stand-in
    assert torch.allclose(g.albedo[:, 0][g.mask[:, 0]], torch.full((1,), DEFAULT_MATERIAL[0][0]))
    for name in g.channels:
        t = getattr(g, name)
        assert not t.is_floating_point() or bool(torch.isfinite(t).all()), name
    assert g.view_z.dtype == torch.float32


def test_ao_and_ssr_passes_run_on_an_implicit_scene():
    from ssbench.passes.ao.hbao import hbao
    from ssbench.passes.ssr.linear import LinearSSRParams, ssr_linear
    floor = FunctionSurface(lambda p: torch.minimum(p[..., 1] + 0.7, p.norm(dim=-1) - 1.0), lipschitz=1.0)
    res = fixed_step(floor, CAM, FixedStepParams(steps=256), dtype=torch.float32)
    g = to_gbuffer(res, None, CAM)
    ao = hbao(g).ao
    assert ao.shape == (1, 1, 24, 32) and bool(torch.isfinite(ao).all())
    assert ao[g.mask].min().item() < 0.9                             # the crease where the ball meets the floor
    s = ssr_linear(g, LinearSSRParams(position_from="view_z"))
    assert bool(torch.isfinite(s.color).all())


def test_supersample_averages_the_high_resolution_samples():
    cast = lambda c: analytic_sphere(c, (0, 0, 0), 1.0, dtype=torch.float64)     # noqa: E731
    color, cov, hi = supersample(cast, CAM, 3)
    assert color.shape == (1, 3, 24, 32) and cov.shape == (1, 1, 24, 32) and hi.width == 96
    assert bool(((cov >= 0) & (cov <= 1)).all()) and bool(((cov > 0) & (cov < 1)).any())
    assert torch.allclose(color[0, :, 5, 7], hi.color[0, :, 15:18, 21:24].mean((1, 2)))
    c1, cov1, g1 = supersample(cast, CAM, 1)
    assert torch.equal(cov1, g1.mask.double()) and torch.equal(c1, g1.color)
    area = cov.sum().item()                                          # projected disc area ≈ sub-sample count
    fine = supersample(cast, CAM, 8)[1].sum().item()
    assert abs(area - fine) < 0.02 * fine
    with pytest.raises(ValueError, match="factor"):
        supersample(cast, CAM, 0)


def test_catalog_scene_materials_and_lights():
    scene_mod = pytest.importorskip("ssbench.implicit.scene")
    try:
        scene = scene_mod.load("torus")
    except Exception as e:
        pytest.skip(f"torus scene unavailable: {e}")
    cam = scene.camera_at(0).with_resolution(32, 24)
    res = fixed_step(scene.surface(0), cam, FixedStepParams(steps=128), dtype=torch.float64)
    g = to_gbuffer(res, None, cam, scene.materials, scene.lights)
    alb = torch.tensor(scene.materials[0].albedo, dtype=torch.float64)
    assert bool(res.hit.any())
    assert torch.allclose(g.albedo.permute(0, 2, 3, 1)[g.mask[:, 0]], alb.expand(int(g.mask.sum()), 3))
    assert bool(torch.isfinite(g.color).all()) and g.color[g.mask.expand(-1, 3, -1, -1)].max() > 0


def test_bad_input():
    res = analytic_sphere(CAM, (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="camera"):
        to_gbuffer(res, None, CAM.with_resolution(8, 6))
    with pytest.raises(TypeError, match="result"):
        to_gbuffer("r", None, CAM)
