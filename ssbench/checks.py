"""Input checks that name the argument and the dimension (kornia style).

Checks are on by default. Switch them off for speed with :func:`disable_checks`, the context manager
:func:`checks_disabled`, or the environment variable ``SSBENCH_CHECKS=0``. Error messages are formatted only
when a check fails, so an enabled check costs a few attribute reads.
"""
from __future__ import annotations

import contextlib
import os
from typing import Iterator, Sequence

import torch

_ENABLED = os.environ.get("SSBENCH_CHECKS", "1").strip().lower() not in ("0", "false", "off", "no")


def checks_enabled() -> bool:
    """Whether shape/value checks run."""
    return _ENABLED


def enable_checks(flag: bool = True) -> None:
    """Turn input checks on (default) or off globally."""
    global _ENABLED
    _ENABLED = bool(flag)


def disable_checks() -> None:
    """Turn input checks off globally (for benchmarks of hot loops)."""
    enable_checks(False)


@contextlib.contextmanager
def checks_disabled() -> Iterator[None]:
    """Context manager that turns checks off inside the block."""
    old = _ENABLED
    enable_checks(False)
    try:
        yield
    finally:
        enable_checks(old)


def check_tensor(x: object, name: str) -> None:
    """Raise ``TypeError`` unless ``x`` is a ``torch.Tensor``."""
    if _ENABLED and not isinstance(x, torch.Tensor):
        raise TypeError(f"{name}: expected a torch.Tensor, got {type(x).__name__}")


def check_shape(x: torch.Tensor, dims: Sequence[str], name: str) -> None:
    """Check ``x`` against named dimensions, e.g. ``["B", "3", "H", "W"]``.

    A digit string demands that size; a letter names a free dimension; ``"*"`` as the first or last entry
    allows any number of leading or trailing dimensions.

    Example:
        >>> check_shape(torch.zeros(2, 3, 4, 5), ["B", "3", "H", "W"], "normal")
        >>> check_shape(torch.zeros(2, 1, 4, 5), ["B", "3", "H", "W"], "normal")
        Traceback (most recent call last):
        ...
        ValueError: normal: dimension C (index 1) must be 3, got shape (2, 1, 4, 5) for (B, 3, H, W)
    """
    if not _ENABLED:
        return
    check_tensor(x, name)
    shape = tuple(x.shape)
    dims = list(dims)
    lead = dims and dims[0] == "*"
    trail = dims and dims[-1] == "*"
    core = dims[1 if lead else 0: len(dims) - (1 if trail else 0)]
    ok_len = len(shape) >= len(core) if (lead or trail) else len(shape) == len(core)
    if not ok_len:
        raise ValueError(
            f"{name}: expected {len(core)} dimensions ({', '.join(dims)}), got shape {shape}")
    offset = len(shape) - len(core) if lead else 0
    names = "BCHW" if len(core) == 4 else None
    for i, d in enumerate(core):
        if d.isdigit() and shape[offset + i] != int(d):
            label = names[i] if names else d
            raise ValueError(
                f"{name}: dimension {label} (index {offset + i}) must be {d}, got shape {shape} "
                f"for ({', '.join(dims)})")


def check_same_size(a: torch.Tensor, b: torch.Tensor, name_a: str, name_b: str) -> None:
    """Check that two ``(B, C, H, W)`` tensors share B, H and W."""
    if not _ENABLED:
        return
    if a.shape[0] != b.shape[0] or a.shape[-2:] != b.shape[-2:]:
        raise ValueError(
            f"{name_b}: batch and image size must match {name_a} {tuple(a.shape)}, got {tuple(b.shape)}")


def has_nan(x: torch.Tensor) -> bool:
    """Whether floating-point ``x`` holds a NaN. The sum first (one read of ``x``, no mask): it is NaN whenever a
    value is; only a NaN sum (a NaN, or +inf beside -inf) pays for the elementwise test, which is 5-7x slower on
    the CPU.

    Example:
        >>> has_nan(torch.tensor([1.0, float("inf"), -float("inf")])), has_nan(torch.tensor([1.0, float("nan")]))
        (False, True)
    """
    return bool(torch.isnan(x.sum())) and bool(torch.isnan(x).any())


def all_finite(x: torch.Tensor) -> bool:
    """Whether every value of floating-point ``x`` is finite. The sum first: it is finite only when every value is;
    a sum that is not (a bad value, or an overflow of finite ones) pays for the elementwise test.

    Example:
        >>> all_finite(torch.tensor([3e38, 3e38])), all_finite(torch.tensor([1.0, float("inf")]))
        (True, False)
    """
    return bool(torch.isfinite(x.sum())) or bool(torch.isfinite(x).all())


def finite_vectors(x: torch.Tensor, dim: int = 1) -> torch.Tensor:
    """Whether each vector of ``x`` along ``dim`` has only finite components (``keepdim``), as
    ``torch.isfinite(x).all(dim, keepdim=True)``, in two fast passes instead of ATen's element-at-a-time reduction
    over a dimension that is not the innermost: ``x · 0`` is 0 for a finite value and NaN for an infinite or NaN one,
    so the sum along ``dim`` is 0 exactly when every component is finite.

    Example:
        >>> finite_vectors(torch.tensor([[1.0, 2.0], [float("inf"), 0.0], [3.0, float("nan")]]), 1).flatten().tolist()
        [True, False, False]
    """
    return (x * 0).sum(dim, keepdim=True) == 0


def check_finite(x: torch.Tensor, name: str) -> None:
    """Raise ``ValueError`` if ``x`` holds NaN (infinities are allowed: they encode 'none')."""
    if _ENABLED and x.is_floating_point() and has_nan(x):
        raise ValueError(f"{name}: contains NaN")
