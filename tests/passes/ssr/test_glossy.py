"""Glossy SSR passes: the mirror limit, determinism, what ray reuse buys, and bad input."""
from __future__ import annotations

import dataclasses

import pytest
import torch

from ssbench.passes.ssr.glossy_blur import BlurSSRParams, ssr_glossy_blur
from ssbench.passes.ssr.glossy_stochastic import StochasticSSR, StochasticSSRParams, ssr_glossy_stochastic
from ssbench.passes.ssr.hiz import HiZSSRParams, ssr_hiz
from ssbench.passes.ssr.linear import LinearSSRParams, ssr_linear
from tests.passes.ssr_scenes import room


def rough(g, r):
    return dataclasses.replace(g, roughness=torch.full_like(g.view_z, r))


MARCH = dict(max_ray_distance=50.0, depth_buffer_thickness=0.5)


@pytest.mark.parametrize("reuse", ["none", "neighbours"])
def test_mirror_limit_is_the_hiz_march(reuse):
    g = rough(room(32, 24), 0.0)
    a = ssr_glossy_stochastic(g, StochasticSSRParams(reuse=reuse, **MARCH))
    b = ssr_hiz(g, HiZSSRParams(**MARCH))
    assert torch.equal(a.termination, b.termination)             # m = n: the mirror ray, up to the frame's rounding
    assert float((a.hit_pixel - b.hit_pixel).abs().max()) < 1e-9
    tol = 1e-9 if reuse == "none" else 1e-3                      # neighbours weigh ~1e-4 against a mirror spike
    assert float((a.raw_color - b.raw_color).abs().max()) <= tol
    assert float((a.color - b.color).abs().max()) <= tol


def test_blur_at_roughness_zero_is_the_linear_march():
    g = rough(room(32, 24), 0.0)
    a = ssr_glossy_blur(g, BlurSSRParams(max_ray_distance=50.0))
    b = ssr_linear(g, LinearSSRParams(max_ray_distance=50.0))
    assert torch.allclose(a.raw_color, b.raw_color, atol=1e-12) and torch.equal(a.termination, b.termination)
    c = ssr_glossy_blur(rough(room(32, 24), 1.0), BlurSSRParams(max_ray_distance=50.0))
    assert float((c.raw_color - b.raw_color).abs().mean()) > 1e-3          # blurred at roughness 1


def test_seeded_and_rough_rays_differ():
    g = rough(room(32, 24), 0.4)
    p = StochasticSSRParams(**MARCH)
    a, b = ssr_glossy_stochastic(g, p), ssr_glossy_stochastic(g, p)
    assert torch.equal(a.raw_color, b.raw_color)
    c = ssr_glossy_stochastic(g, dataclasses.replace(p, seed=1))
    assert not torch.equal(a.raw_color, c.raw_color)
    assert torch.equal(StochasticSSR(p)(g).raw_color, a.raw_color)
    assert all(bool(torch.isfinite(t).all()) for t in (a.raw_color, a.color, c.raw_color))
    m = ssr_glossy_stochastic(g, dataclasses.replace(p, rays_per_pixel=3))
    assert int(m.steps.sum()) > 2 * int(a.steps.sum())                    # three rays' reads


def test_reuse_lowers_the_noise():
    g = rough(room(32, 24), 0.4)
    floor = (g.shape_id == 0) & g.mask

    def spread(reuse):
        runs = torch.stack([ssr_glossy_stochastic(g, StochasticSSRParams(reuse=reuse, seed=s, **MARCH)).raw_color
                            for s in range(8)])
        return float(runs.std(0).mean(1, keepdim=True)[floor].mean()), runs.mean(0)

    s_none, m_none = spread("none")
    s_reuse, m_reuse = spread("neighbours")
    assert s_reuse < 0.6 * s_none, (s_reuse, s_none)
    bias = float((m_reuse - m_none).mean(1, keepdim=True)[floor].mean())
    assert abs(bias) < 0.02                                     # the same lobe on average (a ratio estimator)


@pytest.mark.slow
def test_the_compiled_reuse_gives_the_eager_colours_to_an_ulp():
    """The reuse sums through ``torch.compile`` (one loop over the pixels for each ray): the same hits bit for bit,
    the resolved colours within float32 rounding (inductor divides and takes roots in its own order); without reuse,
    whose weights are the mask, the same bits."""
    from ssbench.passes import compiled as C
    g = dataclasses.replace(rough(room(32, 24, torch.float32), 0.3), color=torch.rand(1, 3, 24, 32,
                            generator=torch.Generator().manual_seed(0)))
    for p in (StochasticSSRParams(rays_per_pixel=2, **MARCH), StochasticSSRParams(reuse_radius=2, **MARCH),
              StochasticSSRParams(reuse="none", **MARCH)):
        with C.compiling(False):
            eager = ssr_glossy_stochastic(g, p)
        before = C.compile_seconds()
        with C.compiling(True):
            comp = ssr_glossy_stochastic(g, p)
        assert C.compile_seconds() > before                        # the reuse kernel went through torch.compile
        assert bool(eager.hit.any()) and torch.equal(eager.hit_pixel, comp.hit_pixel)
        for name in ("raw_color", "color"):
            a, b = getattr(eager, name), getattr(comp, name)
            assert float(a.amax()) > 0.1
            assert torch.equal(a, b) if p.reuse == "none" else float((a - b).abs().max()) <= 1e-6, name


@pytest.mark.parametrize("kw,name", [(dict(rays_per_pixel=0), "rays_per_pixel"), (dict(reuse="all"), "reuse"),
                                     (dict(reuse_radius=9), "reuse_radius"), (dict(seed=-1), "seed"),
                                     (dict(depth_buffer_thickness=-1.0), "depth_buffer_thickness")])
def test_bad_stochastic_params(kw, name):
    with pytest.raises(ValueError, match=name):
        StochasticSSRParams(**kw)


@pytest.mark.parametrize("kw,name", [(dict(max_sigma=-1.0), "max_sigma"), (dict(levels=1), "levels"),
                                     (dict(iterations=0), "iterations")])
def test_bad_blur_params(kw, name):
    with pytest.raises(ValueError, match=name):
        BlurSSRParams(**kw)


def test_roughness_is_required():
    g = room(8, 6).select(["view_z", "normal", "mask", "color"])
    with pytest.raises(ValueError, match="roughness"):
        ssr_glossy_stochastic(g)
    with pytest.raises(ValueError, match="roughness"):
        ssr_glossy_blur(g)
