"""ssbench.metrics.image: masked MAE/RMSE/bias/PSNR/SSIM/ꟻLIP with closed-form answers and clear errors."""
import math

import pytest
import torch

from ssbench.metrics import bias, flip, mae, masked_mean, psnr, rmse, ssim


def _img(values, h=2, w=2):
    return torch.tensor(values, dtype=torch.float32).reshape(1, 1, h, w)


def _gen(seed=0):
    return torch.Generator().manual_seed(seed)


class TestPointwise:
    def test_closed_forms(self):
        pred, target = _img([0.2, 0.4, 1.0, 0.0]), _img([0.0, 0.0, 1.0, 1.0])
        assert mae(pred, target).item() == pytest.approx((0.2 + 0.4 + 0 + 1) / 4)
        assert rmse(pred, target).item() == pytest.approx(math.sqrt((0.04 + 0.16 + 1) / 4))
        assert bias(pred, target).item() == pytest.approx((0.2 + 0.4 - 1) / 4)

    def test_mask_excludes_pixels(self):
        pred, target = _img([0.5, 0.5, 0.0, 9.0]), _img([0.0, 0.0, 0.0, 0.0])
        mask = _img([1, 1, 1, 0]).bool()
        assert mae(pred, target, mask).item() == pytest.approx(1 / 3)
        assert bias(pred, target, mask).item() == pytest.approx(1 / 3)
        assert rmse(pred, target, mask).item() == pytest.approx(math.sqrt(0.5 / 3))
        assert masked_mean(pred, mask).item() == pytest.approx(1 / 3)

    def test_pooled_over_batch_and_channels(self):
        pred = torch.stack([torch.full((3, 2, 2), 1.0), torch.full((3, 2, 2), 3.0)])      # (2, 3, 2, 2)
        target = torch.zeros(2, 3, 2, 2)
        mask = torch.ones(2, 1, 2, 2, dtype=torch.bool)
        mask[1] = False
        assert mae(pred, target, mask).item() == 1.0
        assert mae(pred, target).item() == 2.0

    def test_empty_mask_is_nan(self):
        x = torch.zeros(1, 1, 2, 2)
        none = torch.zeros(1, 1, 2, 2, dtype=torch.bool)
        for f in (mae, rmse, bias):
            assert math.isnan(f(x, x, none).item())

    def test_bias_sign(self):
        t = torch.full((1, 1, 3, 3), 0.5)
        assert bias(t + 0.1, t).item() == pytest.approx(0.1)
        assert bias(t - 0.1, t).item() == pytest.approx(-0.1)

    @pytest.mark.parametrize("f", [mae, rmse, bias, psnr, ssim, flip])
    def test_errors_name_the_argument(self, f):
        x = torch.zeros(1, 1, 4, 4)
        with pytest.raises(ValueError, match="target"):
            f(x, torch.zeros(1, 1, 4, 5))
        with pytest.raises(ValueError, match="pred"):
            f(torch.zeros(4, 4), torch.zeros(4, 4))
        with pytest.raises(TypeError, match="mask"):
            f(x, x, torch.ones(1, 1, 4, 4))
        with pytest.raises(ValueError, match="mask"):
            f(x, x, torch.ones(1, 1, 4, 3, dtype=torch.bool))
        with pytest.raises(TypeError, match="pred"):
            f(x.long(), x)


class TestPSNR:
    def test_closed_form(self):
        pred = _img([0.1, 0.0, 0.0, 0.0])                                 # MSE = 0.01/4
        assert psnr(pred, torch.zeros_like(pred)).item() == pytest.approx(10 * math.log10(1 / 0.0025), rel=1e-5)
        assert psnr(pred, torch.zeros_like(pred), max_val=2.0).item() == pytest.approx(
            10 * math.log10(4 / 0.0025), rel=1e-5)

    def test_masked_error_only(self):
        pred, target = _img([0.1, 0.1, 0.0, 0.0]), torch.zeros(1, 1, 2, 2)
        mask = _img([1, 0, 1, 0]).bool()                                   # MSE over mask = 0.01/2
        assert psnr(pred, target, mask).item() == pytest.approx(10 * math.log10(200), rel=1e-5)

    def test_identical_is_inf(self):
        x = torch.rand(1, 1, 4, 4, generator=_gen())
        assert psnr(x, x).item() == math.inf

    def test_bad_max_val(self):
        with pytest.raises(ValueError, match="max_val"):
            psnr(torch.zeros(1, 1, 2, 2), torch.zeros(1, 1, 2, 2), max_val=0)


