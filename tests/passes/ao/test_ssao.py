"""Hemisphere SSAO (ssbench/passes/ao/ssao.py), Crytek SSAO (ao/crytek.py) and their teaching twins.

Unit tests use analytic G-buffers: infinite planes intersected with the camera's pixel rays (no Mitsuba).
"""
from __future__ import annotations

from dataclasses import replace

import pytest
import torch

from ssbench import checks
from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes import ao_method
from ssbench.passes.ao.ssao import HemisphereSSAO, HemisphereSSAOParams, hemisphere_ssao
from ssbench.passes.ao.crytek import CrytekSSAO, CrytekSSAOParams, crytek_ssao
from ssbench.passes.teaching.ssao_basic import crytek_ssao_basic, hemisphere_ssao_basic

FLOOR = [((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))]
CREASE = FLOOR + [((0.0, 0.0, -3.0), (0.0, 0.0, 1.0))]                  # floor meets a wall at z = -3
CREASE_EYE, CREASE_TARGET = (1.5, 2.5, 5.0), (0.0, 0.5, -1.5)            # the catalog's crease camera
PLANE_EYE = (0.0, 4.0, 3.0)                                              # steep view of the floor


def camera(eye, target, w=64, h=48, near=0.1, far=100.0, s=1.0) -> Camera:
    return Camera.from_look_at([s * v for v in eye], [s * v for v in target], (0, 1, 0), 45.0, w, h,
                               s * near, s * far)


def planes_gbuffer(cam: Camera, planes, dtype=torch.float64, s=1.0) -> GBuffer:
    """First hit of the rays through pixel centres with infinite world planes ``[(point, normal), ...]``."""
    d = cam.pixel_rays(torch.float64)                                    # (3, H, W), z = -1
    t_best = torch.full(d.shape[1:], float("inf"), dtype=torch.float64)
    n_best = torch.zeros_like(d)
    for p0, nw in planes:
        p = cam.world_to_view(torch.tensor([s * v for v in p0], dtype=torch.float64), dim=-1)
        n = cam.world_to_view_dir(torch.tensor(nw, dtype=torch.float64), dim=-1)
        t = (p @ n) / (d * n[:, None, None]).sum(0)                     # view z of the hit is -t
        ok = (t >= cam.near) & (t <= cam.far) & (t < t_best)
        t_best = torch.where(ok, t, t_best)
        n_best = torch.where(ok, n[:, None, None].expand_as(d), n_best)
    mask = torch.isfinite(t_best)
    pos = d * torch.where(mask, t_best, torch.full_like(t_best, cam.far))   # background: far plane
    normal = torch.where((n_best * pos).sum(0) > 0, -n_best, n_best)         # face the camera
    return GBuffer(cam, view_z=pos[2:3][None].to(dtype), normal=normal[None].to(dtype),
                   position=pos[None].to(dtype), mask=mask[None, None])


def crease_distance(g: GBuffer) -> torch.Tensor:
    """(H, W) world distance of each pixel's point to the crease line (y = 0, z = -3)."""
    p = g.camera.view_to_world(g.position[0].double())
    return torch.where(p[1].abs() < 1e-6, p[2] + 3.0, p[1])


@pytest.fixture(scope="module")
def plane() -> GBuffer:
    return planes_gbuffer(camera(PLANE_EYE, (0, 0, 0)), FLOOR)


@pytest.fixture(scope="module")
def crease() -> GBuffer:
    return planes_gbuffer(camera(CREASE_EYE, CREASE_TARGET), CREASE)


@pytest.fixture(scope="module")
def horizon() -> GBuffer:
    """A floor seen to its horizon: the top rows are background."""
    return planes_gbuffer(camera((0, 1, 6), (0, 0.8, 0), w=32, h=24), FLOOR)


VARIANTS = [(hemisphere_ssao, HemisphereSSAOParams, HemisphereSSAO, hemisphere_ssao_basic),
            (crytek_ssao, CrytekSSAOParams, CrytekSSAO, crytek_ssao_basic)]
IDS = ["hemisphere", "crytek"]


