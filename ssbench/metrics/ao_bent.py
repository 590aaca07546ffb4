"""Bent-normal error: the angle between a pass's bent normal (GTAO, Jimenez et al. 2016, Algorithm 2) and the
ray-traced one (:func:`ssbench.reference.bent_normal.bent_normals`), in degrees, with the truth's own error bar
beside it so a small error can be told from the truth's noise."""
from __future__ import annotations

import math
from typing import Optional

import torch

from .. import checks
from ..rays import vector_norm

__all__ = ["bent_normal_angle", "bent_normal_error"]


def bent_normal_angle(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """:math:`(B, 1, H, W)` angle in degrees between two :math:`(B, 3, H, W)` fields of directions (normalised
    here; a zero vector gives NaN).

    Example:
        >>> x, y = torch.tensor([1.0, 0, 0]).view(1, 3, 1, 1), torch.tensor([0, 2.0, 0]).view(1, 3, 1, 1)
        >>> bent_normal_angle(x, y).item(), bent_normal_angle(x, x).item()
        (90.0, 0.0)
    """
    checks.check_shape(pred, ["B", "3", "H", "W"], "pred")
    checks.check_same_size(pred, truth, "pred", "truth")
    a, b = pred.double(), truth.double()
    na, nb = vector_norm(a), vector_norm(b)
    cos = (a * b).sum(1, keepdim=True) / (na * nb)
    cos = torch.where((na > 0) & (nb > 0), cos.clamp(-1.0, 1.0), torch.full_like(cos, math.nan))
    return torch.rad2deg(torch.acos(cos))


def bent_normal_error(pred: torch.Tensor, truth: torch.Tensor, mask: torch.Tensor,
                      truth_stderr_deg: Optional[torch.Tensor] = None) -> dict:
    """``{"mean_deg", "median_deg", "p95_deg", "pixels", "truth_stderr_deg"}`` of the angle over ``mask`` (pixels
    whose truth is defined: a finite ``truth_stderr_deg`` when given); ``truth_stderr_deg`` in the result is the
    truth's mean angular standard error over the same pixels (NaN when not given)."""
    ang = bent_normal_angle(pred, truth)
    m = mask.bool() & torch.isfinite(ang)
    if truth_stderr_deg is not None:
        m = m & torch.isfinite(truth_stderr_deg)
    v = ang[m]
    if v.numel() == 0:
        raise ValueError("mask: no pixel with a defined bent normal")
    se = float(truth_stderr_deg[m].double().mean()) if truth_stderr_deg is not None else math.nan
    return {"mean_deg": float(v.mean()), "median_deg": float(v.median()), "p95_deg": float(torch.quantile(v, 0.95)),
            "pixels": int(v.numel()), "truth_stderr_deg": se}
