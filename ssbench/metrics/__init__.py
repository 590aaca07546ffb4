"""Image and artifact metrics, all restricted to valid pixels (``mask`` :math:`(B, 1, H, W)` bool).

* :mod:`ssbench.metrics.image` — MAE, RMSE, signed bias, PSNR and mean SSIM (kornia), ꟻLIP (flip-evaluator);
* :mod:`ssbench.metrics.ao` — AO artifact metrics: halo, flat bias, banding, noise, over-darkening;
* :mod:`ssbench.metrics.implicit` — implicit-surface hit classes (missed / false hit, punch-through), depth error.
"""
from __future__ import annotations

from .ao import (HaloResult, banding, depth_edges, flat_bias, halo, highpass, noise, over_darkening,
                 power_spectrum)
from . import implicit
from .image import bias, flip, mae, masked_mean, psnr, rmse, ssim

__all__ = ["mae", "rmse", "bias", "psnr", "ssim", "flip", "masked_mean", "halo", "HaloResult", "depth_edges",
           "flat_bias", "banding", "power_spectrum", "noise", "highpass", "over_darkening", "implicit"]