@pytest.mark.parametrize("fn,Params,Module,basic", VARIANTS, ids=IDS)
class TestBothVariants:
    def test_smoke(self, fn, Params, Module, basic, crease):
        out = fn(crease, Params(), debug=True)
        assert out.ao.shape == (1, 1, 48, 64) and out.ao.dtype == torch.float64
        assert bool(((out.ao >= 0) & (out.ao <= 1)).all())
        assert out.debug["samples"].shape == (1, 1, 48, 64)
        # AO is exactly the counted fraction
        torch.testing.assert_close(out.ao, 1 - out.debug["samples"].double() / Params().kernel_size, rtol=0, atol=0)

    def test_background_is_one(self, fn, Params, Module, basic, horizon):
        ao = fn(horizon, Params()).ao
        assert bool((~horizon.mask).any()) and bool((ao[~horizon.mask] == 1).all())
        assert not bool(torch.isnan(ao).any())

    @pytest.mark.parametrize("position_from", ["depth", "view_z"])
    def test_no_nan_grazing_and_near(self, fn, Params, Module, basic, position_from):
        kw = {"position_from": position_from} if Params is HemisphereSSAOParams else {}
        grazing = planes_gbuffer(camera((0, 0.02, 0), (0, 0.02, -10), w=32, h=24), FLOOR)
        # a wall just past the near plane: most samples land behind the camera (z > 0)
        near = planes_gbuffer(camera((0, 0, 0.1003), (0, 0, -1), w=16, h=12), [((0, 0, 0), (0, 0, 1))])
        for g in (grazing, near):
            for dtype in (torch.float64, torch.float32):
                ao = fn(g.to(dtype=dtype), Params(**kw)).ao
                assert bool(torch.isfinite(ao).all()) and bool(((ao >= 0) & (ao <= 1)).all())

    def test_crease_darkens_near_corner(self, fn, Params, Module, basic, crease):
        ao, dist = fn(crease, Params()).ao[0, 0], crease_distance(crease)
        m = crease.mask[0, 0]
        bands = [ao[m & (dist >= lo) & (dist < hi)].mean() for lo, hi in
                 [(0, 0.1), (0.1, 0.25), (0.25, 0.5), (1.0, 100)]]
        assert all(float(a) <= float(b) + 0.02 for a, b in zip(bands, bands[1:])), bands   # monotone-ish
        assert float(bands[0]) < float(bands[-1]) - 0.05, bands

    def test_determinism(self, fn, Params, Module, basic, crease):
        a = fn(crease, Params(seed=3)).ao
        assert torch.equal(a, fn(crease, Params(seed=3)).ao)
        assert torch.equal(a, fn(crease, Params(), generator=torch.Generator().manual_seed(3)).ao)
        assert not torch.equal(a, fn(crease, Params(seed=4)).ao)

    def test_float32_vs_float64(self, fn, Params, Module, basic, crease, plane):
        # Range checks and nearest fetches are hard thresholds: a sample that flips changes AO by 1/K, so
        # this holds only where no delta sits within float32 round-off of MinDistance/MaxDistance. The
        # planes here have none (checked: max difference 0, no pixel masking needed).
        for g in (crease, plane):
            d = (fn(g, Params()).ao - fn(g.to(dtype=torch.float32), Params()).ao.double()).abs()
            assert float(d.max()) <= 1e-3

    def test_scale_invariance(self, fn, Params, Module, basic):
        s = 1000.0
        small = planes_gbuffer(camera(CREASE_EYE, CREASE_TARGET, 32, 24), CREASE)
        big = planes_gbuffer(camera(CREASE_EYE, CREASE_TARGET, 32, 24, s=s), CREASE, s=s)
        p = Params()
        a, b = fn(small, p).ao, fn(big, replace(p, kernel_radius=p.kernel_radius * s)).ao
        assert float((a - b).abs().max()) <= 1e-4
        assert float(a.min()) < 1                                        # not trivially all ones

    def test_module(self, fn, Params, Module, basic, crease):
        p = Params(kernel_size=8, seed=2)
        assert torch.equal(Module(p)(crease).ao, fn(crease, p).ao)
        assert isinstance(Module(p), torch.nn.Module)

    def test_twin(self, fn, Params, Module, basic):
        g = planes_gbuffer(camera(CREASE_EYE, CREASE_TARGET, 16, 12), CREASE)
        modes = [{"position_from": "depth"}, {"position_from": "view_z"}] if Params is HemisphereSSAOParams \
            else [{}]
        for kw in modes:
            p = Params(seed=1, **kw)
            ref, out = basic(g, p), fn(g, p, debug=True)
            assert float((ref.ao - out.ao).abs().max()) <= 1e-5
            assert torch.equal(ref.debug["samples"], out.debug["samples"])

    def test_strength(self, fn, Params, Module, basic, crease):
        assert bool((fn(crease, Params(strength=0.0)).ao == 1).all())
        occlusion = fn(crease, Params(), debug=True).debug["samples"].double() / Params().kernel_size
        torch.testing.assert_close(fn(crease, Params(strength=3.0)).ao, (1 - 3 * occlusion).clamp(0, 1))
        assert float(fn(crease, Params(strength=100.0)).ao.min()) == 0.0   # clamped like an 8-bit target

    def test_batch(self, fn, Params, Module, basic, crease):
        g2 = planes_gbuffer(camera(CREASE_EYE, CREASE_TARGET), FLOOR)
        out = fn(GBuffer.cat([crease, g2]), Params()).ao
        assert torch.equal(out[:1], fn(crease, Params()).ao) and torch.equal(out[1:], fn(g2, Params()).ao)

    @pytest.mark.parametrize("field,value", [("kernel_radius", 0.0), ("kernel_radius", -1.0),
                                             ("kernel_size", 0), ("kernel_size", 2.0), ("noise_size", 0),
                                             ("min_distance", -0.1), ("max_distance", 0.0),
                                             ("strength", float("nan")), ("seed", -1)])
    def test_bad_params(self, fn, Params, Module, basic, field, value):
        with pytest.raises(ValueError, match=f"{field}:"):
            Params(**{field: value})

    def test_bad_inputs(self, fn, Params, Module, basic, crease):
        with pytest.raises(TypeError, match="gbuffer"):
            fn(crease.view_z, Params())
        with pytest.raises(TypeError, match="params"):
            fn(crease, {"kernel_size": 16})
        with pytest.raises(ValueError, match="mask"):
            fn(GBuffer(crease.camera, view_z=crease.view_z, normal=crease.normal), Params())
        with pytest.raises(TypeError, match="mask"):                   # GBuffer checks dtypes itself
            GBuffer(crease.camera, view_z=crease.view_z, mask=crease.mask.double())
        with checks.checks_disabled():                                  # ... so bypass it to reach the pass
            bad_dtype = GBuffer(crease.camera, view_z=crease.view_z, normal=crease.normal,
                                mask=crease.mask.double())
            bad_shape = GBuffer(crease.camera, view_z=crease.view_z[..., :-1], normal=crease.normal,
                                mask=crease.mask)
            int_z = GBuffer(crease.camera, view_z=crease.view_z.long(), normal=crease.normal, mask=crease.mask)
        with pytest.raises(ValueError, match="mask"):
            fn(bad_dtype, Params())
        with pytest.raises(ValueError, match="view_z"):
            fn(bad_shape, Params())
        with pytest.raises(ValueError, match="view_z"):
            fn(int_z, Params())
        with pytest.raises(ValueError, match="view_z"):
            fn(replace(crease, view_z=-crease.view_z), Params())      # behind the camera


