"""Banding: the structured (low-frequency) part of an AO method's error, independent of any noise tile.

Too few samples make SSAO show *bands* (SSAO article §1 Fig. 5: mebiusbox, 「スクリーンスペース・アンビエント・
オクルージョン (SSAO)」, 2022, https://zenn.dev/mebiusbox/articles/c7ea4871698ada): with one fixed kernel every
pixel makes the same mistakes, so neighbouring pixels' errors line up into contours; rotating the kernel per pixel (the noise
texture) turns the same error into fine noise, and a blur removes it (Fig. 6). The two differ only in the
*spatial frequency* of the error. This metric keeps the part of the error a small blur does not remove:

.. math::
    \\tilde e = \\frac{G_\\sigma * (m\\,(\\hat a - a))}{G_\\sigma * m}, \\qquad
    \\mathrm{banding} = \\sqrt{\\max\\Big(\\frac{1}{|D|}\\sum_{p \\in D} \\tilde e_p^2
                         - \\frac{1}{|D|}\\sum_{p \\in D} \\big(G_\\sigma^2 * s^2\\big)_p,\\ 0\\Big)}

with :math:`G_\\sigma` a Gaussian of ``sigma`` pixels (1.5 by default: it removes a 4×4 tile's pattern to
≈ 6 % of its amplitude while keeping bands a few pixels wide), :math:`m` the valid mask (a normalised
convolution: background never bleeds in), and the region :math:`D` the valid pixels **away from depth edges**
(halos are :func:`ssbench.metrics.halo`'s business) **where the target is occluded** (smoothed target
``< occluded``): bands follow occlusion gradients, while occlusion added on open ground is
:func:`ssbench.metrics.flat_bias`'s. The second sum removes the target's own Monte-Carlo noise
(:math:`s` its per-pixel standard error, ``target_stderr``) that survives the blur, so a noisier ground truth
does not read as banding. Units are AO (an rms), so ``banding = 0.05`` is a 5 % structured error.

What it does not separate: a *smooth* bias of the estimator (a range check that cuts real occlusion, depth
quantisation) passes the low-pass too. Score against the screen-space oracle (what the depth buffer holds)
to leave information loss out, as :func:`ssbench.evaluate.ao` does.
"""
from __future__ import annotations

import math
from typing import Optional

import kornia
import torch

from .. import checks
from .ao import edge_band
from .image import prepare

__all__ = ["banding", "lowpass"]


def _gaussian(sigma: float, dtype: torch.dtype, device) -> torch.Tensor:
    """:math:`(1, k)` normalised 1-D Gaussian of ``sigma`` pixels, ``k = 2⌈3σ⌉ + 1`` (kornia); the 2-D kernel is
    its outer product, applied separably (121 taps → 2 × 11 at σ = 1.5: float64 convolution has no fast path)."""
    k = 2 * max(1, int(math.ceil(3 * sigma))) + 1
    return kornia.filters.get_gaussian_kernel1d(k, sigma, dtype=dtype, device=device)


