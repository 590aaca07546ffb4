"""ssbench.metrics.ao: artifact metrics on inputs whose answer is known in closed form."""
import math

import pytest
import torch

from ssbench.metrics import depth_edges, tile_energy, flat_bias, halo, noise, over_darkening


def _gen(seed=0):
    return torch.Generator().manual_seed(seed)


def _step_scene(h=24, w=32, col=16):
    """view_z with a depth step between columns col-1 and col (near on the left)."""
    z = torch.full((1, 1, h, w), -2.0)
    z[..., col:] = -6.0
    return z


class TestDepthEdges:
    def test_step_marks_both_sides(self):
        e = depth_edges(_step_scene())
        assert e[0, 0].any(0).nonzero().flatten().tolist() == [15, 16]
        assert e[..., 15].all() and e[..., 16].all()

    def test_plane_and_small_gradient_have_no_edges(self):
        z = -torch.linspace(2.0, 2.5, 32).expand(1, 1, 24, 32)            # 0.8 % per pixel, far below 10 %
        assert not depth_edges(z).any()

    def test_threshold_is_relative(self):
        # the same 10 % jump at depth 1 and at depth 1000
        for s in (1.0, 1000.0):
            z = torch.full((1, 1, 4, 4), -1.0 * s)
            z[..., 2:] = -1.2 * s
            assert depth_edges(z, threshold=0.1).any()
            assert not depth_edges(z, threshold=0.3).any()

    def test_silhouettes(self):
        z = torch.full((1, 1, 6, 6), -2.0)
        mask = torch.ones(1, 1, 6, 6, dtype=torch.bool)
        mask[..., 3:] = False
        z[..., 3:] = -100.0                                                # background at the far plane
        assert not depth_edges(z, mask).any()                              # default: no surface behind
        e = depth_edges(z, mask, silhouettes=True)
        assert e[..., 2].all() and e.sum() == 6                            # only the valid side is marked

    def test_bad_threshold(self):
        with pytest.raises(ValueError, match="threshold"):
            depth_edges(_step_scene(), threshold=0)


class TestHalo:
    def test_planted_halo_is_measured(self):
        z = _step_scene()
        target = torch.full_like(z, 0.7)
        pred = target.clone()
        pred[..., 14:18] += 0.2                                            # bright seam, 2 px each side
        pred += 0.01 * (-1.0) ** torch.arange(32)                          # a small error everywhere
        r = halo(pred, target, z, band=2)
        # band = edge columns 15, 16 dilated by 2 = 13..18: columns 14..17 err 0.2 +- 0.01, 13 and 18 err 0.01
        assert r.band.item() == pytest.approx((4 * 0.2 + 2 * 0.01) / 6, abs=1e-5)
        assert r.elsewhere.item() == pytest.approx(0.01, abs=1e-6)
        assert r.ratio.item() == pytest.approx(r.band.item() / 0.01, rel=1e-4)
        assert r.band_bias.item() > 0                                      # too bright: a halo of non-occlusion
        assert r.band_mask[0, 0].any(0).nonzero().flatten().tolist() == list(range(13, 19))

    def test_dark_and_missing_split_the_band_error_by_sign_and_respond_to_their_own_artifact(self):
        """Induce a dark halo of depth d (false occlusion at the step) over a fixed bright error elsewhere in
        the band: ``dark`` grows as d, ``missing`` stays, and the old band MAE would mix the two."""
        z = _step_scene()
        target = torch.full_like(z, 0.8)
        base = target.clone()
        base[..., 13] += 0.1                                               # a fixed missing-occlusion column
        darks = []
        for d in (0.0, 0.05, 0.1, 0.2, 0.4):
            pred = base.clone()
            pred[..., 15:17] -= d                                          # dark halo at the edge columns
            r = halo(pred, target, z, band=2)
            assert r.dark.item() == pytest.approx(2 * d / 6, abs=1e-6)    # band = 6 columns
            assert r.missing.item() == pytest.approx(0.1 / 6, abs=1e-6)
            assert (r.dark + r.missing).item() == pytest.approx(r.band.item(), abs=1e-6)
            assert (r.missing - r.dark).item() == pytest.approx(r.band_bias.item(), abs=1e-6)
            darks.append(r.dark.item())
        assert darks == sorted(darks) and darks[-1] > darks[0]

    def test_dark_is_absolute_so_error_elsewhere_does_not_move_it(self):
        z = _step_scene()
        target = torch.full_like(z, 0.8)
        pred = target.clone()
        pred[..., 15:17] -= 0.2
        quiet = halo(pred, target, z, band=2)
        pred[..., :8] += 0.15                                              # a large error far from the edge
        noisy = halo(pred, target, z, band=2)
        assert noisy.dark.item() == quiet.dark.item() and noisy.ratio.item() < quiet.ratio.item()

    def test_band_width(self):
        z = _step_scene()
        for k in (0, 1, 3):
            r = halo(torch.ones_like(z), torch.ones_like(z), z, band=k)
            assert int(r.band_mask[0, 0, 0].sum()) == 2 + 2 * k

    def test_error_away_from_edges_gives_small_ratio(self):
        z = _step_scene()
        target = torch.full_like(z, 0.7)
        pred = target + 0.1
        pred[..., 12:20] = target[..., 12:20]
        r = halo(pred, target, z, band=2)
        assert r.band.item() == 0 and r.ratio.item() == 0

    def test_mask_restricts_both_regions(self):
        z = _step_scene()
        mask = torch.ones_like(z, dtype=torch.bool)
        mask[..., :4] = False
        pred = torch.ones_like(z)
        pred[..., :4] = 0.0                                                # error only off the mask
        r = halo(pred, torch.ones_like(z), z, mask, band=2)
        assert r.band.item() == 0 and r.elsewhere.item() == 0 and math.isnan(r.ratio.item())
        assert not (r.band_mask & ~mask).any()

    def test_bad_band(self):
        z = _step_scene()
        with pytest.raises(ValueError, match="band"):
            halo(z, z, z, band=-1)
        with pytest.raises(ValueError, match="view_z"):
            halo(z, z, z[..., :5])


