"""Noise and tiling of an AO image: energy at the noise tile's frequency (:func:`tile_energy`, from
:func:`power_spectrum`) and the variance of the high-frequency residual (:func:`noise`, from :func:`highpass`).

AO maps are :math:`(B, 1, H, W)` visibilities in [0, 1]; masks :math:`(B, 1, H, W)` bool. Re-exported by
:mod:`ssbench.metrics.ao`.
"""
from __future__ import annotations

from typing import Optional

import torch

from .. import checks
from .image import prepare

__all__ = ["tile_energy", "power_spectrum", "noise", "highpass"]


def tile_energy(pred: torch.Tensor, mask: Optional[torch.Tensor] = None, tile: int = 4) -> torch.Tensor:
    r"""Fraction of the AO map's AC spectral energy at the noise-tile frequency and its harmonics.

    It tells how much of the image is the noise texture's repeating pattern (what a ``tile``-pixel blur
    removes), not whether there are bands: one fixed kernel has no tile and reads 0 whatever its error.
    Structured error is :func:`ssbench.metrics.ao_banding.banding`.

    The image is cropped to a multiple of ``tile`` (:math:`H' \times W'`, top-left) so the harmonics fall on
    FFT bins; the masked, mean-removed signal :math:`x_p = m_p(\hat a_p - \bar a)` (:math:`\bar a` the mean over
    the mask) is transformed, :math:`X = \mathrm{FFT2}(x)`, and

    .. math::
        \mathrm{tile\_energy} = \frac{\sum_{(k_y, k_x) \in T} |X_{k_y k_x}|^2}{\sum_{(k_y, k_x) \ne (0,0)} |X_{k_y k_x}|^2},
        \qquad T = \{(k_y, k_x) \ne (0, 0) : k_y \equiv 0 \bmod H'/t,\ k_x \equiv 0 \bmod W'/t\}

    i.e. the frequencies :math:`(j/t, i/t)` cycles/px, :math:`0 \le i, j < t` — where all the energy of a
    pattern repeating every ``t`` pixels (a tiled 4×4 noise texture) lies. A pattern periodic in ``tile``
    gives 1, white noise :math:`\approx (t^2-1)/(H'W')`, a smooth image ≈ 0. Energies are summed over the batch;
    ``nan`` for a constant image. Background pixels become 0 after mean removal, so a ragged mask leaks some
    energy elsewhere.

    Args:
        pred: :math:`(B, 1, H, W)` AO map, ``H, W ≥ tile``.
        mask: :math:`(B, 1, H, W)` bool (``None``: all).
        tile: noise-tile period :math:`t` in pixels.

    Returns:
        0-d tensor in [0, 1].

    Example:
        >>> pattern = torch.rand(1, 1, 4, 4, generator=torch.Generator().manual_seed(0))
        >>> round(float(tile_energy(pattern.repeat(1, 1, 8, 8))), 6)        # a tiled 4x4 texture
        1.0
    """
    power, harm = power_spectrum(pred, mask, tile)
    return (power[harm].sum() / power.sum()).to(pred.dtype)


