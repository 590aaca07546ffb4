"""Scalable Ambient Obscurance: the teaching twin equal to the pass (every option, odd sizes, MIP levels in use),
the rotated-grid pyramid and the MIP level of each tap as the listing computes them, an open plane unoccluded, a
crease occluded, the pyramid's approximation small, and bad parameters refused by name."""
import pytest
import torch

from ssbench.passes.ao.sao import SAO, SAOParams, sao
from ssbench.passes.ao.sao_parts import depth_mips, mip_level, quad_filter
from ssbench.passes.teaching.sao_basic import sao_basic

from .test_gtao import crease, open_plane, quad_with_background


@pytest.mark.parametrize("params", [SAOParams(), SAOParams(normals="gbuffer"), SAOParams(quad_filter=False),
                                    SAOParams(radius=2.5, use_mips=False), SAOParams(radius=2.5, num_samples=5),
                                    SAOParams(bias=0.0, intensity=2.0, log_max_offset=1, max_mip_level=2)])
def test_the_teaching_twin_equals_the_pass(params):
    for g in (crease(w=17, h=13)[0], quad_with_background()):
        fast, slow = sao(g, params).ao, sao_basic(g, params).ao
        assert fast.dtype == torch.float64 and torch.allclose(fast, slow, atol=1e-12, rtol=0), \
            float((fast - slow).abs().max())
    levels = sao(crease(w=17, h=13)[0], SAOParams(radius=2.5, log_max_offset=1), debug=True).debug["mip_level"]
    assert int(levels.max()) >= 2                                      # the twin was compared on coarse levels too


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("params", [SAOParams(radius=2.5, log_max_offset=1), SAOParams(use_mips=False)])
def test_the_int32_taps_give_the_bits_of_the_int64_taps(monkeypatch, dtype, params):
    import dataclasses
    import ssbench.passes.ao.sao as sao_module
    g, _ = crease(w=40, h=30)
    g = dataclasses.replace(g, **{k: getattr(g, k).to(dtype) for k in ("view_z", "normal")})
    two = dataclasses.replace(g, view_z=torch.cat([g.view_z, g.view_z * 1.5 - 0.5]),  # two images: layer offsets
                              normal=g.normal.repeat(2, 1, 1, 1), mask=g.mask.repeat(2, 1, 1, 1))
    narrow = [sao(x, params, debug=True) for x in (g, two)]
    monkeypatch.setattr(sao_module, "INT32_TAP_RADIUS", 0.0)                       # every band falls back to int64
    wide = [sao(x, params, debug=True) for x in (g, two)]
    for a, b in zip(narrow, wide):
        assert torch.equal(a.ao, b.ao) and torch.equal(a.debug["mip_level"], b.debug["mip_level"])
    assert int(narrow[0].debug["mip_level"].max()) >= (1 if params.use_mips else 0)


def test_pyramid_and_levels_follow_the_listing():
    z = torch.arange(6 * 7, dtype=torch.float64).view(1, 1, 6, 7)
    mips = depth_mips(z, 3)
    assert [tuple(m.shape[-2:]) for m in mips] == [(6, 7), (3, 3), (1, 1), (1, 1)]
    for y in range(3):
        for x in range(3):                                            # texel (x, y) ← (2x + (y&1), 2y + (x&1))
            assert mips[1][0, 0, y, x] == z[0, 0, min(2 * y + (x & 1), 5), min(2 * x + (y & 1), 6)]
    assert mip_level(torch.tensor([15.9, 16.0, 31.9, 32.0]), 3, 5).tolist() == [0, 1, 1, 2]
    g = crease(w=64, h=48)[0]
    wide = sao(g, SAOParams(radius=4.0), debug=True).debug["mip_level"]
    flat = sao(g, SAOParams(radius=4.0, use_mips=False), debug=True).debug["mip_level"]
    assert int(wide.max()) >= 1 and int(flat.max()) == 0


def test_open_plane_is_unoccluded_and_a_crease_is_not():
    g = open_plane()
    for normals in ("depth", "gbuffer"):
        ao = sao(g, SAOParams(normals=normals)).ao
        assert float(ao[..., 3:, :].min()) == 1.0
        # the top rows see taps off the far edge: the clamped edge depth at the tap's own (higher) position is a
        # point above the plane: the shader's edge artifact, kept
        assert float(ao[..., :3, :].min()) < 1.0
    g, _ = crease()
    ao = sao(g, SAOParams(radius=1.0)).ao
    assert float(ao[g.mask].min()) < 0.6 and float(ao[g.mask].max()) == 1.0
    assert float(sao(g, SAOParams(radius=1.0, intensity=2.0)).ao[g.mask].mean()) < float(ao[g.mask].mean())


def test_depth_normals_match_the_gbuffer_on_planes_and_mips_approximate():
    g, _ = crease(w=64, h=48)
    n = sao(g, debug=True).debug["normal"]                                # the quads' face normals
    inner = g.mask.clone()
    inner[..., :2, :] = inner[..., -2:, :] = False
    close = ((n * g.normal).sum(1, keepdim=True) > 0.999) & inner
    assert float(close.float().sum() / inner.float().sum()) > 0.8      # all but the pixels whose quad spans the fold
    a = sao(g, SAOParams(radius=2.0)).ao
    b = sao(g, SAOParams(radius=2.0, use_mips=False)).ao
    assert 0 < float((a - b).abs().mean()) < 0.05


def test_quad_filter_averages_quads_within_a_depth_step():
    a = torch.tensor([[[[0.0, 1.0, 5.0], [1.0, 1.0, 5.0]]]], dtype=torch.float64)
    z = torch.zeros_like(a)
    out = quad_filter(a, z)
    assert out[0, 0, :, :2].eq(0.75).all() and out[0, 0, :, 2].eq(5.0).all()     # an odd column is left alone
    z[..., 1] = 1.0                                                               # a depth step inside the quad
    assert quad_filter(a, z)[0, 0, 0, 0] == 0.5                                    # only the y pass averages


def test_parameters_are_checked_and_the_module_wraps_the_function():
    for bad in (dict(num_samples=0), dict(radius=-1.0), dict(bias=-0.1), dict(intensity=0.0),
                dict(normals="mesh"), dict(max_mip_level=-1), dict(use_mips=1)):
        name = next(iter(bad))
        with pytest.raises(ValueError, match=name):
            SAOParams(**bad)
    g = quad_with_background()
    assert torch.equal(SAO(radius=0.7)(g).ao, sao(g, SAOParams(radius=0.7)).ao)
    assert torch.equal(sao(g, generator=torch.Generator().manual_seed(1)).ao, sao(g).ao)   # no randomness
    with pytest.raises(TypeError, match="params"):
        sao(g, {"radius": 1.0})