def _conv(x: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
    return kornia.filters.filter2d_separable(x, k, k, border_type="constant")   # zero border


def lowpass(x: torch.Tensor, mask: torch.Tensor, sigma: float = 1.5) -> torch.Tensor:
    r"""Masked (normalised) Gaussian low-pass :math:`G_\sigma * (m x) / G_\sigma * m` of a :math:`(B, 1, H, W)`
    map; 0 off the mask.

    Example:
        >>> m = torch.ones(1, 1, 8, 8, dtype=torch.bool)
        >>> float(lowpass(torch.full((1, 1, 8, 8), 0.25), m).max())
        0.25
    """
    k = _gaussian(sigma, x.dtype, x.device)
    mf = mask.to(x.dtype)
    out = _conv(x * mf, k) / _conv(mf, k).clamp_min(torch.finfo(x.dtype).tiny)
    return torch.where(mask, out, torch.zeros_like(out))


def banding(pred: torch.Tensor, target: torch.Tensor, view_z: torch.Tensor, mask: Optional[torch.Tensor] = None,
            *, target_stderr: Optional[torch.Tensor] = None, sigma: float = 1.5, occluded: float = 0.99,
            band: int = 4, reduction: str = "mean") -> torch.Tensor:
    r"""Structured error of ``pred`` against ``target`` (see the module docstring for the formula).

    Args:
        pred: :math:`(B, 1, H, W)` method AO :math:`\hat a`.
        target: :math:`(B, 1, H, W)` reference AO :math:`a` (ground truth or the screen-space oracle).
        view_z: :math:`(B, 1, H, W)` view z, for the depth edges left out (:func:`~ssbench.metrics.depth_edges`).
        mask: :math:`(B, 1, H, W)` bool valid pixels (``None``: all).
        target_stderr: :math:`(B, 1, H, W)` per-pixel standard error of ``target`` (``None``: exact target).

        ``target``, ``view_z``, ``mask`` and ``target_stderr`` may instead all have batch 1: one scene shared
        by every item of ``pred`` (a stack of kernel draws), whose region and noise floor are computed once.
        sigma: low-pass scale in pixels (> 0).
        occluded: the region is where the smoothed target is below this (in (0, 1]).
        band: half-width in pixels of the depth-edge band left out.
        reduction: ``"mean"`` pools the region of every batch item into one energy (a batch of kernel draws
            gives the banding of the method, not of one draw); ``"none"`` scores each item on its own.

    Returns:
        0-d tensor (``"mean"``) or :math:`(B,)` (``"none"``); ``nan`` where the region is empty.

    Example:
        >>> y = torch.linspace(0, 1, 32).reshape(1, 1, 32, 1).expand(1, 1, 32, 32)
        >>> truth, z = 0.5 + 0.4 * y, torch.full((1, 1, 32, 32), -1.0)
        >>> stairs = torch.floor(truth * 4) / 4                    # one fixed kernel of 4: bands
        >>> u = torch.rand(1, 1, 32, 32, generator=torch.Generator().manual_seed(0))
        >>> dithered = stairs + 0.25 * (u < (truth - stairs) * 4).double()   # rotated kernels: noise
        >>> bool(banding(stairs, truth, z) > 3 * banding(dithered, truth, z))
        True
    """
    checks.check_shape(pred, ["B", "1", "H", "W"], "pred")
    checks.check_shape(view_z, ["B", "1", "H", "W"], "view_z")
    if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not 0 < sigma < float("inf"):
        raise ValueError(f"sigma: must be a finite number > 0, got {sigma!r}")
    if isinstance(occluded, bool) or not isinstance(occluded, (int, float)) or not 0 < occluded <= 1:
        raise ValueError(f"occluded: must be a number in (0, 1], got {occluded!r}")
    if isinstance(band, bool) or not isinstance(band, int) or band < 0:
        raise ValueError(f"band: must be an integer >= 0, got {band!r}")
    if reduction not in ("mean", "none"):
        raise ValueError(f"reduction: must be 'mean' or 'none', got {reduction!r}")
    n, rb = pred.shape[0], view_z.shape[0]          # rb: the references' batch, n or 1 (shared by every item)
    if rb not in (1, n):
        raise ValueError(f"view_z: batch must be {n} (pred's) or 1, got {rb}")
    for name, v in (("target", target), ("mask", mask), ("target_stderr", target_stderr)):
        if v is not None and v.dim() == 4 and v.shape[0] != rb:
            raise ValueError(f"{name}: batch must match view_z's ({rb}), got {v.shape[0]}")
    x, t, m = prepare(pred[:1] if rb == 1 else pred, target, mask)     # checks; x is reread below
    if view_z.shape != t.shape:
        raise ValueError(f"view_z: shape must match pred {tuple(pred.shape)}, got {tuple(view_z.shape)}")
    x, t = pred.double(), t.double()
    region = m & ~edge_band(view_z, m[:, :1], band) & (lowpass(t, m, sigma) < occluded)     # (rb, 1, H, W)
    dims = (1, 2, 3) if reduction == "none" else (0, 1, 2, 3)
    region_n = region.expand(n, -1, -1, -1)
    count = region_n.sum(dims)
    e = lowpass(x - t, m, sigma)
    energy = torch.where(region_n, e.square(), torch.zeros_like(e)).sum(dims) / count.clamp_min(1)
    if target_stderr is not None:
        if target_stderr.shape != t.shape:
            raise ValueError(f"target_stderr: shape must match target {tuple(t.shape)}, "
                             f"got {tuple(target_stderr.shape)}")
        k = _gaussian(sigma, torch.float64, x.device)
        mf = m.double()
        var = torch.where(m, target_stderr.double(), torch.zeros_like(t)).square()
        floor = _conv(var, k * k) / _conv(mf, k).clamp_min(1e-300).square()   # variance of the blurred noise
        floor = torch.where(region, floor, torch.zeros_like(floor)).expand(n, -1, -1, -1)
        energy = energy - floor.sum(dims) / count.clamp_min(1)
    out = energy.clamp_min(0).sqrt()
    return torch.where(count > 0, out, torch.full_like(out, float("nan"))).to(pred.dtype)
