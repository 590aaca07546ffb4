r"""The h/w prediction of punch-through (progressive-tracing article 手法 2, "method 2"): a march with step ``h``
and a uniform phase finds a slab of chord ``w`` with probability ``min(1, w/h)`` (:func:`detection_prediction`);
per frame for a fixed step (:func:`predicted_punch_through`) and for the progressive method, whose step shrinks
with its stored ``t'`` and which keeps what it found (:func:`survivor_punch_through`). The chord comes from
:func:`ssbench.metrics.implicit.chord`.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence, Union

import torch

from .. import checks

__all__ = ["detection_prediction", "predicted_punch_through", "survivor_punch_through"]


def detection_prediction(h: Union[float, torch.Tensor], chord: Union[float, torch.Tensor]) -> torch.Tensor:
    r"""Probability ``min(1, w/h)`` that a jittered uniform step ``h`` finds a slab of chord ``w`` in one frame.

    A march samples ``t = s₀ + k·h`` with ``s₀`` uniform over one step (the article's ``s₀ = s₁R``): one
    sample per step length, so a slab ``[c, c + w]`` along the ray holds a sample with probability
    ``min(1, w/h)`` (progressive-tracing article 手法 2); the expected number of frames to find it is ≈ ``h/w``.
    Broadcasts ``h`` (> 0) against ``chord`` (w ≤ 0 gives 0).

    Example:
        >>> [round(p, 12) for p in detection_prediction(0.25, [0.02, 0.1, 0.5, 0.0]).tolist()]
        [0.08, 0.4, 1.0, 0.0]
    """
    h = torch.as_tensor(h, dtype=torch.float64)
    w = torch.as_tensor(chord, dtype=torch.float64)
    if not bool(torch.isfinite(h).all() & (h > 0).all()):
        raise ValueError("h: every step length must be finite and > 0")
    if not bool(torch.isfinite(w).all()):
        raise ValueError("chord: must be finite (use chord(truth), 0 where the truth misses)")
    return (w.clamp(min=0) / h).clamp(max=1.0)


def predicted_punch_through(h_per_frame: Union[float, torch.Tensor, Sequence], chord: torch.Tensor,
                            frames: Optional[int] = None, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Predicted punch-through rate after each frame: ``mean_pixels Π_{k ≤ K} (1 − min(1, w/h_k))``.

    Args:
        h_per_frame: the step per frame: a number or 0-d tensor (every frame), a :math:`(F,)` sequence/tensor
            (one per frame), one :math:`(B, 1, H, W)` map (every frame) or :math:`(F, B, 1, H, W)` maps.
        chord: :math:`(B, 1, H, W)` slab chords ``w`` (:func:`chord`).
        frames: number of frames ``K``; default ``F``; beyond ``F`` the last step repeats.
        mask: pixels to average over; default ``chord > 0`` (the truth-hit pixels).

    Returns:
        :math:`(K,)` float64, entry ``k`` the expected share of ``mask`` pixels still unfound after frame ``k+1``.

    Example:
        >>> w = torch.tensor([0.02, 0.125], dtype=torch.float64).view(1, 1, 1, 2)
        >>> [round(p, 12) for p in predicted_punch_through(0.25, w, frames=2).tolist()]  # ((1-.08)^k + .5^k) / 2
        [0.71, 0.5482]
    """
    checks.check_shape(chord, ["B", "1", "H", "W"], "chord")
    h = torch.as_tensor(h_per_frame if not isinstance(h_per_frame, (list, tuple)) else
                        torch.stack([torch.as_tensor(x, dtype=torch.float64) for x in h_per_frame]),
                        dtype=torch.float64)
    if h.dim() in (1, chord.dim() + 1):
        per = list(h)
    elif h.dim() in (0, chord.dim()):
        per = [h]
    else:
        raise ValueError(f"h_per_frame: expected a number, (F,), (B, 1, H, W) or (F, B, 1, H, W), "
                         f"got shape {tuple(h.shape)}")
    if frames is None:
        frames = len(per) if h.dim() in (1, chord.dim() + 1) else None
    if isinstance(frames, bool) or not isinstance(frames, int) or frames <= 0:
        raise ValueError(f"frames: must be a positive integer (required for one step for all frames), "
                         f"got {frames!r}")
    m = chord > 0 if mask is None else mask.bool()
    if int(m.sum()) == 0:
        return torch.full((frames,), math.nan, dtype=torch.float64)
    alive = torch.ones_like(chord, dtype=torch.float64)
    out = []
    for k in range(frames):
        alive = alive * (1.0 - detection_prediction(per[min(k, len(per) - 1)], chord))
        out.append(alive.expand_as(chord)[m].mean())
    return torch.stack(out)


def survivor_punch_through(h_per_frame: torch.Tensor, chord: torch.Tensor, found: torch.Tensor,
                           mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    r"""Survivor (hazard) form of the h/w prediction: each frame, only pixels the run has not found yet are at risk.

    :func:`predicted_punch_through` multiplies miss probabilities over all frames for every pixel, so a pixel the
    run found at frame 3 still counts as "maybe unfound" at frame 40: it over-predicts late frames (progressive-tracing article's
    progressive method keeps a found root's ``t'``; the pixel stays found). Here the at-risk set of frame
    :math:`k` is the run's own set of unfound pixels after frame :math:`k-1` (all pixels before frame 1), and the
    hazard of staying unfound is the one-frame miss probability :math:`1 - \min(1, w/h_k)`:

    .. math::  \hat P_k = \frac{1}{|M|}\sum_{p \in M} [p \notin F_{k-1}]\,\bigl(1 - \min(1, w_p/h_{k,p})\bigr)

    It predicts the next frame from the state the run is in (a one-step survival model), so it tracks the
    measured curve where the product form drifts; the product form remains the a-priori prediction.

    Args:
        h_per_frame: :math:`(F, B, 1, H, W)` the step of each frame (``t'/N`` before the frame).
        chord: :math:`(B, 1, H, W)` slab chords ``w`` (:func:`chord`).
        found: :math:`(F, B, 1, H, W)` bool, the run found the pixel's first root after frame ``k``.
        mask: pixels to average over; default ``chord > 0``.

    Returns:
        :math:`(F,)` float64, entry ``k`` the predicted share of ``mask`` pixels unfound after frame ``k+1``.

    Example:
        >>> w = torch.tensor([0.02, 0.125], dtype=torch.float64).view(1, 1, 1, 2)
        >>> h = torch.full((2, 1, 1, 1, 2), 0.25, dtype=torch.float64)
        >>> found = torch.tensor([[False, True], [False, True]]).view(2, 1, 1, 1, 2)   # pixel 1 found at frame 1
        >>> [round(p, 12) for p in survivor_punch_through(h, w, found).tolist()]      # (.92 + .5)/2, (.92 + 0)/2
        [0.71, 0.46]
    """
    checks.check_shape(chord, ["B", "1", "H", "W"], "chord")
    if h_per_frame.dim() != chord.dim() + 1 or found.shape != h_per_frame.shape:
        raise ValueError(f"h_per_frame, found: expected (F, B, 1, H, W) each, got {tuple(h_per_frame.shape)} and "
                         f"{tuple(found.shape)}")
    m = chord > 0 if mask is None else mask.bool()
    if int(m.sum()) == 0:
        return torch.full((h_per_frame.shape[0],), math.nan, dtype=torch.float64)
    out, at_risk = [], torch.ones_like(chord, dtype=torch.bool)
    for hk, fk in zip(h_per_frame, found):
        miss = 1.0 - detection_prediction(hk, chord)
        out.append(torch.where(at_risk, miss, torch.zeros_like(miss)).expand_as(chord)[m].mean())
        at_risk = ~fk.bool()
    return torch.stack(out)
