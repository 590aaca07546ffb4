"""Temporal metrics: what a sequence of frames of one effect does from frame to frame.

* :func:`flicker` — the per-pixel temporal standard deviation, averaged over the pixels valid in every frame:
  a static scene whose noise pattern moves (a new rotation texture, an advancing Hilbert index) or whose
  camera jitters by a sub-pixel offset shows it as flicker/"blinking" (the complaint of three.js PR #33663
  and Godot PR #101961 about moving AO noise).

* :func:`ghosting` — on a moving camera, the error the temporal resolve *adds* where it kept history: mean
  |accumulated − truth| minus mean |raw − truth| over the pixels whose history was trusted (optionally only near
  depth edges, where trails show: :func:`ssbench.metrics.ao.edge_band`). Averaging noise makes it negative on a still scene; stale history behind
  moving edges and view-dependent AO that lags make it positive.

Frames are :math:`(T, B, 1, H, W)` (or :math:`(T, 1, H, W)` for one image per frame); masks likewise, bool.
"""
from __future__ import annotations

from typing import Optional

import torch

from .. import checks

__all__ = ["flicker", "temporal_std", "ghosting"]


def _frames(frames: torch.Tensor, mask: Optional[torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
    if not isinstance(frames, torch.Tensor) or not frames.is_floating_point():
        raise TypeError(f"frames: expected a floating-point tensor, got {type(frames).__name__}")
    if frames.dim() == 4:
        frames = frames.unsqueeze(1)
        mask = mask.unsqueeze(1) if isinstance(mask, torch.Tensor) and mask.dim() == 4 else mask
    checks.check_shape(frames, ["T", "B", "1", "H", "W"], "frames")
    if frames.shape[0] < 2:
        raise ValueError(f"frames: need at least 2 frames for a temporal deviation, got {frames.shape[0]}")
    if mask is None:
        return frames, torch.ones_like(frames, dtype=torch.bool)
    if not isinstance(mask, torch.Tensor) or mask.dtype != torch.bool:
        raise TypeError("mask: expected a torch.bool tensor")
    if mask.shape != frames.shape:
        raise ValueError(f"mask: shape must match frames {tuple(frames.shape)}, got {tuple(mask.shape)}")
    return frames, mask


def temporal_std(frames: torch.Tensor, mask: Optional[torch.Tensor] = None) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Per-pixel temporal standard deviation (unbiased, :math:`T - 1` in the denominator) and where it is
    defined (pixels valid in every frame).

    Returns:
        ``(std, valid)``, each :math:`(B, 1, H, W)`; ``std`` is 0 off ``valid``.
    """
    x, m = _frames(frames, mask)
    valid = m.all(0)
    std = x.double().std(0, unbiased=True)
    return torch.where(valid, std, torch.zeros_like(std)).to(x.dtype), valid


def flicker(frames: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Mean per-pixel temporal standard deviation over the pixels valid in every frame:

    .. math::  \mathrm{flicker} = \frac{1}{|V|}\sum_{p \in V} \sqrt{\frac{1}{T-1}\sum_t (x_{t,p} - \bar x_p)^2},
               \qquad V = \{p : m_{t,p}\ \forall t\}

    In AO units: 0 for a sequence that does not change; a pixel toggling between 0 and 1 every other frame
    gives ≈ 0.5. ``nan`` when no pixel is valid in every frame.

    Args:
        frames: :math:`(T, B, 1, H, W)` or :math:`(T, 1, H, W)`, :math:`T \ge 2`.
        mask: the same shape, bool (``None``: all valid).

    Returns:
        0-d tensor.

    Example:
        >>> still = torch.full((4, 1, 2, 2), 0.7)
        >>> float(flicker(still))
        0.0
        >>> blink = torch.tensor([0.0, 1.0, 0.0, 1.0]).view(4, 1, 1, 1).expand(4, 1, 2, 2)
        >>> round(float(flicker(blink)), 4)                          # sqrt(1/3): the unbiased std of 0,1,0,1
        0.5774
    """
    std, valid = temporal_std(frames, mask)
    if not bool(valid.any()):
        return torch.tensor(float("nan"), dtype=std.dtype)
    return std[valid].mean()


def ghosting(accumulated: torch.Tensor, raw: torch.Tensor, truth: torch.Tensor, trusted: torch.Tensor,
             where: Optional[torch.Tensor] = None) -> float:
    r"""The error a temporal resolve adds where it used history (see the module docstring):

    .. math::  \mathrm{ghosting} = \overline{|a_{t,p} - g_{t,p}|} - \overline{|r_{t,p} - g_{t,p}|},
               \quad (t, p) : \text{history trusted at } p \text{ in frame } t \ (\text{and } p \in \text{where}_t)

    All arguments :math:`(T, B, 1, H, W)`; ``trusted`` and ``where`` bool. NaN when no pixel qualifies.

    Example:
        >>> g = torch.zeros(2, 1, 1, 1, 2, dtype=torch.float64); ok = torch.ones(2, 1, 1, 1, 2, dtype=torch.bool)
        >>> ghosting(g + 0.3, g + 0.1, g, ok)                          # the resolve left 0.2 more error
        0.2
    """
    sel = trusted.bool() if where is None else trusted.bool() & where.bool()
    if not bool(sel.any()):
        return float("nan")
    a = (accumulated.double() - truth.double()).abs()[sel].mean()
    r = (raw.double() - truth.double()).abs()[sel].mean()
    return round(float(a - r), 12)

