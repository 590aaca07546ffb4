"""Small 3-vector helpers on plain tuples (camera set-up, scene placement) and the component split of tensors
that :mod:`ssbench.camera` uses for every conversion.

Example:
    >>> cross((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    (0.0, 0.0, 1.0)
    >>> vec3([1, 2, 3], "eye")
    (1.0, 2.0, 3.0)
"""
from __future__ import annotations

import math
from typing import Sequence

import torch

__all__ = ["Vec3", "vec3", "sub", "cross", "norm", "normalize", "split_components"]

Vec3 = tuple[float, float, float]


def vec3(value: Sequence[float], name: str) -> Vec3:
    """``value`` as three finite floats; ``ValueError`` naming ``name`` otherwise."""
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected three numbers, got {value!r}") from None
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise ValueError(f"{name}: expected three finite numbers, got {value!r}")
    return out  # type: ignore[return-value]


def sub(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def cross(a: Vec3, b: Vec3) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def norm(a: Vec3) -> float:
    return math.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)


def normalize(a: Vec3) -> Vec3:
    n = norm(a)
    return (a[0] / n, a[1] / n, a[2] / n)


def split_components(x: torch.Tensor, dim: int, n: int, name: str) -> list[torch.Tensor]:
    """The ``n`` components of ``x`` along ``dim``; ``ValueError`` naming ``name`` when there are not ``n``."""
    if x.shape[dim] != n:
        raise ValueError(f"{name}: dimension {dim} must have {n} components, got shape {tuple(x.shape)}")
    return list(x.unbind(dim))
