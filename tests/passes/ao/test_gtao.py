"""GTAO (ssbench.passes.ao.gtao) on analytic G-buffers: planes seen by a Camera, intersected per pixel ray."""
import math
from dataclasses import replace

import pytest
import torch

from ssbench import checks
from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes import ao_method
from ssbench.passes.ao.gtao import (GTAO, QUALITY_PRESETS, REQUIRES, GTAOParams, hilbert_index, gtao,
                                 noise_buffer, slice_visibility)

F64 = torch.float64
EVERYWHERE = lambda hit: torch.ones(hit.shape[1:], dtype=torch.bool)


def planes_gbuffer(cam: Camera, planes, dtype=F64, scale: float = 1.0):
    """Nearest hit of each pixel-centre ray with ``planes`` = [(point, normal, inside(hit_world) -> bool)].

    Returns the G-buffer (view space, normals facing the camera) and the world hit points (3, H, W).
    ``scale`` multiplies the scene (points) and is applied to the camera by the caller.
    """
    rays = cam.pixel_rays(F64)                                          # (3, H, W), view z = -1
    d = cam.view_to_world_dir(rays)
    o = torch.tensor(cam.eye, dtype=F64).view(3, 1, 1)
    H, W = cam.height, cam.width
    best_t = torch.full((H, W), math.inf, dtype=F64)
    best_n = torch.zeros(3, H, W, dtype=F64)
    for p, nrm, inside in planes:
        p = torch.tensor(p, dtype=F64).view(3, 1, 1) * scale
        n = torch.nn.functional.normalize(torch.tensor(nrm, dtype=F64), dim=0).view(3, 1, 1)
        t = ((p - o) * n).sum(0) / (d * n).sum(0)
        hit = o + t * d
        ok = (t > cam.near) & (t < cam.far) & inside(hit / scale) & (t < best_t)
        best_t = torch.where(ok, t, best_t)
        best_n = torch.where(ok, n.expand(3, H, W), best_n)
    mask = torch.isfinite(best_t)
    view_z = torch.where(mask, -best_t, torch.full_like(best_t, -cam.far))   # ray z = -1 => view z = -t
    nv = cam.world_to_view_dir(best_n)
    nv = torch.where((nv * rays).sum(0) > 0, -nv, nv)                  # face the camera
    nv = torch.where(mask, nv, torch.zeros_like(nv))
    g = GBuffer(cam, view_z=view_z[None, None].to(dtype), normal=nv[None].to(dtype), mask=mask[None, None])
    return g, o + best_t.nan_to_num(posinf=0.0) * d


def open_plane(dtype=F64, w=24, h=18):
    cam = Camera.from_look_at((0, 4, 1), (0, 0, 0), (0, 1, 0), 30.0, w, h, 0.1, 100.0)
    return planes_gbuffer(cam, [((0, 0, 0), (0, 1, 0), EVERYWHERE)], dtype)[0]


def crease(dtype=F64, scale=1.0, w=32, h=24):
    s = scale
    cam = Camera.from_look_at((0, 1.2 * s, 2.5 * s), (0, 0.2 * s, -s), (0, 1, 0), 60.0, w, h, 0.1 * s, 100.0 * s)
    floor = ((0, 0, 0), (0, 1, 0), lambda p: p[2] >= -1)
    wall = ((0, 0, -1), (0, 0, 1), lambda p: p[1] >= 0)
    return planes_gbuffer(cam, [floor, wall], dtype, scale)


def quad_with_background():
    cam = Camera.from_look_at((0, 2, 2.5), (0, 0, 0), (0, 1, 0), 50.0, 24, 18, 0.1, 100.0)
    inside = lambda p: (p[0].abs() <= 0.8) & (p[2].abs() <= 0.8)
    return planes_gbuffer(cam, [((0, 0, 0), (0, 1, 0), inside)])[0]