def power_spectrum(pred: torch.Tensor, mask: Optional[torch.Tensor] = None, tile: int = 4
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    r"""The AC power spectrum :func:`tile_energy` reads, and where the tile harmonics are.

    Args:
        pred: :math:`(B, 1, H, W)` AO map, ``H, W ≥ tile``.
        mask: :math:`(B, 1, H, W)` bool (``None``: all).
        tile: noise-tile period in pixels.

    Returns:
        ``(power, harmonics)``: :math:`(H', W')` float64 :math:`\sum_b |X_{k_y k_x}|^2` with the DC bin zeroed
        (unshifted FFT layout, :math:`H' \times W'` the crop to a multiple of ``tile``), and the
        :math:`(H', W')` bool set :math:`T` of tile harmonics.

    Example:
        >>> power, harm = power_spectrum(torch.rand(1, 1, 8, 12))
        >>> power.shape, int(harm.sum())                                   # 4 x 4 - 1 harmonics
        (torch.Size([8, 12]), 15)
    """
    checks.check_shape(pred, ["B", "1", "H", "W"], "pred")
    if isinstance(tile, bool) or not isinstance(tile, int) or tile < 1:
        raise ValueError(f"tile: must be a positive integer, got {tile!r}")
    H, W = pred.shape[-2:]
    if H < tile or W < tile:
        raise ValueError(f"pred: image {H}x{W} is smaller than tile {tile}")
    x, _, m = prepare(pred, None, mask)
    h, w = H // tile * tile, W // tile * tile
    x, m = x[..., :h, :w].double(), m[..., :h, :w]
    mean = x[m].mean()
    x = torch.where(m, x - mean, torch.zeros_like(x))                     # (B, 1, h, w)
    power = torch.fft.fft2(x).abs().square().sum((0, 1))                  # (h, w)
    ky = torch.arange(h, device=power.device) % (h // tile) == 0
    kx = torch.arange(w, device=power.device) % (w // tile) == 0
    harm = ky[:, None] & kx[None, :]                                      # (h, w)
    harm[0, 0] = False
    power[0, 0] = 0.0
    return power, harm


def noise(pred: torch.Tensor, mask: Optional[torch.Tensor] = None, kernel: int = 5) -> torch.Tensor:
    r"""Variance of the high-frequency residual: the AO map minus its masked 5×5 box blur.

    The blur is a normalised convolution (``kornia.filters.box_blur`` of :math:`m\hat a` over that of
    :math:`m`), so background never bleeds in:

    .. math::
        r_p = \hat a_p - \frac{(B_k * m\hat a)_p}{(B_k * m)_p}, \qquad
        \mathrm{noise} = \frac{1}{|M|}\sum_{p\in M}(r_p - \bar r)^2

    Smooth (locally linear) AO has :math:`r \approx 0` inside the image; i.i.d. noise of variance
    :math:`\sigma^2` gives :math:`\sigma^2 (1 - 1/k^2)` (0.96 σ² for k = 5). Compare before and after a blur.

    Args:
        pred: :math:`(B, 1, H, W)` AO map.
        mask: :math:`(B, 1, H, W)` bool (``None``: all).
        kernel: odd box size :math:`k`.

    Returns:
        0-d tensor.

    Example:
        >>> float(noise(torch.ones(1, 1, 8, 8)))
        0.0
        >>> i = torch.arange(32)
        >>> checker = 0.5 + 0.1 * (-1.0) ** (i[:, None] + i)                # +-0.1: interior r = +-0.1 * 24/25
        >>> round(float(noise(checker.expand(1, 1, 32, 32))), 4)            # (0.096)^2 = 0.0092 + borders
        0.0093
    """
    v = highpass(pred, mask, kernel)[prepare(pred, None, mask)[2]]
    return (v - v.mean()).square().mean()


def highpass(pred: torch.Tensor, mask: Optional[torch.Tensor] = None, kernel: int = 5) -> torch.Tensor:
    r"""The residual :math:`r` of :func:`noise`: ``pred`` minus its masked (normalised) ``kernel``² box blur.

    Args:
        pred: :math:`(B, 1, H, W)` AO map.
        mask: :math:`(B, 1, H, W)` bool (``None``: all).
        kernel: odd box size.

    Returns:
        :math:`(B, 1, H, W)` residual, 0 off the mask.

    Example:
        >>> highpass(torch.full((1, 1, 6, 6), 0.3)).abs().max().item() < 1e-7
        True
    """
    import kornia
    checks.check_shape(pred, ["B", "1", "H", "W"], "pred")
    if isinstance(kernel, bool) or not isinstance(kernel, int) or kernel < 1 or kernel % 2 == 0:
        raise ValueError(f"kernel: must be an odd positive integer, got {kernel!r}")
    x, _, m = prepare(pred, None, mask)
    mf = m.to(x.dtype)
    num = kornia.filters.box_blur(x * mf, kernel, border_type="constant")
    den = kornia.filters.box_blur(mf, kernel, border_type="constant")
    r = x - num / den.clamp_min(torch.finfo(x.dtype).tiny)              # (B, 1, H, W)
    return torch.where(m, r, torch.zeros_like(r))
