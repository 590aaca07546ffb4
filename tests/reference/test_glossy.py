"""Glossy ground truth: the mirror limit equals the mirror-ray truth, the error bars predict the seed spread, the
oracle reads the G-buffer where the mirror truth says it can, and more roughness spreads the lobe."""
from __future__ import annotations

import pytest
import torch

from ssbench.reference import gbuffer, reflections
from ssbench.reference.glossy import GLOSSY_CHANNELS, glossy_reflections

CHANNELS = tuple(dict.fromkeys(("view_z", "normal", "position", "shape_id") + GLOSSY_CHANNELS))


@pytest.fixture(scope="module")
def floor():
    g = gbuffer("reflective_floor", 48, 36, CHANNELS, spp=4)
    return g, glossy_reflections("reflective_floor", g, rays=16, use_cache=False), reflections("reflective_floor", g,
                                                                                              spp=16)


def test_mirror_limit_is_the_mirror_truth(floor):
    g, gr, mirror = floor
    sel = gr.valid[0, 0] & (g.roughness[0, 0] == 0) & mirror.valid[0, 0]
    assert int(sel.sum()) > 300
    # every direction of a roughness-0 pixel is the mirror ray: the lobe is the mirror radiance, its spread is
    # only the path tracer's
    diff = (gr.lobe - mirror.radiance)[0][:, sel].abs().mean()
    assert float(diff) < 3 * float(gr.lobe_se[0][:, sel].mean()) + 0.01
    # the oracle at a visible on-screen mirror hit is the G-buffer colour there
    ok = sel & mirror.visible[0, 0] & mirror.on_screen[0, 0] & ~mirror.back_face[0, 0]
    px = mirror.hit_pixel[0].floor().long()
    want = g.color[0][:, px[1][ok], px[0][ok]]
    close = ((gr.oracle[0][:, ok] - want).abs().max(0).values < 1e-5).double().mean()
    assert int(ok.sum()) > 100 and float(close) > 0.95          # a hit on a pixel border may round the other way
    off = sel & mirror.hit[0, 0] & ~mirror.on_screen[0, 0]       # the target is outside the image
    assert float(gr.reachable[0, 0][ok].mean()) > 0.95 and int(off.sum()) > 20
    assert float(gr.reachable[0, 0][off].mean()) < 0.05 and float(gr.oracle[0][:, off].abs().mean()) < 0.01


def test_error_bars_predict_the_seed_spread():
    g = gbuffer("glossy_ramp", 40, 30, CHANNELS, spp=4)
    a = glossy_reflections("glossy_ramp", g, rays=16, seed=0, use_cache=False)
    b = glossy_reflections("glossy_ramp", g, rays=16, seed=1, use_cache=False)
    sel = a.valid[0, 0] & (g.metallic[0, 0] > 0.5) & (g.roughness[0, 0] > 0.05)
    z = ((a.lobe - b.lobe) / (a.lobe_se ** 2 + b.lobe_se ** 2).sqrt().clamp_min(1e-6))[0][:, sel]
    z = z[(a.lobe_se[0][:, sel] > 1e-4) & (b.lobe_se[0][:, sel] > 1e-4)]
    rms = float(z.pow(2).mean().sqrt())
    assert z.numel() > 300 and 0.7 < rms < 1.3, rms            # the error bars are honest
    again = glossy_reflections("glossy_ramp", g, rays=16, seed=0, use_cache=False)
    assert torch.equal(a.lobe, again.lobe) and torch.equal(a.oracle, again.oracle)   # same seed, same bits
    assert bool((a.specular <= a.lobe + 1e-6).all())           # F·G1 ≤ 1
    assert bool(((a.reachable >= 0) & (a.reachable <= 1)).all())


def test_bad_arguments(floor):
    g = floor[0]
    with pytest.raises(ValueError, match="rays"):
        glossy_reflections("reflective_floor", g, rays=1)
    with pytest.raises(ValueError, match="seed"):
        glossy_reflections("reflective_floor", g, seed=-1)
    with pytest.raises(ValueError, match="roughness"):
        glossy_reflections("reflective_floor", g.select(["color", "mask"]))
