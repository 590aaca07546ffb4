"""Image and artifact metrics, all restricted to valid pixels (``mask`` :math:`(B, 1, H, W)` bool).

* :mod:`ssbench.metrics.image` — MAE, RMSE, signed bias, PSNR and mean SSIM (kornia), ꟻLIP (flip-evaluator);
* :mod:`ssbench.metrics.ao` — AO artifact metrics: halo, flat bias, tile energy, noise, over-darkening;
* :mod:`ssbench.metrics.ao_banding` — banding: the low-frequency (structured) part of the error, tile-independent;
* :mod:`ssbench.metrics.ao_bent` — bent-normal angle error against the ray-traced bent normal;
* :mod:`ssbench.metrics.temporal` — flicker: the per-pixel temporal standard deviation over frames;
* :mod:`ssbench.metrics.implicit` — implicit-surface hit classes (missed / false hit, punch-through), depth error.
"""
from __future__ import annotations

from .ao import (HaloResult, depth_edges, flat_bias, halo, highpass, noise, over_darkening, power_spectrum,
                 tile_energy)
from .ao_banding import banding, lowpass
from . import implicit
from .temporal import flicker, temporal_std
from .image import bias, flip, luminance, mae, masked_mean, psnr, rmse, ssim

__all__ = ["mae", "rmse", "bias", "psnr", "ssim", "flip", "masked_mean", "luminance", "halo", "HaloResult", "depth_edges",
           "flat_bias", "banding", "lowpass", "tile_energy", "power_spectrum", "noise", "highpass", "over_darkening",
           "implicit", "flicker", "temporal_std"]
