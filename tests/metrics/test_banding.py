"""Banding: the low-frequency part of the error, independent of the noise tile (induced on synthetic images)."""
import math

import pytest
import torch

from ssbench.metrics import banding, lowpass

H = W = 64


def _truth():
    y = torch.linspace(0, 1, H, dtype=torch.float64).reshape(1, 1, H, 1).expand(1, 1, H, W)
    return 0.3 + 0.6 * y                                                    # a smooth occlusion gradient


def _z():
    return torch.full((1, 1, H, W), -2.0, dtype=torch.float64)


def _quantised(truth, k, dither=None):
    """What a K-sample count gives: ``floor(a·K)/K``, or with per-pixel dither (rotated kernels) its unbiased
    random rounding."""
    lo = torch.floor(truth * k) / k
    if dither is None:
        return lo
    u = torch.rand(truth.shape, generator=torch.Generator().manual_seed(dither), dtype=torch.float64)
    return lo + (u < (truth - lo) * k).double() / k


def test_bands_fall_with_the_sample_count_and_dither_turns_them_into_noise():
    t = _truth()
    fixed = [float(banding(_quantised(t, k), t, _z())) for k in (2, 4, 8, 16, 32)]
    dithered = [float(banding(_quantised(t, k, dither=k), t, _z())) for k in (2, 4, 8, 16, 32)]
    assert all(b < a for a, b in zip(fixed, fixed[1:])), fixed
    assert fixed[0] > 8 * fixed[-1]                                          # steps of 1/K: ~1/K
    assert all(d < 0.5 * f for d, f in zip(dithered, fixed)), (dithered, fixed)


def test_a_tiled_pattern_is_not_banding_but_a_smooth_bias_is():
    t = _truth()
    tile = 0.1 * (torch.rand(1, 1, 4, 4, generator=torch.Generator().manual_seed(1), dtype=torch.float64) - 0.5)
    tile = tile - tile.mean()                                               # a zero-mean 4x4 noise texture
    assert float(banding(t + tile.repeat(1, 1, H // 4, W // 4), t, _z())) < 0.004   # ~6 % of its amplitude
    assert float(banding(t - 0.05, t, _z())) == pytest.approx(0.05, rel=1e-9)       # documented: it passes


def test_region_leaves_out_open_ground_and_depth_edges():
    t = _truth().clone()
    t[..., : H // 4, :] = 1.0                                               # open ground at the top
    pred = t.clone()
    pred[..., : H // 4 - 8, :] -= 0.3          # self-occlusion there, farther than the blur reaches: flat bias
    assert float(banding(pred, t, _z())) < 1e-3
    z = _z().clone()
    z[..., :, W // 2:] = -6.0                                              # a depth edge down the middle
    pred = t.clone()
    pred[..., H // 2:, W // 2 - 2: W // 2 + 2] -= 0.3                      # an error hugging it: a halo
    assert float(banding(pred, t, z)) < 1e-3
    assert float(banding(pred, t, _z())) > 0.01                            # the same error without the edge


def test_the_target_noise_floor_is_removed():
    t = _truth()
    sigma = 0.05
    noisy = t + sigma * torch.randn(t.shape, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    se = torch.full_like(t, sigma)
    raw = float(banding(t, noisy, _z()))
    assert raw > 0.005                                                      # a noisy truth reads as structure
    assert float(banding(t, noisy, _z(), target_stderr=se)) < 0.25 * raw


def test_lowpass_is_normalised_inside_the_mask_and_arguments_are_checked():
    m = torch.zeros(1, 1, 8, 8, dtype=torch.bool)
    m[..., 2:6, 2:6] = True
    x = torch.where(m, torch.full((1, 1, 8, 8), 0.4), torch.full((1, 1, 8, 8), 9.0))
    out = lowpass(x, m)
    assert torch.allclose(out[m], torch.tensor(0.4)) and torch.all(out[~m] == 0)
    t = _truth()
    assert math.isnan(float(banding(torch.ones_like(t), torch.ones_like(t), _z())))   # nothing occluded
    for kw, name in ((dict(sigma=0), "sigma"), (dict(occluded=1.5), "occluded"), (dict(band=-1), "band"),
                     (dict(target_stderr=torch.ones(1, 1, 2, 2)), "target_stderr")):
        with pytest.raises(ValueError, match=name):
            banding(t, t, _z(), **kw)
    with pytest.raises(ValueError, match="view_z"):
        banding(t, t, torch.ones(1, 1, 2, 2))


def test_a_batch_of_draws_pools_their_energy_and_shares_one_scene():
    """``reduction="none"`` scores each draw as a batch of one would; ``"mean"`` is the root of their mean
    energy; batch-1 references (one scene for every draw) give the same numbers as repeating them."""
    t = _truth()
    draws = torch.cat([_quantised(t, k, dither=None if k % 2 else k) for k in (3, 4, 5, 8)])
    se = torch.full_like(t, 0.01)
    n = draws.shape[0]
    one = torch.stack([banding(d[None], t, _z(), target_stderr=se) for d in draws])
    each = banding(draws, t, _z(), target_stderr=se, reduction="none")
    assert each.shape == (n,) and torch.allclose(each, one, rtol=1e-12, atol=0)
    pooled = banding(draws, t.expand(n, -1, -1, -1), _z().expand(n, -1, -1, -1), target_stderr=se.expand(n, -1, -1, -1))
    assert float(pooled) == pytest.approx(float(one.square().mean().sqrt()), rel=1e-12)
    assert float(banding(draws, t, _z(), target_stderr=se)) == pytest.approx(float(pooled), rel=1e-12)
    with pytest.raises(ValueError, match="reduction"):
        banding(draws, t, _z(), reduction="sum")
    with pytest.raises(ValueError, match="target"):
        banding(draws, t.expand(2, -1, -1, -1), _z())                       # neither n nor view_z's batch 1
