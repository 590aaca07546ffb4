"""Argument checks shared by the SSR metric modules (:mod:`ssbench.metrics.ssr` and its parts).

Duck-typed ``SSRResult`` / ``ReflectionReference`` fields, bool masks, the ``k_px`` tolerance and class maps;
bad input raises ``ValueError``/``TypeError`` naming the argument.
"""
from __future__ import annotations

import math
from typing import Any, Optional

import torch

from .. import checks

RESULT_FIELDS = {"hit": 1, "hit_pixel": 2, "hit_view": 3}
TRUTH_FIELDS = {"valid": 1, "hit": 1, "hit_view": 3, "hit_pixel": 2, "on_screen": 1, "visible": 1, "back_face": 1}


def field_of(obj: Any, name: str, arg: str, channels: int, like: Optional[torch.Tensor] = None) -> torch.Tensor:
    t = getattr(obj, name, None)
    if not isinstance(t, torch.Tensor):
        raise TypeError(f"{arg}.{name}: expected a torch.Tensor, got {type(t).__name__}")
    checks.check_shape(t, ["B", str(channels), "H", "W"], f"{arg}.{name}")
    if like is not None and (t.shape[0] != like.shape[0] or t.shape[-2:] != like.shape[-2:]):
        raise ValueError(f"{arg}.{name}: batch and image size must match result.hit {tuple(like.shape)}, "
                         f"got {tuple(t.shape)}")
    return t


def mask_arg(m: Optional[torch.Tensor], like: torch.Tensor, name: str) -> Optional[torch.Tensor]:
    if m is None:
        return None
    if not isinstance(m, torch.Tensor):
        raise TypeError(f"{name}: expected a torch.Tensor, got {type(m).__name__}")
    checks.check_shape(m, ["B", "1", "H", "W"], name)
    if m.dtype != torch.bool:
        raise TypeError(f"{name}: expected dtype torch.bool, got {m.dtype}")
    if m.shape[0] != like.shape[0] or m.shape[-2:] != like.shape[-2:]:
        raise ValueError(f"{name}: batch and image size must match {tuple(like.shape)}, got {tuple(m.shape)}")
    return m


def check_pair(result: Any, truth: Any) -> torch.Tensor:
    hit = field_of(result, "hit", "result", 1)
    for n, c in RESULT_FIELDS.items():
        field_of(result, n, "result", c, hit)
    for n, c in TRUTH_FIELDS.items():
        field_of(truth, n, "truth", c, hit)
    return hit


def k_px_arg(k_px) -> float:
    if isinstance(k_px, bool) or not isinstance(k_px, (int, float)) or not (math.isfinite(k_px) and k_px > 0):
        raise ValueError(f"k_px: must be a finite number > 0, got {k_px!r}")
    return float(k_px)


def check_classes(classes: torch.Tensor) -> None:
    checks.check_tensor(classes, "classes")
    checks.check_shape(classes, ["B", "1", "H", "W"], "classes")
    if classes.is_floating_point() or classes.dtype == torch.bool:
        raise TypeError(f"classes: expected an integer dtype, got {classes.dtype}")
