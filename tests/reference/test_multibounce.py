"""Multi-bounce AO ground truth: reduces to the single-bounce cosine truth, grows with albedo path by path, and
carries a standard error that predicts its own seed-to-seed spread."""
import pytest
import torch

from ssbench.reference import ambient_occlusion, gbuffer
from ssbench.reference.multibounce import multibounce_ao
from ssbench.scenes import catalog

pytestmark = pytest.mark.mitsuba


@pytest.fixture(scope="module")
def box():
    sc = catalog.get("cornell_box")
    return sc, gbuffer(sc, 48, 36)


def test_no_albedo_and_no_bounce_are_the_single_bounce_truth_bit_for_bit(box):
    sc, g = box
    single = ambient_occlusion(sc, g, 0.5, 32, "cosine", 3, use_cache=False).ao
    for kw in ({"albedo_scale": 0.0}, {"bounces": 0}):
        mb = multibounce_ao(sc, g, 0.5, rays=32, seed=3, use_cache=False, **kw)
        assert torch.equal(mb.ao, single.expand(-1, 3, -1, -1)), kw
        assert torch.equal(mb.single, single)


def test_more_albedo_more_light_on_every_path(box):
    """The same paths (same seed) with every albedo scaled up can only carry more: per pixel and channel."""
    sc, g = box
    runs = [multibounce_ao(sc, g, 0.5, rays=32, seed=1, albedo_scale=s, use_cache=False).ao for s in (0.0, 0.5, 1.0)]
    m = g.mask.expand(-1, 3, -1, -1)
    assert bool((runs[1][m] >= runs[0][m] - 1e-6).all()) and bool((runs[2][m] >= runs[1][m] - 1e-6).all())
    assert float((runs[2] - runs[0])[m].mean()) > 0.05                # a closed box: interreflection matters
    assert bool((runs[2][m] <= 1.0 + 1e-6).all())


def test_standard_error_predicts_the_spread_between_seeds(box):
    sc, g = box
    a, b = (multibounce_ao(sc, g, 0.5, rays=64, seed=s, use_cache=False) for s in (10, 11))
    m = g.mask.expand(-1, 3, -1, -1) & (a.stderr > 0) & (b.stderr > 0)
    z = ((a.ao - b.ao) / (a.stderr ** 2 + b.stderr ** 2).sqrt())[m]
    assert 0.8 < float(z.pow(2).mean().sqrt()) < 1.25


def test_arguments_are_checked(box):
    sc, g = box
    for kw, name in (({"bounces": -1}, "bounces"), ({"albedo_scale": 1.5}, "albedo_scale"), ({"rays": 1}, "rays")):
        with pytest.raises(ValueError, match=name):
            multibounce_ao(sc, g, 0.5, **{"rays": 8, **kw})
