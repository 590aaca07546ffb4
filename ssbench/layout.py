"""Copies that change a tensor's layout: a transposed view made contiguous (:func:`contiguous`) and 1-D columns
stacked side by side (:func:`stack_columns`; :func:`stack` takes it wherever ``torch.stack`` would do the same),
the two re-layouts every marcher makes between its per-ray rows :math:`(N, C)` and its per-component arrays
:math:`(N,)` or :math:`(C, N)`, and the camera's conversions of point lists.

On the CPU, ATen copies a 2-D transposed view into a contiguous tensor (``x.T.contiguous()``, and ``reshape`` of a
permuted image) through a blocked transpose made for square matrices; for the project's thin ones, :math:`N × 3`,
it runs 2.5–4× slower than a plain copy that reads the source in its own memory order and writes the strided
destination (measured at 640×360 on this project's 2-core VM, 1 thread: 1.32 → 0.51 ms for 230 400 × 3 float32,
1.58 → 0.40 ms for int64 × 2, 1.48 → 0.49 ms for a :math:`(1, 3, H, W)` image to :math:`(H·W, 3)` rows).
``torch.stack(columns, 1)`` is 2.3–2.6× slower than writing the columns one by one for the same reason. Both
functions give exactly the values of those calls (a copy is exact); other devices, tensors of fewer than
:data:`MIN_NUMEL` elements, tensors that need a gradient and code inside ``torch.compile`` (which fuses the copy into
its kernel) keep the plain calls.
"""
from __future__ import annotations

from typing import Sequence

import torch

__all__ = ["MIN_NUMEL", "contiguous", "stack", "stack_columns"]


#: the size (elements) below which the plain calls are as fast or faster: the copies' own overhead, ~10 µs a call,
#: outweighs the slow transpose below ~4000 elements (measured, 1 thread: 3 × 1000 float32 6.5 µs stacked, 14 µs
#: column by column; 3 × 5000 25 µs and 21 µs)
MIN_NUMEL = 4096


def _plain(t: torch.Tensor, numel: int) -> bool:
    """Whether the plain ATen call is the one to make: compiling, off the CPU, with gradients, or for small tensors.
    Compiling is asked first: a size-dynamic kernel would otherwise guard on ``numel < MIN_NUMEL`` and compile again
    on either side of it."""
    return torch.compiler.is_compiling() or t.device.type != "cpu" or t.requires_grad or numel < MIN_NUMEL


def contiguous(x: torch.Tensor) -> torch.Tensor:
    """``x.contiguous()``: ``x`` itself when it is contiguous, else a contiguous copy of its values, made on the CPU
    by reading ``x`` in the order of its own memory (its dimensions sorted by stride).

    Example:
        >>> rows = torch.arange(6.0).view(3, 2).T                   # a transposed view, (2, 3)
        >>> y = contiguous(rows)
        >>> y.tolist(), y.is_contiguous()
        ([[0.0, 2.0, 4.0], [1.0, 3.0, 5.0]], True)
    """
    if x.is_contiguous() or _plain(x, x.numel()):
        return x.contiguous()
    order = sorted(range(x.dim()), key=lambda d: (-x.stride(d), -x.shape[d]))    # x's memory order, outer first
    out = torch.empty(x.shape, dtype=x.dtype, device=x.device)
    out.permute(order).copy_(x.permute(order))
    return out


def stack_columns(columns: Sequence[torch.Tensor]) -> torch.Tensor:
    """``torch.stack(columns, 1)`` for :math:`C` tensors :math:`(N,)` of one dtype and device: the :math:`(N, C)`
    rows, written a column at a time on the CPU.

    Raises:
        ValueError: ``columns`` is empty, or its tensors are not 1-D of one length, dtype and device.

    Example:
        >>> stack_columns([torch.tensor([1, 2]), torch.tensor([3, 4])]).tolist()
        [[1, 3], [2, 4]]
    """
    if not columns:
        raise ValueError("columns: expected at least one tensor, got none")
    k = _first_unlike(columns)
    if k is not None:
        first, c = columns[0], columns[k]
        got = f"{tuple(c.shape)}, {c.dtype}, {c.device}" if isinstance(c, torch.Tensor) else type(c).__name__
        raise ValueError(f"columns[{k}]: expected a 1-D tensor like columns[0] ({tuple(first.shape)}, "
                         f"{first.dtype}, {first.device}), got {got}")
    return _columns(columns)


def _first_unlike(columns: Sequence[torch.Tensor]) -> int | None:
    """The position of the first of ``columns`` (not empty) that is not a 1-D tensor of ``columns[0]``'s length,
    dtype and device (``0`` when ``columns[0]`` is not 1-D), or ``None`` when they all are."""
    first = columns[0]
    for k, c in enumerate(columns):
        if not isinstance(c, torch.Tensor) or c.dim() != 1 or (c.shape, c.dtype, c.device) != (
                first.shape, first.dtype, first.device):
            return k
    return None


def _columns(columns: Sequence[torch.Tensor]) -> torch.Tensor:
    """:func:`stack_columns` of columns already checked."""
    first = columns[0]
    if _plain(first, first.numel() * len(columns)) or any(c.requires_grad for c in columns):
        return torch.stack(list(columns), 1)
    out = torch.empty(first.shape[0], len(columns), dtype=first.dtype, device=first.device)
    for k, c in enumerate(columns):
        out[:, k].copy_(c)
    return out


def stack(parts: Sequence[torch.Tensor], dim: int) -> torch.Tensor:
    """``torch.stack(parts, dim)``, through :func:`stack_columns` where that is the same call (1-D ``parts`` of one
    length, dtype and device stacked on ``dim`` 1 or −1: a point list's :math:`(N, C)` rows).

    Example:
        >>> stack([torch.tensor([1.0, 2.0]), torch.tensor([3.0, 4.0])], -1).tolist()
        [[1.0, 3.0], [2.0, 4.0]]
        >>> stack([torch.zeros(2, 2), torch.ones(2, 2)], 0).shape
        torch.Size([2, 2, 2])
    """
    if dim in (1, -1) and len(parts) and _first_unlike(parts) is None:
        return _columns(parts)
    return torch.stack(list(parts), dim)