class TestGTAO:
    def test_smoke_and_debug(self):
        g, _ = crease()
        p = GTAOParams(quality="medium")
        r = gtao(g, p, debug=True, bent_normals=True)
        B, S, H, W = 1, 2, g.height, g.width
        assert r.ao.shape == (B, 1, H, W) and r.ao.dtype == F64
        assert bool(((r.ao >= 0) & (r.ao <= 1)).all())
        assert r.bent_normal.shape == (B, 3, H, W)
        assert r.debug["horizon_cos"].shape == (B, S, 2, H, W)
        assert r.debug["normal_angle"].shape == (B, S, H, W)
        assert r.debug["slice_visibility"].shape == (B, S, H, W)
        assert r.debug["screen_radius"].shape == (B, 1, H, W)
        hc = r.debug["horizon_cos"]
        assert bool(((hc >= -1) & (hc <= 1)).all())
        assert gtao(g, p).bent_normal is None and gtao(g, p).debug == {}
        assert REQUIRES == ("view_z", "normal", "mask")
        fn, params_cls, req = ao_method("gtao")
        assert fn is gtao and params_cls is GTAOParams and req == REQUIRES

    def test_presets(self):
        for name, (slices, steps) in {"low": (1, 2), "medium": (2, 2), "high": (3, 3), "ultra": (9, 3)}.items():
            p = GTAOParams(quality=name)
            assert (p.slices, p.steps) == (slices, steps) == QUALITY_PRESETS[name]
        assert GTAOParams().slices == 3 and GTAOParams().steps == 3          # XeGTAO default: High
        p = GTAOParams(quality="low", slice_count=5, steps_per_slice=7)
        assert (p.slices, p.steps) == (5, 7)
        g, _ = crease(w=16, h=12)
        r = gtao(g, GTAOParams(quality="ultra"), debug=True)
        assert r.debug["horizon_cos"].shape[1] == 9

    def test_no_nan_background_grazing_near(self):
        g = quad_with_background()
        assert bool((~g.mask).any()) and bool(g.mask.any())
        r = gtao(g, bent_normals=True, debug=True)
        assert bool(torch.isfinite(r.ao).all()) and bool(((r.ao >= 0) & (r.ao <= 1)).all())
        assert bool((r.ao[~g.mask] == 1).all())
        assert bool((r.bent_normal[:, :, ~g.mask[0, 0]] == 0).all())
        assert bool(torch.isfinite(r.bent_normal).all())
        for v in r.debug.values():
            assert bool(torch.isfinite(v).all())
        # grazing: eye 2 cm above an infinite floor, looking at the horizon
        cam = Camera.from_look_at((0, 0.02, 0), (0, 0.02, -10), (0, 1, 0), 60.0, 24, 18, 0.01, 100.0)
        g, _ = planes_gbuffer(cam, [((0, 0, 0), (0, 1, 0), EVERYWHERE)])
        r = gtao(g, bent_normals=True)
        assert bool(torch.isfinite(r.ao).all()) and bool(torch.isfinite(r.bent_normal).all())
        # near plane: a wall right at z = -near fills the view
        cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 16, 12, 0.01, 10.0)
        g, _ = planes_gbuffer(cam, [((0, 0, -0.0100001), (0.3, 0, 1), EVERYWHERE)])
        assert bool(g.mask.any())
        r = gtao(g, GTAOParams(radius=5.0), bent_normals=True)
        assert bool(torch.isfinite(r.ao).all()) and bool(((r.ao >= 0) & (r.ao <= 1)).all())

    @pytest.mark.parametrize("noise", ["none", "hash", "hilbert"])
    def test_open_plane_unoccluded(self, noise):
        g = open_plane()
        r = gtao(g, GTAOParams(noise=noise), bent_normals=True)
        assert float(r.ao.min()) >= 0.99
        cos = (r.bent_normal * g.normal).sum(1)                         # bent normal == normal
        assert float(cos.min()) >= 0.998

    def test_crease_darkens_near_corner(self):
        g, hit = crease()
        r = gtao(g, GTAOParams(quality="ultra"))
        dist = hit[1].abs() + (hit[2] + 1).abs()                         # distance to the other plane
        m = g.mask[0, 0]
        near, far = m & (dist < 0.15), m & (dist > 1.0)
        assert int(near.sum()) > 5 and int(far.sum()) > 5
        ao = r.ao[0, 0]
        assert float(ao[near].mean()) < float(ao[far].mean()) - 0.2
        assert float(ao[far].mean()) > 0.97

    def test_slice_integral_matches_quadrature(self):
        gen = torch.Generator().manual_seed(1)
        n = (torch.rand(64, generator=gen, dtype=F64) - 0.5) * math.pi            # projected normal angle
        h0 = (n - math.pi / 2) * torch.rand(64, generator=gen, dtype=F64)          # in [n - π/2, 0]
        h1 = (n + math.pi / 2) * torch.rand(64, generator=gen, dtype=F64)          # in [0, n + π/2]
        t = torch.linspace(0, 1, 20001, dtype=F64).view(1, -1)
        f = lambda th: torch.cos(th - n[:, None]) * th.sin().abs()                # cosine weight × Jacobian
        left = torch.trapezoid(f(h0[:, None] * (1 - t)), t, dim=1) * -h0           # ∫_{h0}^{0}
        right = torch.trapezoid(f(h1[:, None] * t), t, dim=1) * h1                 # ∫_{0}^{h1}
        assert torch.allclose(slice_visibility(h0, h1, n), left + right, atol=1e-8)

    def test_unoccluded_slices_integrate_to_one(self):
        # (1/π) ∫ |proj n| (a(n-π/2) + a(n+π/2)) dψ over slices uniform around v: the cosine-weighted hemisphere
        alpha = 0.9                                                           # normal tilted 0.9 rad from v
        psi = (torch.arange(4000, dtype=F64) + 0.5) / 4000 * math.pi
        N = torch.tensor([math.sin(alpha), 0.0, math.cos(alpha)], dtype=F64)
        o = torch.stack([psi.cos(), psi.sin(), torch.zeros_like(psi)], 1)      # slice directions, v = +z
        axis = torch.stack([-psi.sin(), psi.cos(), torch.zeros_like(psi)], 1)
        proj = N - axis * (axis @ N)[:, None]
        plen = proj.norm(dim=1)
        n = torch.sign(o @ N) * torch.acos((proj[:, 2] / plen).clamp(0, 1))
        vis = plen * slice_visibility(n - math.pi / 2, n + math.pi / 2, n)
        assert abs(float(vis.mean()) - 1.0) < 1e-6

    def test_seed_determinism(self):
        g, _ = crease(w=16, h=12)
        hashed = dict(noise="hash")                                        # the seeded noise kind
        a, b = gtao(g, GTAOParams(seed=3, **hashed)).ao, gtao(g, GTAOParams(seed=3, **hashed)).ao
        assert torch.equal(a, b)
        assert not torch.equal(a, gtao(g, GTAOParams(seed=4, **hashed)).ao)
        gen = torch.Generator().manual_seed(3)
        assert torch.equal(a, gtao(g, GTAOParams(seed=99, **hashed), generator=gen).ao)
        nz = noise_buffer(GTAOParams(**hashed), 1, 4, 5)
        assert nz.shape == (1, 2, 4, 5) and bool(((nz >= 0) & (nz < 1)).all())

    def test_noise_kinds(self):
        g, _ = crease(w=16, h=12)
        tile2 = torch.rand(2, 4, 4, generator=torch.Generator().manual_seed(0), dtype=F64)
        for noise in ("none", "hilbert", tile2, tile2[0].tolist()):
            r = gtao(g, GTAOParams(noise=noise))
            assert bool(((r.ao >= 0) & (r.ao <= 1)).all())
        nb = noise_buffer(GTAOParams(noise=tile2), 1, 8, 8)
        assert torch.equal(nb[0, :, 5, 6], tile2[:, 1, 2])
        assert bool((noise_buffer(GTAOParams(noise="none"), 1, 3, 3) == 0.5).all())
        idx = hilbert_index(torch.arange(64).repeat(64), torch.arange(64).repeat_interleave(64))
        assert sorted(idx.tolist()) == list(range(4096))                    # a permutation of the 64² cells
        order = torch.argsort(idx)
        xs, ys = torch.arange(64).repeat(64)[order], torch.arange(64).repeat_interleave(64)[order]
        assert bool(((xs.diff().abs() + ys.diff().abs()) == 1).all())      # consecutive cells are adjacent

    def test_float32_matches_float64(self):
        g, _ = crease()
        a = gtao(g).ao
        b = gtao(g.to(dtype=torch.float32)).ao
        assert b.dtype == torch.float32
        assert float((a - b.double()).abs().max()) <= 1e-3

    def test_scale_invariance(self):
        g1, _ = crease()
        g2, _ = crease(scale=1000.0)
        a = gtao(g1, GTAOParams(radius=0.5)).ao
        b = gtao(g2, GTAOParams(radius=500.0)).ao
        assert torch.equal(g1.mask, g2.mask)
        assert float((a - b).abs().max()) <= 1e-4

    def test_module_matches_function(self):
        g, _ = crease(w=16, h=12)
        p = GTAOParams(quality="medium", seed=2)
        r1 = gtao(g, p, bent_normals=True)
        r2 = GTAO(p)(g, bent_normals=True)
        assert torch.equal(r1.ao, r2.ao) and torch.equal(r1.bent_normal, r2.bent_normal)
        assert GTAO(p, radius=2.0).params == replace(p, radius=2.0)

    def test_falloff_range_zero_is_a_hard_cut(self):
        g, _ = crease(w=16, h=12)
        r = gtao(g, GTAOParams(falloff_range=0.0))
        assert bool(((r.ao >= 0) & (r.ao <= 1)).all())
        r = gtao(g, GTAOParams(thin_occluder_compensation=0.7))
        assert bool(((r.ao >= 0) & (r.ao <= 1)).all())

    @pytest.mark.parametrize("kwargs, name", [
        ({"radius": 0.0}, "radius"), ({"radius": -1.0}, "radius"), ({"slice_count": 0}, "slice_count"),
        ({"steps_per_slice": 0}, "steps_per_slice"), ({"quality": "epic"}, "quality"),
        ({"falloff_range": 1.5}, "falloff_range"), ({"final_value_power": 0.0}, "final_value_power"),
        ({"radius_multiplier": float("nan")}, "radius_multiplier"), ({"noise": "blue"}, "noise"),
        ({"noise": torch.zeros(3, 3)}, "noise"), ({"seed": -1}, "seed"),
    ])
    def test_bad_params(self, kwargs, name):
        with pytest.raises(ValueError, match=name):
            GTAOParams(**kwargs)

    def test_bad_gbuffer(self):
        g, _ = crease(w=8, h=6)
        with pytest.raises(ValueError, match="normal"):
            gtao(replace(g, normal=g.normal * 2.0))                         # non-unit normals
        with pytest.raises(ValueError, match="normal"):
            gtao(g.select(["view_z", "mask"]))                              # missing channel
        with checks.checks_disabled():
            bad = [replace(g, view_z=g.view_z[..., :5]), replace(g, normal=g.normal[:, :2]),
                   replace(g, view_z=g.view_z.long()), replace(g, normal=g.normal.float()),
                   replace(g, mask=g.mask.float()), replace(g, view_z=-g.view_z)]
        for b, name in zip(bad, ["view_z", "normal", "view_z", "normal", "mask", "view_z"]):
            with pytest.raises(ValueError, match=name):
                gtao(b)
        with pytest.raises(TypeError, match="gbuffer"):
            gtao(g.view_z)
        with pytest.raises(TypeError, match="params"):
            gtao(g, {"radius": 1.0})


