"""Artifact metrics for ambient occlusion: one number per complaint users file against SSAO-style passes.

* :func:`halo` — error in a band around depth discontinuities vs elsewhere (halos behind foreground objects),
  split by sign into ``dark`` (false occlusion) and ``missing`` occlusion;
* :func:`flat_bias` — occlusion where the ground truth sees none (self-occlusion, Crytek's grey floors);
* :func:`tile_energy` — spectral energy at the noise-tile frequency and its harmonics (the tile pattern itself;
  banding, the structured error, is :func:`ssbench.metrics.ao_banding.banding`);
* :func:`noise` — variance of the high-frequency residual (before vs after a blur);
  (these two and :func:`power_spectrum`, :func:`highpass` live in :mod:`ssbench.metrics.ao_noise`)
* :func:`over_darkening` — mean method occlusion over mean ground-truth occlusion.

AO maps are :math:`(B, 1, H, W)` visibilities in [0, 1] (1 = unoccluded); *occlusion* is ``1 − ao``. Masks
are :math:`(B, 1, H, W)` bool (valid pixels). Statistics pool all masked pixels of the batch; a mean over an
empty region is ``nan``. Bad input raises ``ValueError``/``TypeError`` naming the argument.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import torch
import torch.nn.functional as F

from .. import checks
from .ao_noise import highpass, noise, power_spectrum, tile_energy
from .image import prepare

__all__ = ["halo", "HaloResult", "depth_edges", "edge_band", "flat_bias", "tile_energy", "power_spectrum", "noise", "highpass",
           "over_darkening"]


class HaloResult(NamedTuple):
    """Output of :func:`halo`: 0-d tensors and the band used."""

    band: torch.Tensor          #: MAE inside the band around depth discontinuities
    elsewhere: torch.Tensor     #: MAE on the other valid pixels
    ratio: torch.Tensor         #: band / elsewhere (> 1: the error concentrates at edges)
    band_bias: torch.Tensor     #: signed mean error inside the band (> 0: too bright, a "halo of non-occlusion")
    band_mask: torch.Tensor     #: (B, 1, H, W) bool band (already intersected with the valid mask)
    dark: torch.Tensor          #: mean false occlusion in the band, max(a − â, 0) (a dark halo); absolute
    missing: torch.Tensor       #: mean missing occlusion in the band, max(â − a, 0) (a bright halo); absolute


def depth_edges(view_z: torch.Tensor, mask: Optional[torch.Tensor] = None, threshold: float = 0.1,
                silhouettes: bool = False) -> torch.Tensor:
    r"""Pixels on a depth discontinuity: a 4-neighbour whose view depth differs by more than ``threshold``.

    .. math::  e_p = \bigvee_{q \in N_4(p)} \frac{|z_p - z_q|}{\min(|z_p|, |z_q|)} > \tau

    Both pixels of a jumping pair are marked. With ``silhouettes=False`` (default) only pairs of two valid
    pixels count (an object against the empty background has no surface behind it to haloe); with ``True``
    a valid pixel next to background is an edge too. Note the relative test also fires on a plane seen at a
    grazing angle once one pixel spans more than ``threshold`` of the depth.

    Args:
        view_z: :math:`(B, 1, H, W)` view-space z (negative in front of the camera).
        mask: :math:`(B, 1, H, W)` bool valid pixels (``None``: all).
        threshold: relative depth jump :math:`\tau`.
        silhouettes: also mark valid pixels bordering background.

    Returns:
        :math:`(B, 1, H, W)` bool, False off the mask.

    Example:
        >>> z = torch.full((1, 1, 4, 4), -1.0); z[..., 2:] = -2.0          # a step between columns 1 and 2
        >>> depth_edges(z)[0, 0].int()
        tensor([[0, 1, 1, 0],
                [0, 1, 1, 0],
                [0, 1, 1, 0],
                [0, 1, 1, 0]], dtype=torch.int32)
    """
    checks.check_shape(view_z, ["B", "1", "H", "W"], "view_z")
    z, _, m = prepare(view_z, None, mask)
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) or not threshold > 0:
        raise ValueError(f"threshold: must be a number > 0, got {threshold!r}")
    a = z.abs()
    edge = torch.zeros_like(m)
    for dim in (-1, -2):                                          # horizontal, then vertical neighbour pairs
        n = z.shape[dim]
        if n < 2:
            continue
        z0, z1 = z.narrow(dim, 0, n - 1), z.narrow(dim, 1, n - 1)
        a0, a1 = a.narrow(dim, 0, n - 1), a.narrow(dim, 1, n - 1)
        m0, m1 = m.narrow(dim, 0, n - 1), m.narrow(dim, 1, n - 1)
        jump = (z0 - z1).abs() > threshold * torch.minimum(a0, a1).clamp_min(torch.finfo(z.dtype).tiny)
        both = m0 & m1
        pair = (jump & both) | ((m0 ^ m1) if silhouettes else torch.zeros_like(both))   # (B, 1, H', W')
        pad = [0, 1, 0, 0] if dim == -1 else [0, 0, 0, 1]
        pair_f = pair.to(torch.uint8)
        edge |= F.pad(pair_f, pad).bool() | F.pad(pair_f, [pad[1], pad[0], pad[3], pad[2]]).bool()
    return edge & m


def edge_band(view_z: torch.Tensor, mask: torch.Tensor, band: int, threshold: float = 0.1,
              silhouettes: bool = False) -> torch.Tensor:
    """:func:`depth_edges` dilated to every pixel within Chebyshev distance ``band`` (a :math:`(2k+1)^2`
    ``max_pool2d``): the band :func:`halo` scores and :func:`~ssbench.metrics.banding` leaves out.
    :math:`(B, 1, H, W)` bool."""
    edges = depth_edges(view_z, mask, threshold, silhouettes)
    return F.max_pool2d(edges.to(torch.float32), 2 * band + 1, stride=1, padding=band) > 0 if band else edges


def halo(pred: torch.Tensor, target: torch.Tensor, view_z: torch.Tensor, mask: Optional[torch.Tensor] = None,
         band: int = 4, threshold: float = 0.1, silhouettes: bool = False) -> HaloResult:
    r"""Error near depth discontinuities vs elsewhere: how much a method's error is a halo.

    The band :math:`D` is the set of valid pixels within Chebyshev distance ``band`` of a depth edge
    (:func:`depth_edges`, dilated by a :math:`(2k+1)^2` ``max_pool2d``); :math:`E = M \setminus D`.

    .. math::
        \mathrm{band} = \frac{1}{|D|}\sum_{p\in D}|\hat a_p - a_p|, \quad
        \mathrm{elsewhere} = \frac{1}{|E|}\sum_{p\in E}|\hat a_p - a_p|, \quad
        \mathrm{ratio} = \frac{\mathrm{band}}{\mathrm{elsewhere}}

    plus ``band_bias`` :math:`= \frac{1}{|D|}\sum_{p\in D}(\hat a_p - a_p)` (positive: a bright halo of
    non-occlusion, the classic complaint), and the band error split by sign, in absolute AO units (not a
    ratio, so lowering the error elsewhere cannot move them):

    .. math::
        \mathrm{dark} = \frac{1}{|D|}\sum_{p\in D}\max(a_p - \hat a_p, 0), \qquad
        \mathrm{missing} = \frac{1}{|D|}\sum_{p\in D}\max(\hat a_p - a_p, 0)

    ``dark`` is false occlusion next to depth edges (the dark halo a missing or loose range check paints
    behind foreground objects); ``missing`` is occlusion the method fails to find there (a bright halo).
    ``dark + missing = band``, and ``missing − dark = band_bias``. ``ratio`` is ``inf`` when the error is all
    in the band, ``nan`` when a region is empty or both errors are 0.

    Args:
        pred: :math:`(B, 1, H, W)` method AO :math:`\hat a`.
        target: :math:`(B, 1, H, W)` ground-truth AO :math:`a`.
        view_z: :math:`(B, 1, H, W)` view z used to find the discontinuities.
        mask: :math:`(B, 1, H, W)` bool valid pixels :math:`M` (``None``: all).
        band: half-width :math:`k` of the band in pixels (0: the edge pixels only).
        threshold: relative depth jump of :func:`depth_edges`.
        silhouettes: count edges against background too (see :func:`depth_edges`).

    Returns:
        :class:`HaloResult` ``(band, elsewhere, ratio, band_bias, band_mask, dark, missing)``.

    Example:
        >>> z = torch.full((1, 1, 8, 8), -1.0); z[..., 4:] = -3.0
        >>> target = torch.full((1, 1, 8, 8), 0.8)
        >>> pred = target.clone(); pred[..., 3:5] = 1.0                   # bright seam at the step
        >>> r = halo(pred, target, z, band=1)
        >>> round(float(r.band), 4), float(r.elsewhere), round(float(r.band_bias), 4)
        (0.1, 0.0, 0.1)
        >>> round(float(r.dark), 4), round(float(r.missing), 4)             # a bright seam: occlusion missing
        (0.0, 0.1)
    """
    checks.check_shape(pred, ["B", "1", "H", "W"], "pred")
    if isinstance(band, bool) or not isinstance(band, int) or band < 0:
        raise ValueError(f"band: must be a non-negative integer, got {band!r}")
    checks.check_same_size(pred, view_z, "pred", "view_z")
    pred, target, m = prepare(pred, target, mask)
    near = edge_band(view_z, m, band, threshold, silhouettes)
    d = near & m
    e = m & ~near
    err = pred - target
    b, el = err[d].abs().mean(), err[e].abs().mean()
    return HaloResult(b, el, b / el, err[d].mean(), d, (-err[d]).clamp_min(0).mean(), err[d].clamp_min(0).mean())


def flat_bias(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None,
              eps: float = 1e-3) -> torch.Tensor:
    r"""Mean occlusion a method adds where the ground truth has none (self-occlusion / grey bias).

    .. math::  U = \{p \in M : a_p \ge 1 - \epsilon\}, \qquad
               \mathrm{flat\_bias} = \frac{1}{|U|}\sum_{p\in U}(1 - \hat a_p)

    :math:`U` is where no occluder lies within the radius (open floors, convex faces). A perfect method gives 0;
    Crytek's sphere kernel gives ≈ 0.5 on an open plane. ``nan`` when :math:`U` is empty.

    Args:
        pred: :math:`(B, 1, H, W)` method AO :math:`\hat a`.
        target: :math:`(B, 1, H, W)` ground-truth AO :math:`a`.
        mask: :math:`(B, 1, H, W)` bool (``None``: all).
        eps: tolerance :math:`\epsilon` on "the ground truth is 1".

    Returns:
        0-d tensor.

    Example:
        >>> target = torch.tensor([1.0, 1.0, 0.3]).reshape(1, 1, 1, 3)
        >>> pred = torch.tensor([0.5, 0.7, 0.3]).reshape(1, 1, 1, 3)
        >>> flat_bias(pred, target)
        tensor(0.4000)
    """
    if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not 0 <= eps < 1:
        raise ValueError(f"eps: must be a number in [0, 1), got {eps!r}")
    pred, target, m = prepare(pred, target, mask)
    u = m & (target >= 1 - eps)
    return (1 - pred)[u].mean()


def over_darkening(pred: torch.Tensor, target: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Ratio of the method's mean occlusion to the ground truth's over the mask.

    .. math::  \mathrm{over\_darkening} = \frac{\sum_{p\in M}(1 - \hat a_p)}{\sum_{p\in M}(1 - a_p)}

    1 is right on average, > 1 too dark, < 1 too bright. ``inf``/``nan`` when the ground truth has no
    occlusion at all.

    Args:
        pred: :math:`(B, 1, H, W)` method AO :math:`\hat a`.
        target: :math:`(B, 1, H, W)` ground-truth AO :math:`a`.
        mask: :math:`(B, 1, H, W)` bool (``None``: all).

    Returns:
        0-d tensor.

    Example:
        >>> target = torch.tensor([0.6, 0.9, 1.0]).reshape(1, 1, 1, 3)
        >>> over_darkening(1 - 2 * (1 - target), target)
        tensor(2.)
    """
    pred, target, m = prepare(pred, target, mask)
    return (1 - pred)[m].sum() / (1 - target)[m].sum()
