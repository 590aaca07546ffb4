"""Full-reference image metrics restricted to valid pixels: MAE, RMSE, signed bias, PSNR, SSIM and ꟻLIP.

Every function takes ``pred`` and ``target`` of shape :math:`(B, C, H, W)` and an optional boolean ``mask``
:math:`(B, 1, H, W)` (``None``: every pixel counts), broadcast over the channels. Statistics are pooled over
all masked pixels of the whole batch and returned as 0-d tensors; a mean over an empty mask is ``nan``
(data for a sweep, not an error). PSNR and SSIM go through :mod:`kornia.metrics`, ꟻLIP through NVIDIA's
``flip_evaluator`` package. Bad input raises ``ValueError``/``TypeError`` naming the argument (``pred``,
``target``, ``mask``, …): wrong rank or size, a non-bool mask, an integer image.
"""
from __future__ import annotations

import hashlib
from collections import OrderedDict
from typing import Optional, Union

import numpy as np
import torch

from .. import checks

__all__ = ["mae", "rmse", "bias", "psnr", "ssim", "flip", "masked_mean", "luminance"]

_REC709 = (0.2126, 0.7152, 0.0722)


def luminance(rgb: torch.Tensor) -> torch.Tensor:
    """:math:`(..., 1, H, W)` Rec. 709 luminance of :math:`(..., 3, H, W)` linear RGB.

    Example:
        >>> luminance(torch.ones(1, 3, 1, 1)).item()
        1.0
    """
    if not isinstance(rgb, torch.Tensor) or rgb.dim() < 3 or rgb.shape[-3] != 3:
        raise ValueError(f"rgb: expected shape (..., 3, H, W), got {getattr(rgb, 'shape', type(rgb))}")
    w = torch.tensor(_REC709, dtype=rgb.dtype, device=rgb.device).view(3, 1, 1)
    return (rgb * w).sum(-3, keepdim=True)


def prepare(pred: torch.Tensor, target: Optional[torch.Tensor], mask: Optional[torch.Tensor]):
    """Check shapes/dtypes; return float ``pred``, ``target`` and the mask expanded to ``pred``'s shape
    (the input checks every metric of this package starts with)."""
    checks.check_shape(pred, ["B", "C", "H", "W"], "pred")
    if not pred.is_floating_point():
        raise TypeError(f"pred: expected a floating-point dtype, got {pred.dtype}")
    if target is not None:
        checks.check_shape(target, ["B", "C", "H", "W"], "target")
        if target.shape != pred.shape:
            raise ValueError(f"target: shape must match pred {tuple(pred.shape)}, got {tuple(target.shape)}")
        if not target.is_floating_point():
            raise TypeError(f"target: expected a floating-point dtype, got {target.dtype}")
        dtype = torch.promote_types(pred.dtype, target.dtype)
        pred, target = pred.to(dtype), target.to(dtype)
    if mask is None:
        mask = torch.ones_like(pred, dtype=torch.bool)
    else:
        checks.check_shape(mask, ["B", "1", "H", "W"], "mask")
        if mask.dtype != torch.bool:
            raise TypeError(f"mask: expected dtype torch.bool, got {mask.dtype}")
        if mask.shape[0] != pred.shape[0] or mask.shape[-2:] != pred.shape[-2:]:
            raise ValueError(f"mask: batch and image size must match pred {tuple(pred.shape)}, "
                             f"got {tuple(mask.shape)}")
        mask = mask.expand_as(pred)
    return pred, target, mask


_prepare = prepare


