"""Noise-periodic offsets (ssbench/passes/noise_tiles.py) and the Crytek pass that repeats them down its bands."""
from __future__ import annotations

import dataclasses

import pytest
import torch

from ssbench.passes.noise_tiles import band_tile_rows, rows_repeat, tiled_add


@pytest.mark.parametrize("axis", [2, -1])
@pytest.mark.parametrize("tile", [1, 2, 4, 12])
def test_tiled_add_equals_the_explicitly_repeated_sum(axis, tile):
    g = torch.Generator().manual_seed(0)
    position, offset = torch.randn(2, 1, 12, 7, generator=g), torch.randn(5, tile, 7, generator=g)
    repeated = offset.repeat(1, 12 // tile, 1)                                   # (K, h, W)
    expected = position.unsqueeze(2) + repeated.unsqueeze(0).unsqueeze(0)        # (B, 1, K, h, W)
    if axis == -1:
        expected = expected.permute(0, 1, 3, 4, 2)
    out = tiled_add(position, offset, axis)
    assert out.is_contiguous() and torch.equal(out, expected)


def test_tiled_add_refuses_a_tile_that_does_not_divide_the_band():
    with pytest.raises(ValueError, match="offset"):
        tiled_add(torch.zeros(1, 1, 6, 4), torch.zeros(2, 4, 4), 2)
    with pytest.raises(ValueError, match="offset"):
        tiled_add(torch.zeros(1, 1, 8, 4), torch.zeros(2, 4, 3), 2)


def test_rows_repeat_reads_the_values():
    tile = torch.randn(1, 3, 4, 6, generator=torch.Generator().manual_seed(1))
    image = tile.repeat(1, 1, 5, 1)                                              # 20 rows, period 4
    assert rows_repeat(image, 4) and rows_repeat(image[..., 1:19, :], 4) and rows_repeat(image[..., :3, :], 4)
    assert not rows_repeat(image, 3)
    broken = image.clone()
    broken[0, 1, 17, 2] += 1e-7
    assert not rows_repeat(broken, 4)
    assert not rows_repeat(image.to("meta"), 4)                                  # no values to compare


def test_band_tile_rows_takes_the_first_period_only_for_whole_aligned_periods():
    assert band_tile_rows(slice(0, 12), 4, True) == slice(0, 4)
    assert band_tile_rows(slice(4, 6), 4, True) == slice(4, 6)                  # part of a period
    assert band_tile_rows(slice(2, 6), 4, True) == slice(2, 6)                  # not on a period's start
    assert band_tile_rows(slice(0, 12), 4, False) == slice(0, 12)


@pytest.mark.parametrize("noise_size", [3, 4, 5])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_crytek_bands_with_and_without_the_repeated_tile_give_the_same_bits(noise_size, dtype, monkeypatch):
    """Crytek's sample offsets come from one period of noise rows where the noise repeats, from each band's own rows
    where it does not (bands that do not start on a period, the last band, a forced non-periodic noise): every
    combination gives the same AO and count."""
    import ssbench.passes.ao.crytek as crytek
    import ssbench.passes.common as C
    from tests.passes.ssr_scenes import room
    g = dataclasses.replace(room(40, 30, dtype, slat=True), color=None)
    p = crytek.CrytekSSAOParams(noise_size=noise_size, seed=2)

    def run(budget, periodic=None):
        monkeypatch.setattr(C, "BLOCK_BYTES", budget)
        if periodic is not None:
            monkeypatch.setattr(crytek, "rows_repeat", lambda noise, size: periodic)
        return crytek.crytek_ssao(g, p, debug=True)

    whole = run(1 << 40, periodic=False)                                # one band, every pixel's own offsets
    for budget in (1, 3 * 16 * 40 * dtype.itemsize * 7):                # one period per band; 6 or 7 rows
        for periodic in (True, False):
            out = run(budget, periodic)
            assert torch.equal(out.ao, whole.ao) and torch.equal(out.debug["samples"], whole.debug["samples"])
    assert 0 < float(whole.ao.mean()) < 1