class TestFlatBias:
    def test_crytek_like_grey_plane(self):
        target = torch.ones(1, 1, 8, 8)
        target[..., :2, :] = 0.4                                           # an occluded strip
        pred = torch.full_like(target, 0.5)                                # the sphere kernel's grey
        assert flat_bias(pred, target).item() == pytest.approx(0.5)

    def test_eps_and_mask(self):
        target = torch.tensor([1.0, 0.9995, 0.99, 1.0]).reshape(1, 1, 2, 2)
        pred = torch.tensor([0.9, 0.8, 0.0, 0.0]).reshape(1, 1, 2, 2)
        mask = torch.tensor([True, True, True, False]).reshape(1, 1, 2, 2)
        assert flat_bias(pred, target, mask).item() == pytest.approx((0.1 + 0.2) / 2)
        assert flat_bias(pred, target, mask, eps=0).item() == pytest.approx(0.1)

    def test_perfect_and_empty(self):
        t = torch.full((1, 1, 4, 4), 0.5)
        assert math.isnan(flat_bias(t, t).item())                          # no unoccluded pixel
        assert flat_bias(torch.ones_like(t), torch.ones_like(t)).item() == 0.0
        with pytest.raises(ValueError, match="eps"):
            flat_bias(t, t, eps=1.0)