class TestHemisphereSSAO:
    def test_open_plane(self, plane):
        for pf in ("depth", "view_z"):
            ao = hemisphere_ssao(plane, HemisphereSSAOParams(position_from=pf)).ao
            assert float(ao[plane.mask].mean()) >= 0.98 and float(ao.min()) >= 0.9

    def test_min_distance_is_the_bias(self, plane):
        # without the article's MinDistance bias, depth-texel quantisation self-occludes the open plane
        ao = hemisphere_ssao(plane, HemisphereSSAOParams(min_distance=0.0)).ao
        assert float(ao[plane.mask].mean()) < hemisphere_ssao(plane).ao[plane.mask].mean()

    def test_debug(self, crease):
        out = hemisphere_ssao(crease, debug=True)
        idx = out.debug["noise_index"]
        assert idx.shape == (1, 1, 48, 64)
        assert torch.equal(idx[0, 0, :4, :4].flatten(), torch.arange(16))   # the 4×4 tile, row-major
        assert torch.equal(idx[..., 4:8, 4:8], idx[..., :4, :4])
        assert out.debug["kernel"].shape == (32, 3) and out.debug["noise"].shape == (3, 4, 4)

    def test_kernel_sizes(self, crease):
        for k in (8, 16, 32, 64):
            out = hemisphere_ssao(crease, HemisphereSSAOParams(kernel_size=k), debug=True)
            assert int(out.debug["samples"].max()) <= k

    def test_non_unit_normals(self, crease):
        with pytest.raises(ValueError, match="normal"):
            hemisphere_ssao(replace(crease, normal=crease.normal * 1.5))
        with pytest.raises(ValueError, match="normal"):
            hemisphere_ssao(GBuffer(crease.camera, view_z=crease.view_z, mask=crease.mask))
        with checks.checks_disabled():
            bad = GBuffer(crease.camera, view_z=crease.view_z, normal=crease.normal[:, :2], mask=crease.mask)
        with pytest.raises(ValueError, match="normal"):
            hemisphere_ssao(bad)

    def test_position_from(self, crease):
        with pytest.raises(ValueError, match="position_from"):
            HemisphereSSAOParams(position_from="position")

    def test_registry(self):
        assert ao_method("ssao")[0] is hemisphere_ssao and ao_method("crytek")[0] is crytek_ssao
        assert ao_method("ssao")[2] == ("view_z", "normal", "mask") and ao_method("crytek")[2] == ("view_z", "mask")


