"""Flicker: the per-pixel temporal standard deviation, on sequences with a known answer."""
import math

import pytest
import torch

from ssbench.metrics import flicker, temporal_std


def test_still_is_zero_and_a_blink_is_its_std():
    assert float(flicker(torch.full((5, 1, 1, 3, 4), 0.3))) == 0.0
    blink = torch.tensor([0.2, 0.8] * 4, dtype=torch.float64).view(8, 1, 1, 1, 1).expand(8, 1, 1, 3, 4)
    assert float(flicker(blink)) == pytest.approx(torch.tensor([0.2, 0.8] * 4).double().std().item())


def test_iid_noise_reads_its_sigma():
    sigma, T = 0.05, 64
    x = 0.5 + sigma * torch.randn(T, 1, 1, 40, 40, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    c4 = math.sqrt(2 / (T - 1)) * math.exp(math.lgamma(T / 2) - math.lgamma((T - 1) / 2))   # E[s] = c4 sigma
    assert float(flicker(x)) == pytest.approx(c4 * sigma, rel=0.02)
    assert float(flicker(x[:, :, :, :20])) == pytest.approx(float(flicker(x[:, :, :, 20:])), rel=0.05)


def test_the_noise_knob_moves_it():
    """Averaging K draws per frame (a K-sample estimate) cuts the flicker as 1/sqrt(K)."""
    g = torch.Generator().manual_seed(1)
    vals = []
    for k in (1, 4, 16):
        draws = (torch.rand(16, k, 1, 16, 16, generator=g, dtype=torch.float64) < 0.3).double()
        vals.append(float(flicker(draws.mean(1, keepdim=True))))
    assert vals[0] > 1.7 * vals[1] > 1.7 * 1.7 * vals[2]


def test_only_pixels_valid_in_every_frame_count():
    x = torch.zeros(3, 1, 1, 2, 2, dtype=torch.float64)
    x[:, 0, 0, 0, 0] = torch.tensor([0.0, 1.0, 0.0])                       # flickers, but invalid in frame 2
    m = torch.ones_like(x, dtype=torch.bool)
    m[2, 0, 0, 0, 0] = False
    assert float(flicker(x, m)) == 0.0
    std, valid = temporal_std(x, m)
    assert not bool(valid[0, 0, 0, 0]) and float(std[0, 0, 0, 0]) == 0.0
    assert math.isnan(float(flicker(x, torch.zeros_like(m))))
    four = x[:, 0]                                                           # (T, 1, H, W) works too
    assert float(flicker(four, m[:, 0])) == 0.0


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="frames"):
        flicker(torch.zeros(1, 1, 1, 2, 2))
    with pytest.raises(TypeError, match="frames"):
        flicker(torch.zeros(2, 1, 1, 2, 2, dtype=torch.int64))
    with pytest.raises(ValueError, match="mask"):
        flicker(torch.zeros(2, 1, 1, 2, 2), torch.ones(2, 1, 1, 2, 3, dtype=torch.bool))
    with pytest.raises(TypeError, match="mask"):
        flicker(torch.zeros(2, 1, 1, 2, 2), torch.ones(2, 1, 1, 2, 2))
