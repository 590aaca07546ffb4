"""Ray-traced AO ground truth against closed forms, and the screen-space oracle."""
import math

import pytest
import torch

from ssbench.reference import ambient_occlusion, gbuffer, screen_space_oracle
from ssbench.reference.ao import jeffreys_variance
from ssbench.scenes import load

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
CH = ["position", "normal", "mask", "shape_id", "view_z"]


def _world(g):
    return g.camera.view_to_world(g.position.double())[0]          # (3, H, W)


def test_crease_matches_closed_form_and_open_floor_is_exactly_one():
    sc, R = load("crease"), 0.8
    g = gbuffer(sc, 160, 120, channels=CH)
    ref = ambient_occlusion(sc, g, R, rays=1024, weighting="cosine", seed=1, use_cache=False)
    floor = g.shape_id[0, 0] == sc.shape_index("floor")
    x = _world(g)[2] + 3.0                                            # distance from the wall (z = −3)
    a = (x / R).clamp(0, 1)
    expected = 1 - (torch.acos(a) - a * torch.sqrt(1 - a * a)) / math.pi
    band = floor & (x < R)
    assert band.sum() > 300
    z = (ref.ao[0, 0].double() - expected) / ref.stderr[0, 0].double().clamp_min(1e-12)
    assert (z.abs()[band] < 3).float().mean() >= 0.95
    assert abs((ref.ao[0, 0].double() - expected)[band].mean()) < 3e-3
    open_floor = floor & (x > R * 1.05)
    assert torch.all(ref.ao[0, 0][open_floor] == 1.0)               # exactly: no self-intersection
    unanimous = math.sqrt(jeffreys_variance(1024, 1024))            # every ray free: error bar > 0, ~1/(√2 n)
    assert torch.allclose(ref.stderr[0, 0][open_floor].double(), torch.tensor(unanimous, dtype=torch.float64),
                          rtol=1e-5) and unanimous == pytest.approx(1 / (math.sqrt(2) * 1024), rel=2e-3)
    assert torch.all(ref.ao[0, 0][~g.mask[0, 0]] == 1.0)


@pytest.mark.parametrize("weighting", ["cosine", "uniform", "obscurance"])
def test_floor_under_a_ceiling_closed_forms(weighting):
    """A floor under an infinite ceiling at height h, a = h/R: cosθ > a is occluded.
    cosine: AO = a²; uniform: AO = a; obscurance: 1 − E[1 − (t/R)²] = 1 − (1 − a)²."""
    h, R = 0.3, 0.5
    a = h / R
    expected = {"cosine": a * a, "uniform": a, "obscurance": 1 - (1 - a) ** 2}[weighting]
    scene = {"name": "sandwich",
             "camera": {"eye": [0, 0.2, 1], "target": [0, 0, -1], "fovy": 60, "width": 64, "height": 48},
             "shapes": [{"type": "rectangle", "id": "floor", "size": [200, 200], "rotate": [-90, 0, 0]},
                        {"type": "rectangle", "id": "ceiling", "size": [200, 200], "rotate": [90, 0, 0],
                         "translate": [0, h, 0]}]}
    sc = load(scene)
    g = gbuffer(sc, channels=CH)
    ref = ambient_occlusion(sc, g, R, rays=1024, weighting=weighting, seed=3, use_cache=False)
    floor = g.shape_id[0, 0] == 0
    assert floor.sum() > 500
    est = ref.ao[0, 0][floor].double()
    z = (est - expected) / ref.stderr[0, 0][floor].double()
    assert (z.abs() < 3).float().mean() >= 0.95
    assert abs(est.mean() - expected) < 2e-3


def test_jeffreys_variance_is_the_beta_posterior_variance_and_never_zero():
    th = torch.linspace(0, math.pi / 2, 2_000_001, dtype=torch.float64)[1:-1]
    x = th.sin() ** 2                          # x = sin²θ: the Beta density has no end singularity in θ
    for n in (2, 16, 256):
        for k in (0, 1, n // 2, n - 1, n):
            a, b = k + 0.5, n - k + 0.5
            logw = (2 * a - 1) * th.sin().log() + (2 * b - 1) * th.cos().log()
            w = (logw - logw.max()).exp()
            w = w / w.sum()
            mean = (w * x).sum()
            assert jeffreys_variance(k, n) == pytest.approx(float((w * (x - mean) ** 2).sum()), rel=1e-4)
            assert jeffreys_variance(k, n) > 0
        mid = jeffreys_variance(n / 2, n)                   # close to the plug-in p(1 - p)/n in the middle
        assert mid == pytest.approx(0.25 / n, rel=3 / n)


@pytest.mark.parametrize("weighting", ["cosine", "obscurance"])
def test_stderr_is_positive_on_every_pixel_even_where_all_rays_agree(weighting):
    sc = load("cornell_box")
    g = gbuffer(sc, 40, 30, channels=CH)
    ref = ambient_occlusion(sc, g, 0.5, rays=16, weighting=weighting, seed=0, use_cache=False)
    m = g.mask[0, 0]
    assert bool((ref.stderr[0, 0][m] > 0).all()) and bool((ref.stderr[0, 0][~m] == 0).all())
    assert bool((ref.ao[0, 0][m] == 1).any())                      # the unanimous case occurs here


def test_same_seed_same_bits_and_argument_checks():
    sc = load("sphere_on_plane")
    g = gbuffer(sc, 48, 36, channels=CH)
    a = ambient_occlusion(sc, g, 0.5, rays=16, seed=4, use_cache=False)
    b = ambient_occlusion(sc, g, 0.5, rays=16, seed=4, use_cache=False)
    c = ambient_occlusion(sc, g, 0.5, rays=16, seed=5, use_cache=False)
    assert torch.equal(a.ao, b.ao) and torch.equal(a.stderr, b.stderr) and not torch.equal(a.ao, c.ao)
    assert a.ao.min() >= 0 and a.ao.max() <= 1 and not torch.isnan(a.ao).any()
    for kw, name in (({"radius": 0}, "radius"), ({"radius": 0.5, "rays": 1}, "rays"),
                     ({"radius": 0.5, "weighting": "gaussian"}, "weighting"),
                     ({"radius": 0.5, "seed": -1}, "seed")):
        with pytest.raises(ValueError, match=name):
            ambient_occlusion(sc, g, **kw)
    with pytest.raises(ValueError, match="gbuffer"):
        ambient_occlusion(sc, type(g).cat([g, g]), 0.5)


def test_oracle_sees_what_is_on_screen():
    sc, R = load("crease"), 0.8
    g = gbuffer(sc, 160, 120, channels=CH)
    full = ambient_occlusion(sc, g, R, rays=256, seed=2, use_cache=False)
    orc = screen_space_oracle(g, R, rays=256, seed=2, use_cache=False)
    floor = g.shape_id[0, 0] == sc.shape_index("floor")
    x = _world(g)[2] + 3.0
    assert torch.all(orc.ao[0, 0][floor & (x > 1.05 * R)] == 1.0)          # a planar height field
    W = g.width
    centre = torch.zeros_like(floor)
    centre[:, W // 4: 3 * W // 4] = True                                  # wall fully in view near here
    band = floor & (x < R) & (x > 0.1) & centre
    diff = (orc.ao - full.ao)[0, 0][band]
    assert band.sum() > 100 and diff.abs().median() < 0.02
    # the height field cannot see the wall beyond the image's top edge: the oracle only ever misses occluders
    assert (orc.ao - full.ao)[0, 0][floor].mean() >= -1e-3