@pytest.mark.slow
def test_reference_crease():
    from ssbench.reference import gbuffer
    g = gbuffer("crease", 64, 48)
    r = gtao(g, bent_normals=True)
    assert r.ao.shape == (1, 1, 48, 64)
    assert bool(torch.isfinite(r.ao).all()) and bool(((r.ao >= 0) & (r.ao <= 1)).all())
    assert bool(torch.isfinite(r.bent_normal).all())
    assert bool((r.ao[~g.mask] == 1).all())


@pytest.mark.parametrize("kw", [dict(), dict(noise="hash", quality="low"), dict(falloff_range=0.0, quality="high"),
                                dict(thin_occluder_compensation=0.7, noise="none", denoise_passes=0),
                                dict(frame=5, sample_distribution_power=1.5, final_value_power=1.0)])
def test_teaching_twin_equals_vectorised(kw):
    from ssbench.passes.teaching.gtao_basic import gtao_basic
    g = crease(w=16, h=12)[0]
    for gb in (g, quad_with_background()):
        p = GTAOParams(radius=2.0, **kw)
        a = gtao(gb, p, generator=torch.Generator().manual_seed(3)).ao
        b = gtao_basic(gb, p, generator=torch.Generator().manual_seed(3)).ao
        assert float((a - b).abs().max()) < 1e-12, float((a - b).abs().max())
    assert float(gtao(g, GTAOParams(radius=2.0, **kw)).ao[g.mask].min()) < 0.9          # the crease is occluded: not trivial


@pytest.mark.parametrize("frame", [0, 5, 70])
def test_hilbert_noise_repeats_one_tile_as_the_per_pixel_formula_does(frame):
    """The noise is read from one cached 64×64 tile; XeGTAO computes it per pixel from the pixel's Hilbert index:
    the same bits on a size that is no multiple of 64."""
    from ssbench.passes.ao.gtao_parts import R2
    H, W = 70, 131
    row, col = torch.arange(H).view(H, 1).expand(H, W), torch.arange(W).view(1, W).expand(H, W)
    idx = hilbert_index(col, row).to(F64) + 288 * (frame % 64)
    expected = torch.frac(0.5 + idx * torch.tensor(R2, dtype=F64).view(2, 1, 1))
    got = noise_buffer(GTAOParams(noise="hilbert", frame=frame), 2, H, W)
    assert got.shape == (2, 2, H, W) and torch.equal(got[1], expected) and torch.equal(got[0], expected)
