"""Jimenez et al.'s multi-bounce fit against its published form, and the fit against the path-traced truth: the
fit applied to the exact single-bounce AO must land closer to the multi-bounce truth than the single bounce."""
import pytest
import torch

from ssbench.metrics.ao_multibounce import jimenez_multibounce, multibounce_error


def published(v: float, rho: float) -> float:
    """The course's formula, written out by hand (§5)."""
    a, b, c = 2.0404 * rho - 0.3324, -4.7951 * rho + 0.6417, 2.7552 * rho + 0.6903
    return max(v, ((a * v + b) * v + c) * v)


@pytest.mark.parametrize("v", [0.0, 0.2, 0.5, 0.8, 1.0])
@pytest.mark.parametrize("rho", [0.0, 0.3, 0.7, 1.0])
def test_fit_is_the_published_cubic(v, rho):
    got = jimenez_multibounce(torch.full((1, 1, 1, 1), v, dtype=torch.float64),
                              torch.full((1, 3, 1, 1), rho, dtype=torch.float64))
    assert torch.allclose(got, torch.full_like(got, published(v, rho)), atol=1e-12)
    assert float(got.min()) >= v                                          # never darker than one bounce


def test_fit_grows_with_albedo_per_channel():
    v = torch.linspace(0, 1, 11, dtype=torch.float64).view(1, 1, 1, 11)
    rho = torch.tensor([0.1, 0.5, 0.9], dtype=torch.float64).view(1, 3, 1, 1).expand(-1, -1, -1, 11)
    out = jimenez_multibounce(v, rho)
    assert bool((out[:, 1] >= out[:, 0]).all()) and bool((out[:, 2] >= out[:, 1]).all())


def test_error_responds_to_bias_and_reports_the_truths_noise():
    t = torch.full((1, 3, 4, 4), 0.7)
    m = torch.ones(1, 1, 4, 4, dtype=torch.bool)
    assert multibounce_error(t, t, m)["rmse"] == 0.0
    e = multibounce_error(t + 0.05, t, m, torch.full_like(t, 0.01))
    assert e["rmse"] == pytest.approx(0.05, abs=1e-6) and e["bias"] == pytest.approx(0.05, abs=1e-6)
    assert e["truth_stderr"] == pytest.approx(0.01, abs=1e-6) and e["pixels"] == 16


@pytest.mark.slow
@pytest.mark.mitsuba
@pytest.mark.parametrize("scene", ["crease", "stairs"])
def test_the_fit_on_exact_single_bounce_ao_approaches_the_multibounce_truth(scene):
    from ssbench.reference import gbuffer
    from ssbench.reference.multibounce import multibounce_ao
    from ssbench.scenes import catalog
    sc = catalog.get(scene)
    g = gbuffer(sc, 64, 48)
    mb = multibounce_ao(sc, g, 0.5, rays=128, use_cache=False)
    single = multibounce_error(mb.single.expand(-1, 3, -1, -1), mb.ao, g.mask, mb.stderr)
    fit = multibounce_error(jimenez_multibounce(mb.single, mb.albedo), mb.ao, g.mask, mb.stderr)
    assert fit["rmse"] < 0.5 * single["rmse"], (single, fit)
    assert single["bias"] < 0                                             # one bounce is too dark