class TestSSIM:
    def test_identical_is_one_and_map_shape(self):
        x = torch.rand(2, 1, 16, 16, generator=_gen())
        mean, smap = ssim(x, x, return_map=True)
        assert mean.item() == pytest.approx(1.0, abs=1e-6)
        assert smap.shape == (2, 1, 16, 16)

    def test_mean_over_mask_matches_map(self):
        x = torch.rand(1, 1, 16, 16, generator=_gen(1))
        y = torch.rand(1, 1, 16, 16, generator=_gen(2))
        mask = torch.zeros(1, 1, 16, 16, dtype=torch.bool)
        mask[..., :, :8] = True
        mean, smap = ssim(x, y, mask, return_map=True)
        assert mean.item() == pytest.approx(smap[..., :8].mean().item(), rel=1e-6)
        assert mean.item() < 0.5                                          # unrelated noise

    def test_constant_images_closed_form(self):
        # constant images: sigma terms vanish, SSIM = (2 a b + c1) / (a^2 + b^2 + c1)
        a, b, c1 = 0.6, 0.4, 0.01 ** 2
        s = ssim(torch.full((1, 1, 16, 16), a), torch.full((1, 1, 16, 16), b)).item()
        assert s == pytest.approx((2 * a * b + c1) / (a * a + b * b + c1), rel=1e-4)

    def test_bad_window(self):
        x = torch.zeros(1, 1, 8, 8)
        with pytest.raises(ValueError, match="window_size"):
            ssim(x, x, window_size=4)


class TestFLIP:
    def test_identical_is_zero(self):
        x = torch.rand(1, 1, 12, 16, generator=_gen())
        assert flip(x, x).item() == 0.0

    def test_map_shape_and_mask_mean(self):
        target = torch.full((2, 1, 12, 16), 0.5)
        pred = target.clone()
        pred[:, :, 4:8, 4:8] = 0.9
        mean, fmap = flip(pred, target, return_map=True)
        assert fmap.shape == (2, 1, 12, 16) and fmap.dtype == torch.float32
        assert 0 < mean.item() < 1 and mean.item() == pytest.approx(fmap.mean().item(), rel=1e-6)
        mask = torch.zeros(2, 1, 12, 16, dtype=torch.bool)
        mask[:, :, 4:8, 4:8] = True
        inside = flip(pred, target, mask)
        assert inside.item() == pytest.approx(fmap[:, :, 4:8, 4:8].mean().item(), rel=1e-6)
        assert inside > mean                                               # the error sits in the square

    def test_grey_equals_rgb_replica(self):
        target = torch.rand(1, 1, 12, 16, generator=_gen(3))
        pred = (target + 0.2).clamp(0, 1)
        assert flip(pred, target).item() == pytest.approx(
            flip(pred.expand(1, 3, 12, 16), target.expand(1, 3, 12, 16)).item(), rel=1e-6)

    def test_bigger_error_scores_higher(self):
        target = torch.full((1, 1, 16, 16), 0.5)
        assert flip(target + 0.05, target) < flip(target + 0.3, target)

    def test_a_pair_is_evaluated_once(self, monkeypatch):
        import flip_evaluator
        calls = []
        real = flip_evaluator.evaluate
        monkeypatch.setattr(flip_evaluator, "evaluate", lambda *a, **k: calls.append(k) or real(*a, **k))
        target = torch.rand(1, 1, 12, 16, generator=_gen(5))
        pred = (target + 0.1).clamp(0, 1)
        first, fmap = flip(pred, target, return_map=True)
        fmap[:] = 7                                                         # the kept map is not aliased
        again, fmap2 = flip(pred.clone(), target.clone(), return_map=True)
        assert len(calls) == 1 and torch.equal(again, first) and bool((fmap2 < 1).all())
        flip(pred, target, inputs_srgb=False)                               # another setting, another pair
        flip(pred, target, ppd=30)
        flip(pred.flip(-1), target)
        assert len(calls) == 4

    def test_bad_arguments(self):
        x = torch.zeros(1, 2, 8, 8)
        with pytest.raises(ValueError, match="1 or 3 channels"):
            flip(x, x)
        with pytest.raises(ValueError, match="ppd"):
            flip(torch.zeros(1, 1, 8, 8), torch.zeros(1, 1, 8, 8), ppd=0)