class TestCrytekSSAO:
    def test_open_plane_is_grey(self, plane):
        ao = crytek_ssao(plane).ao
        assert abs(float(ao[plane.mask].mean()) - 0.5) <= 0.05

    def test_needs_no_normal(self, crease):
        g = GBuffer(crease.camera, view_z=crease.view_z, mask=crease.mask)
        assert torch.equal(crytek_ssao(g).ao, crytek_ssao(crease).ao)


@pytest.mark.slow
@pytest.mark.mitsuba
def test_reference_crease():
    from ssbench.reference import gbuffer                             # imports Mitsuba lazily, on first use
    g = gbuffer("crease", 64, 48)
    for out in (hemisphere_ssao(g.to(dtype=torch.float32)), crytek_ssao(g)):
        assert out.ao.shape == (1, 1, 48, 64) and bool(torch.isfinite(out.ao).all())
        assert bool(((out.ao >= 0) & (out.ao <= 1)).all()) and float(out.ao.min()) < 1




def test_red_channel_noise_turns_the_kernel_about_the_diagonal_only(crease):
    """three.js's ``vec3(noise.r)``: ``random = r·(1, 1, 1)``, so every pixel's tangent is ±normalize(d − n(n·d)),
    d = (1, 1, 1), whatever the noise; the article's ``.xyz`` tangents are not."""
    from ssbench.passes.ao.ssao import hemisphere_frame
    g = crease.to(dtype=torch.float64)
    fr = hemisphere_frame(g, HemisphereSSAOParams(noise_channels="r"))
    n, d = fr.normal, torch.ones(1, 3, 1, 1, dtype=torch.float64)
    expect = d - n * (d * n).sum(1, keepdim=True)
    expect = expect / expect.norm(dim=1, keepdim=True)
    cos = (fr.tangent * expect).sum(1)[g.mask[:, 0]]
    assert torch.allclose(cos.abs(), torch.ones_like(cos), atol=1e-12)
    xyz = hemisphere_frame(g, HemisphereSSAOParams()).tangent
    assert float(((xyz * expect).sum(1)[g.mask[:, 0]].abs() - 1).abs().max()) > 0.1
    with pytest.raises(ValueError, match="noise_channels"):
        HemisphereSSAOParams(noise_channels="rgb")