def masked_mean(x: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Mean of ``x`` over the pixels where ``mask`` is True (``nan`` when none is).

    .. math::  \bar x = \frac{\sum_p m_p\, x_p}{\sum_p m_p}

    Args:
        x: :math:`(B, C, H, W)` floating tensor.
        mask: :math:`(B, 1, H, W)` bool, or ``None`` for every pixel.

    Returns:
        0-d tensor.

    Example:
        >>> x = torch.tensor([1.0, 2.0, 3.0, 10.0]).reshape(1, 1, 2, 2)
        >>> masked_mean(x, x < 5)
        tensor(2.)
    """
    x, _, m = _prepare(x, None, mask)
    return x[m].mean()


def mae(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Mean absolute error over the mask.

    .. math::  \mathrm{MAE} = \frac{1}{|M|}\sum_{p \in M} |\hat y_p - y_p|

    Args:
        pred: :math:`(B, C, H, W)` estimate :math:`\hat y`.
        target: :math:`(B, C, H, W)` reference :math:`y`.
        mask: :math:`(B, 1, H, W)` bool valid pixels :math:`M` (``None``: all).

    Returns:
        0-d tensor (``nan`` for an empty mask).

    Example:
        >>> pred, target = torch.full((1, 1, 2, 2), 0.5), torch.ones(1, 1, 2, 2)
        >>> mae(pred, target)
        tensor(0.5000)
    """
    pred, target, m = _prepare(pred, target, mask)
    return (pred - target)[m].abs().mean()


def rmse(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Root-mean-square error over the mask.

    .. math::  \mathrm{RMSE} = \sqrt{\frac{1}{|M|}\sum_{p \in M} (\hat y_p - y_p)^2}

    Args:
        pred: :math:`(B, C, H, W)`.
        target: :math:`(B, C, H, W)`.
        mask: :math:`(B, 1, H, W)` bool (``None``: all pixels).

    Returns:
        0-d tensor (``nan`` for an empty mask).

    Example:
        >>> pred = torch.tensor([0.0, 0.0, 0.0, 1.0]).reshape(1, 1, 2, 2)
        >>> rmse(pred, torch.zeros(1, 1, 2, 2))
        tensor(0.5000)
    """
    pred, target, m = _prepare(pred, target, mask)
    return (pred - target)[m].square().mean().sqrt()


def bias(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Signed mean error over the mask (positive: ``pred`` too bright / too little occlusion for AO).

    .. math::  \mathrm{bias} = \frac{1}{|M|}\sum_{p \in M} (\hat y_p - y_p)

    Args:
        pred: :math:`(B, C, H, W)`.
        target: :math:`(B, C, H, W)`.
        mask: :math:`(B, 1, H, W)` bool (``None``: all pixels).

    Returns:
        0-d tensor (``nan`` for an empty mask).

    Example:
        >>> pred = torch.tensor([0.5, 1.0]).reshape(1, 1, 1, 2)
        >>> bias(pred, torch.full((1, 1, 1, 2), 0.75))
        tensor(0.)
    """
    pred, target, m = _prepare(pred, target, mask)
    return (pred - target)[m].mean()


def psnr(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None,
         max_val: float = 1.0) -> torch.Tensor:
    r"""Peak signal-to-noise ratio of the masked pixels (``kornia.metrics.psnr`` on them), in dB.

    .. math::  \mathrm{PSNR} = 10 \log_{10} \frac{\mathrm{max\_val}^2}{\frac{1}{|M|}\sum_{p\in M}(\hat y_p - y_p)^2}

    Identical images give ``inf``.

    Args:
        pred: :math:`(B, C, H, W)`.
        target: :math:`(B, C, H, W)`.
        mask: :math:`(B, 1, H, W)` bool (``None``: all pixels).
        max_val: the peak signal value (1 for AO).

    Returns:
        0-d tensor.

    Example:
        >>> pred = torch.tensor([0.1, 0.0, 0.0, 0.0]).reshape(1, 1, 2, 2)   # MSE = 0.0025
        >>> psnr(pred, torch.zeros(1, 1, 2, 2))
        tensor(26.0206)
    """
    import kornia
    if isinstance(max_val, bool) or not isinstance(max_val, (int, float)) or not max_val > 0:
        raise ValueError(f"max_val: must be a number > 0, got {max_val!r}")
    pred, target, m = _prepare(pred, target, mask)
    return kornia.metrics.psnr(pred[m], target[m], float(max_val))


def ssim(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None,
         window_size: int = 11, max_val: float = 1.0, return_map: bool = False
         ) -> Union[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
    r"""Mean structural similarity over the mask (the ``kornia.metrics.ssim`` map averaged on ``M``).

    .. math::
        \mathrm{SSIM}_p = \frac{(2\mu_{\hat y}\mu_y + c_1)(2\sigma_{\hat y y} + c_2)}
                               {(\mu_{\hat y}^2 + \mu_y^2 + c_1)(\sigma_{\hat y}^2 + \sigma_y^2 + c_2)},
        \qquad \overline{\mathrm{SSIM}} = \frac{1}{|M|}\sum_{p\in M}\mathrm{SSIM}_p

    with Gaussian windows of ``window_size`` (σ = 1.5), :math:`c_1 = (0.01\,\mathrm{max\_val})^2`,
    :math:`c_2 = (0.03\,\mathrm{max\_val})^2`. Windows near the mask border also see background pixels.

    Args:
        pred: :math:`(B, C, H, W)`.
        target: :math:`(B, C, H, W)`.
        mask: :math:`(B, 1, H, W)` bool (``None``: all pixels).
        window_size: odd Gaussian window size.
        max_val: dynamic range of the images (1 for AO).
        return_map: also return the :math:`(B, C, H, W)` SSIM map.

    Returns:
        0-d tensor, or ``(mean, map)``.

    Example:
        >>> x = torch.rand(1, 1, 16, 16, generator=torch.Generator().manual_seed(0))
        >>> ssim(x, x)
        tensor(1.)
    """
    import kornia
    if isinstance(window_size, bool) or not isinstance(window_size, int) or window_size < 1 or window_size % 2 == 0:
        raise ValueError(f"window_size: must be an odd positive integer, got {window_size!r}")
    if isinstance(max_val, bool) or not isinstance(max_val, (int, float)) or not max_val > 0:
        raise ValueError(f"max_val: must be a number > 0, got {max_val!r}")
    pred, target, m = _prepare(pred, target, mask)
    smap = kornia.metrics.ssim(pred, target, window_size, max_val=float(max_val))     # (B, C, H, W)
    mean = smap[m].mean()
    return (mean, smap) if return_map else mean


#: ꟻLIP maps of the last few image pairs, by a digest of the images as ``flip_evaluator`` receives them (and the
#: settings): a report scores a pair and then shows its map, and one 640×360 map costs ~0.15 s
FLIP_MAPS_KEPT = 8
_FLIP_MAPS: "OrderedDict[tuple, np.ndarray]" = OrderedDict()


def flip(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None, *,
         ppd: Optional[float] = None, inputs_srgb: bool = True, return_map: bool = False
         ) -> Union[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
    r"""Mean LDR-ꟻLIP error (Andersson et al. 2020) over the mask, via ``flip_evaluator.evaluate``.

    .. math::  \overline{\text{ꟻLIP}} = \frac{1}{|M|}\sum_{p\in M} \text{ꟻLIP}_p(\hat y, y) \in [0, 1]

    ꟻLIP compares the images as a viewer sees them (colour difference in a perceptual space after
    contrast-sensitivity filtering, plus a feature/edge term). One-channel images (an AO map) are replicated to
    grey RGB; three-channel images are used as they are. Values are clamped to [0, 1] (LDR). With
    ``inputs_srgb=True`` (default) the values are taken as display-encoded, i.e. the AO map is shown as the grey
    levels written to the report's PNGs; pass ``False`` for linear values. The maps of the last
    :data:`FLIP_MAPS_KEPT` image pairs are kept (by a digest of their bytes), so scoring a pair and then drawing
    its map runs ``flip_evaluator`` once.

    Args:
        pred: :math:`(B, C, H, W)` with ``C`` 1 or 3 (the test image).
        target: :math:`(B, C, H, W)` (the reference image).
        mask: :math:`(B, 1, H, W)` bool (``None``: all pixels); the map is computed on the whole image.
        ppd: pixels per degree of visual angle (``None``: ꟻLIP's default, 67).
        inputs_srgb: whether values are sRGB-encoded display values.
        return_map: also return the :math:`(B, 1, H, W)` error map.

    Returns:
        0-d tensor, or ``(mean, map)``.

    Example:
        >>> target = torch.full((1, 1, 8, 8), 0.5)
        >>> flip(target, target)
        tensor(0.)
        >>> bool(flip(torch.zeros(1, 1, 8, 8), target) > 0.1)
        True
    """
    import flip_evaluator
    pred, target, m = _prepare(pred, target, mask)
    if pred.shape[1] not in (1, 3):
        raise ValueError(f"pred: flip needs 1 or 3 channels, got shape {tuple(pred.shape)}")
    if ppd is not None and (isinstance(ppd, bool) or not isinstance(ppd, (int, float)) or not ppd > 0):
        raise ValueError(f"ppd: must be a number > 0, got {ppd!r}")   # flip_evaluator would sys.exit
    params = {} if ppd is None else {"ppd": float(ppd)}

    def hwc(x: torch.Tensor) -> np.ndarray:                                     # (C, H, W) -> (H, W, 3)
        a = torch.nan_to_num(x.detach(), nan=0.0).clamp(0, 1).permute(1, 2, 0).cpu().numpy()
        return np.ascontiguousarray(np.repeat(a, 3, -1) if a.shape[-1] == 1 else a, dtype=np.float32)

    maps = []
    for b in range(pred.shape[0]):
        ref, test = hwc(target[b]), hwc(pred[b])
        key = (hashlib.blake2b(ref.tobytes() + test.tobytes(), digest_size=16).hexdigest(), ref.shape,
               bool(inputs_srgb), repr(params))
        err = _FLIP_MAPS.pop(key, None)
        if err is None:
            err, _, _ = flip_evaluator.evaluate(ref, test, "LDR", inputsRGB=bool(inputs_srgb), applyMagma=False,
                                                computeMeanError=False, parameters=params)
            err = np.asarray(err, dtype=np.float32)[..., 0].copy()
        _FLIP_MAPS[key] = err                                       # most recent last
        while len(_FLIP_MAPS) > FLIP_MAPS_KEPT:
            _FLIP_MAPS.popitem(last=False)
        maps.append(torch.from_numpy(err.copy()))
    fmap = torch.stack(maps)[:, None].to(pred.device)                           # (B, 1, H, W)
    mean = fmap.to(pred.dtype)[m[:, :1]].mean()
    return (mean, fmap) if return_map else mean