class TestTileEnergy:
    def test_tiled_pattern_is_one(self):
        pattern = torch.rand(1, 1, 4, 4, generator=_gen())
        tiled = pattern.repeat(1, 1, 12, 16)                               # 48 x 64
        assert tile_energy(tiled).item() == pytest.approx(1.0, abs=1e-9)

    def test_tiled_pattern_on_a_ragged_size_is_cropped(self):
        pattern = torch.rand(1, 1, 4, 4, generator=_gen(1))
        tiled = pattern.repeat(1, 1, 12, 16)[..., :46, :63]
        assert tile_energy(tiled).item() == pytest.approx(1.0, abs=1e-9)

    def test_smooth_ramp_is_near_zero(self):
        ramp = torch.linspace(0, 1, 64).expand(1, 1, 48, 64)
        # a sawtooth: |X_k|^2 ~ 1/sin^2(pi k/N); the harmonics k = 16, 32, 48 hold 5 / ((N^2-1)/3) of it
        assert tile_energy(ramp).item() == pytest.approx(5 / ((64 ** 2 - 1) / 3), rel=1e-3)
        assert tile_energy(ramp).item() < 0.01

    def test_white_noise_is_small(self):
        x = torch.rand(1, 1, 64, 64, generator=_gen(2))
        assert tile_energy(x).item() < 5 * 15 / 64 ** 2

    def test_structured_noise_on_smooth_signal(self):
        ramp = torch.linspace(0.3, 1, 64).expand(1, 1, 64, 64)
        tile = 0.2 * (torch.rand(1, 1, 4, 4, generator=_gen(3)) - 0.5)
        b0, b1 = tile_energy(ramp), tile_energy(ramp + tile.repeat(1, 1, 16, 16))
        assert b1 > 10 * b0

    def test_other_tile(self):
        stripes = (torch.arange(48) % 3 == 0).float().expand(1, 1, 48, 48)
        assert tile_energy(stripes, tile=3).item() == pytest.approx(1.0, abs=1e-9)
        assert tile_energy(stripes, tile=4).item() < 0.1

    def test_constant_is_nan_and_bad_args(self):
        assert math.isnan(tile_energy(torch.ones(1, 1, 8, 8)).item())
        with pytest.raises(ValueError, match="tile"):
            tile_energy(torch.ones(1, 1, 8, 8), tile=0)
        with pytest.raises(ValueError, match="smaller than tile"):
            tile_energy(torch.ones(1, 1, 3, 8))


class TestNoise:
    def test_iid_noise_closed_form(self):
        sigma = 0.1
        x = 0.5 + sigma * torch.randn(1, 1, 256, 256, generator=_gen(4))
        # r = x - mean_5x5(x): var = sigma^2 (1 - 1/25) in the interior
        assert noise(x).item() == pytest.approx(sigma ** 2 * 24 / 25, rel=0.03)

    def test_smooth_is_near_zero_and_blur_reduces_noise(self):
        import kornia
        ramp = torch.linspace(0, 1, 64).expand(1, 1, 64, 64).contiguous()
        assert noise(ramp).item() < 1e-2 * noise(ramp + 0.1 * torch.randn(1, 1, 64, 64, generator=_gen(5))).item()
        x = 0.5 + 0.1 * torch.randn(1, 1, 64, 64, generator=_gen(6))
        assert noise(kornia.filters.box_blur(x, 5)).item() < 0.2 * noise(x).item()

    def test_background_does_not_leak(self):
        x = torch.full((1, 1, 16, 16), 0.4)
        mask = torch.zeros(1, 1, 16, 16, dtype=torch.bool)
        mask[..., 4:12, 4:12] = True
        x[~mask] = 1.0                                                     # background AO is 1
        assert noise(x, mask).item() == pytest.approx(0.0, abs=1e-12)
        assert noise(x).item() > 0.001                                     # unmasked: the edge counts

    def test_bad_kernel(self):
        with pytest.raises(ValueError, match="kernel"):
            noise(torch.ones(1, 1, 8, 8), kernel=4)


class TestOverDarkening:
    def test_double_occlusion_is_two(self):
        t = 0.5 + 0.5 * torch.rand(1, 1, 8, 8, generator=_gen(7))
        assert over_darkening(1 - 2 * (1 - t), t).item() == pytest.approx(2.0, rel=1e-6)
        assert over_darkening(1 - 0.5 * (1 - t), t).item() == pytest.approx(0.5, rel=1e-6)
        assert over_darkening(t, t).item() == pytest.approx(1.0)

    def test_mask(self):
        t = torch.tensor([0.5, 0.5]).reshape(1, 1, 1, 2)
        p = torch.tensor([0.0, 0.5]).reshape(1, 1, 1, 2)
        assert over_darkening(p, t, torch.tensor([True, False]).reshape(1, 1, 1, 2)).item() == 2.0
        assert over_darkening(p, t).item() == 1.5

    def test_unoccluded_gt(self):
        one = torch.ones(1, 1, 2, 2)
        assert over_darkening(one * 0.5, one).item() == math.inf
        assert math.isnan(over_darkening(one, one).item())
