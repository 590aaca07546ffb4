"""HBAO (SSAO article §3): synthetic analytic G-buffers (ray/plane intersections, no Mitsuba) plus one slow
reference-G-buffer smoke test."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench import checks
from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes import ao_method
from ssbench.passes.ao.hbao import HBAO, REQUIRES, HBAOParams, hbao
from ssbench.passes.teaching.hbao_basic import hbao_basic


# ----------------------------------------------------------------------------- analytic scenes
def raycast_planes(cam: Camera, planes, dtype=torch.float64) -> GBuffer:
    """First hit of each pixel-centre ray with world-space planes ``(point, normal, keep(world_xyz) -> bool)``.

    Hits outside ``[near, far]`` or rejected by ``keep`` are misses; background gets ``view_z = −far``.
    """
    ray = cam.pixel_rays(torch.float64)                                   # (3, H, W), view z = −1
    best = torch.full(ray.shape[1:], math.inf, dtype=torch.float64)
    for point, normal, keep in planes:
        p = cam.world_to_view(torch.tensor(point, dtype=torch.float64), dim=-1)
        n = cam.world_to_view_dir(torch.tensor(normal, dtype=torch.float64), dim=-1)
        denom = (ray * n.view(3, 1, 1)).sum(0)
        t = (p @ n) / denom                                               # hit = t·ray, view z = −t
        t = torch.where(torch.isfinite(t) & (t >= cam.near) & (t <= cam.far), t, math.inf)
        if keep is not None:
            world = cam.view_to_world(ray * torch.where(torch.isfinite(t), t, 0.0))
            t = torch.where(keep(world), t, math.inf)
        best = torch.minimum(best, t)
    mask = torch.isfinite(best)
    view_z = torch.where(mask, -best, torch.tensor(-cam.far, dtype=torch.float64))
    return GBuffer(cam, view_z=view_z[None, None].to(dtype), mask=mask[None, None])


def cam_(eye, target, w=32, h=24, near=0.1, far=100.0, fovy=45.0) -> Camera:
    return Camera.from_look_at(eye, target, (0, 1, 0), fovy, w, h, near, far)


def floor_plane(keep=None):
    return ((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), keep)


def crease(w=48, h=36, scale=1.0, dtype=torch.float64, near=0.1, far=100.0) -> GBuffer:
    """Floor ``y = 0`` meeting a wall ``z = −1`` (a concave right angle along the x axis)."""
    cam = cam_((0, 1.2 * scale, 2.5 * scale), (0, 0.3 * scale, -1 * scale), w, h, near * scale, far * scale)
    return raycast_planes(cam, [floor_plane(), ((0.0, 0.0, -1.0 * scale), (0.0, 0.0, 1.0), None)], dtype)


def faceted(w=48, h=36, slope_deg=10.0, period=0.5) -> GBuffer:
    """A corrugated floor of flat facets alternating ``±slope_deg`` (low-tessellation look, article Figs. 16-17)."""
    cam = cam_((0, 2, 1), (0, 0, -0.3), w, h)
    s, planes = math.tan(math.radians(slope_deg)), []
    for k in range(-12, 12):
        x0, sign = k * period, (1 if k % 2 == 0 else -1)
        y0 = 0.0 if sign > 0 else s * period                             # facet k spans [x0, x0 + period]
        n = (-sign * s, 1.0, 0.0)
        planes.append(((x0, y0, 0.0), n, lambda p, a=x0: (p[0] >= a) & (p[0] <= a + period)))
    return raycast_planes(cam, planes)


def inside(g: GBuffer, radius_pixels: torch.Tensor) -> torch.Tensor:
    """``(H, W)`` geometry pixels whose ray footprint stays inside the image.

    Rays that leave the image read CLAMP_TO_EDGE depth: a fake wall at the edge pixel's depth, which darkens
    pixels within ``radius_pixels`` of an edge where the surface recedes (an open floor drops to ~0.9 at its
    top edge for R = 3 seen from (1, 2, 2)). That is the shader's behaviour; tests of "no false occlusion"
    look at the other pixels.
    """
    H, W = g.height, g.width
    rows, cols = torch.arange(H).view(H, 1) + 0.5, torch.arange(W).view(1, W) + 0.5
    border = torch.minimum(torch.minimum(rows, H - rows), torch.minimum(cols, W - cols))   # px to the edge
    return g.mask[0, 0] & (border > radius_pixels[0, 0] + 1)


def ao_of(g, **kw):
    return hbao(g, HBAOParams(**kw)).ao


# ----------------------------------------------------------------------------- basic behaviour
def test_shape_range_and_registry():
    g = crease(24, 18)
    r = hbao(g, HBAOParams(radius=0.5), debug=True)
    assert r.ao.shape == (1, 1, 18, 24) and r.ao.dtype == torch.float64
    assert bool(((r.ao >= 0) & (r.ao <= 1)).all())
    assert r.debug["horizons"].shape == (1, 6, 18, 24)
    for k in ("num_steps", "samples", "radius_pixels"):
        assert r.debug[k].shape == (1, 1, 18, 24)
    assert ao_method("hbao") == (hbao, HBAOParams, REQUIRES) and REQUIRES == ("view_z", "mask")


@pytest.mark.parametrize("eye", [(0, 1.5, 3), (0, 1, 4), (1, 2, 2), (-2, 1, 1)])
def test_open_plane_is_unoccluded(eye):
    """The tangent bias removes planar self-occlusion (wherever the footprint stays inside the image).

    Not exactly: ``snapUVOffset(randstep·dUv)`` starts the march off the image direction of ``T``, and on a
    floor seen at a steep view slope that leaves up to ~1-1.6 % residual occlusion on a few pixels.
    """
    g = raycast_planes(cam_(eye, (0, 0, 0)), [floor_plane()])
    for radius in (0.3, 0.6):
        for pf in ("depth", "view_z"):
            r = hbao(g, HBAOParams(radius=radius, position_from=pf), debug=True)
            keep = inside(g, r.debug["radius_pixels"])
            assert int(keep.sum()) > 30
            assert float(r.ao[0, 0][keep].min()) >= 0.99, (radius, pf)
            assert float(r.ao[g.mask].mean()) >= 0.995 and float(r.ao.min()) >= 0.9
            assert float(r.debug["samples"].max()) >= 2                  # the march really ran


def test_background_and_edges_no_nan():
    keep = lambda p: (p[0].abs() < 1) & (p[2].abs() < 1)                # a 2×2 square floating in the void
    g = raycast_planes(cam_((0, 1.5, 3), (0, 0, 0)), [floor_plane(keep)])
    assert 0 < int(g.mask.sum()) < g.mask.numel()
    ao = ao_of(g, radius=1.0)
    assert not bool(torch.isnan(ao).any())
    assert bool((ao[~g.mask] == 1).all())
    assert bool(((ao >= 0) & (ao <= 1)).all())


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_grazing_and_near_plane_no_nan(dtype):
    grazing = raycast_planes(cam_((0, 0.02, 3), (0, 0, -20), near=0.01), [floor_plane()], dtype)
    close = raycast_planes(cam_((0, 0.05, 0), (0, -1, -0.3), near=0.04), [floor_plane()], dtype)
    assert float(-close.view_z[close.mask].max()) < 1.2 * 0.04           # pixels right at the near plane
    for g in (grazing, close):
        for pf in ("depth", "view_z"):
            r = hbao(g, HBAOParams(radius=0.5, position_from=pf), debug=True)
            assert not bool(torch.isnan(r.ao).any()) and bool(((r.ao >= 0) & (r.ao <= 1)).all())
            assert not bool(torch.isnan(r.debug["horizons"]).any())
    r = hbao(close, HBAOParams(radius=0.5, max_radius_pixels=10.0), debug=True)
    assert float(r.debug["radius_pixels"].max()) > 10                   # MaxRadiusPixels clamp + dithering hit
    assert float(r.debug["num_steps"][close.mask].min()) >= 1


def test_crease_darkens_near_corner():
    g, R = crease(), 0.5
    world = g.camera.view_to_world(g.camera.pixel_rays(torch.float64) * -g.view_z[0].double())
    dist = torch.hypot(world[1], world[2] + 1.0)                           # distance to the corner line
    r = hbao(g, HBAOParams(radius=R), debug=True)
    ao = r.ao[0, 0]
    band = [ao[g.mask[0, 0] & (dist >= lo * R) & (dist < hi * R)] for lo, hi in ((0, 0.1), (0.1, 0.5), (0.5, 1))]
    assert all(b.numel() >= 10 for b in band)
    assert float(band[0].mean()) < 0.95                                    # the corner row is darkest
    assert float(band[0].mean()) < float(band[1].mean()) < float(band[2].mean())
    far_away = inside(g, r.debug["radius_pixels"]) & (dist > 1.5 * R)
    # out of the wall's reach only the planar snapping residue is left (see test_open_plane_is_unoccluded)
    assert int(far_away.sum()) > 10 and float(ao[far_away].min()) >= 0.98


def test_tan_angle_bias_removes_facet_occlusion():
    g = faceted()
    for radius in (0.3, 0.5):
        biased = hbao(g, HBAOParams(radius=radius), debug=True)
        unbiased = hbao(g, HBAOParams(radius=radius, tan_angle_bias=0.0)).ao[0, 0]
        keep = inside(g, biased.debug["radius_pixels"])
        assert int(keep.sum()) > 100
        assert float(unbiased[keep].min()) < 0.9                         # false occlusion at the shallow folds
        assert float(biased.ao[0, 0][keep].min()) >= 0.99                # bias tan 30° > the 20° fold: gone
        assert bool((biased.ao[0, 0] >= unbiased - 1e-12).all())         # here the bias only removes occlusion


# ----------------------------------------------------------------------------- determinism and precision
def test_seed_determinism():
    g = crease(24, 18)
    a, b = ao_of(g, radius=0.5, seed=3), ao_of(g, radius=0.5, seed=3)
    assert torch.equal(a, b)
    gen = torch.Generator().manual_seed(3)
    assert torch.equal(a, hbao(g, HBAOParams(radius=0.5), generator=gen).ao)
    assert not torch.equal(a, ao_of(g, radius=0.5, seed=4))


def test_float32_matches_float64():
    keep = lambda p: (p[0].abs() < 1) & (p[2].abs() < 1)
    square = raycast_planes(cam_((0, 1.5, 3), (0, 0, 0), 48, 36), [floor_plane(keep)])    # depth edges
    for g64 in (crease(48, 36), square):
        g32 = g64.to(dtype=torch.float32)
        for pf in ("depth", "view_z"):
            a64, a32 = ao_of(g64, radius=0.5, position_from=pf), ao_of(g32, radius=0.5, position_from=pf)
            # no pixel needed masking: sample uvs sit on texel centres (uv0 + k/W), so snapping and the nearest
            # fetch never flip between precisions here, not even next to the square's depth discontinuities
            assert float((a64 - a32.double()).abs().max()) <= 1e-3, pf


def test_batch_equals_single():
    a = crease(24, 18)
    b = raycast_planes(a.camera, [floor_plane()])
    ab = hbao(GBuffer.cat([a, b]), HBAOParams(radius=0.5)).ao
    assert torch.equal(ab[:1], ao_of(a, radius=0.5)) and torch.equal(ab[1:], ao_of(b, radius=0.5))


def test_scale_invariance():
    k = 1000.0
    for pf in ("depth", "view_z"):
        a = ao_of(crease(32, 24), radius=0.5, position_from=pf)
        b = ao_of(crease(32, 24, scale=k), radius=0.5 * k, position_from=pf)
        assert float((a - b).abs().max()) <= 1e-4, pf


def test_module_equals_function():
    g, p = crease(24, 18), HBAOParams(radius=0.5, seed=1)
    assert torch.equal(HBAO(p)(g).ao, hbao(g, p).ao)


@pytest.mark.parametrize("pf", ["depth", "view_z"])
def test_teaching_twin_equals_vectorised(pf):
    g = crease(16, 12)
    for p in (HBAOParams(radius=0.8, position_from=pf, seed=5),
              HBAOParams(radius=2.0, max_radius_pixels=3.0, num_directions=5, num_steps=4, position_from=pf)):
        fast, slow = hbao(g, p).ao, hbao_basic(g, p).ao
        assert float(fast.min()) < 0.95                                   # something to compare
        assert float((fast - slow).abs().max()) <= 1e-5
    g = raycast_planes(cam_((0, 1.5, 3), (0, 0, 0), 16, 12),
                       [floor_plane(lambda p: (p[0].abs() < 1) & (p[2].abs() < 1))])
    p = HBAOParams(radius=1.0, tan_angle_bias=0.0, position_from=pf)
    assert float((hbao(g, p).ao - hbao_basic(g, p).ao).abs().max()) <= 1e-5


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("kw, name", [({"radius": 0.0}, "radius"), ({"radius": -1.0}, "radius"),
                                      ({"num_directions": 0}, "num_directions"), ({"num_steps": 0}, "num_steps"),
                                      ({"max_radius_pixels": 0.0}, "max_radius_pixels"),
                                      ({"noise_size": 0}, "noise_size"), ({"ao_strength": -1.0}, "ao_strength"),
                                      ({"tan_angle_bias": math.nan}, "tan_angle_bias"),
                                      ({"position_from": "normal"}, "position_from")])
def test_bad_params(kw, name):
    with pytest.raises(ValueError, match=name):
        HBAOParams(**kw)


def test_bad_gbuffer():
    g = crease(8, 6)
    with pytest.raises(ValueError, match="mask"):
        hbao(GBuffer(g.camera, view_z=g.view_z))
    with pytest.raises(ValueError, match="view_z"):
        hbao(GBuffer(g.camera, mask=g.mask))
    with checks.checks_disabled():                        # build broken G-buffers past GBuffer's own checks
        bad = [(GBuffer(g.camera, view_z=g.view_z[:, :, :5], mask=g.mask), "view_z"),
               (GBuffer(g.camera, view_z=g.view_z, mask=g.mask[..., :7]), "mask"),
               (GBuffer(g.camera, view_z=g.view_z.long(), mask=g.mask), "view_z"),
               (GBuffer(g.camera, view_z=g.view_z, mask=g.mask.float()), "mask"),
               (GBuffer(g.camera, view_z=-g.view_z, mask=g.mask), "view_z"),
               (GBuffer(g.camera, view_z=g.view_z * math.nan, mask=g.mask), "view_z")]
    for gb, name in bad:
        with pytest.raises(ValueError, match=name):
            hbao(gb)
    with pytest.raises(TypeError, match="params"):
        hbao(g, {"radius": 1.0})


# ----------------------------------------------------------------------------- real data
@pytest.mark.slow
@pytest.mark.mitsuba
def test_reference_crease_gbuffer():
    from ssbench.reference import gbuffer                 # not importorskip: ssbench must load Dr.Jit first
    g = gbuffer("crease", 64, 48)
    for pf in ("depth", "view_z"):
        ao = hbao(g, HBAOParams(position_from=pf)).ao
        assert not bool(torch.isnan(ao).any()) and bool(((ao >= 0) & (ao <= 1)).all())
        assert bool((ao[~g.mask] == 1).all())

