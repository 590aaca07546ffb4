"""Masks as 0/1 floating-point numbers in eager code: the same results as boolean masks, without boolean tensors.

On the CPU, torch's elementwise kernels that write or read ``bool`` tensors run several times slower than their
floating-point twins, and ``torch.where`` is the slowest of them (``benchmarks/bench_ops.py`` times the family on whole
images). Measured on this project's 2-core AVX2 machine (torch 2.13, 1 thread, one band of 16 × 8 × 640 float32
samples, the block an eager AO pass works on, ``ssbench/passes/common.py``; the masks flip at random):

=============================================  =======
operation                                       µs
=============================================  =======
``a * b`` (float32)                              22
``a > 0.5`` (→ bool)                             78
``torch.gt(a, 0.5, out=float32 buffer)``         18
``mask.sum(0)`` (bool → int64)                   50
``f.sum(0)`` (float32)                           22
``torch.where(mask, -1e-38, a)``                302
``torch.addcmul(a, f, f, value=-1e-38)``         27
=============================================  =======

A comparison written into a floating-point buffer gives 1.0 or 0.0 in a vectorised loop; products and sums of
those are exact (integers below :math:`2^{24}`), and adding ``value · m · m`` to ``x`` replaces ``x`` exactly where
``m`` is 1 and adds a signed zero elsewhere, which leaves every nonzero ``x`` (infinities and NaN too) as it was.
So each helper here returns the bits of its boolean twin. Inside ``torch.compile`` (inductor fuses the boolean
form into the loop around it) and with gradients (``where`` routes them differently) the boolean form runs. The SSR
marchers' eager steps (:mod:`ssbench.passes.ssr.linear_float_step`, :mod:`ssbench.passes.ssr.dda_float_step`) keep
their working sets' flags, counts and codes in this form where :func:`float_flags` says it is exact.
"""
from __future__ import annotations

import torch

from .compiled import enabled

__all__ = ["float_masks", "float_flags", "replace_zeros", "count_between", "inside_image", "select"]


def float_masks(x: torch.Tensor) -> bool:
    """Whether the helpers of this module take their floating-point form for ``x``: eager, without gradients, in
    float32 or float64 (whose sums of ones are exact up to :math:`2^{24}`; float16 stops at 2048, bfloat16 at 256)."""
    return not (torch.compiler.is_compiling() or x.requires_grad) and x.dtype in (torch.float32, torch.float64)


def float_flags(samples: torch.Tensor, count: int) -> bool:
    """Whether a marcher keeps its working set's flags, counts and codes in ``samples``' dtype, as 0/1 masks and
    integer-valued floats, and steps eagerly in that form: not :func:`~ssbench.passes.compiled.enabled` (a compiled
    step keeps them in int32), :func:`float_masks` of ``samples``, and every integer the step forms — a flat texel
    index among ``count`` texels, a count of rays — exact in that dtype (at most :math:`2/\varepsilon`,
    :math:`2^{24}` in float32).

    Example:
        >>> float_flags(torch.zeros(4), 640 * 360), float_flags(torch.zeros(4), 2 ** 25)
        (True, False)
    """
    return not enabled() and float_masks(samples) and count <= 2 / torch.finfo(samples.dtype).eps


def replace_zeros(x: torch.Tensor, value: float) -> torch.Tensor:
    """``torch.where(x == 0, value, x)``: ``x`` with its zeros (±0) replaced by ``value``, the same bits.

    Example:
        >>> replace_zeros(torch.tensor([0.0, -0.0, 2.0, float("inf")]), -1.0)
        tensor([-1., -1.,  2., inf])
    """
    if not float_masks(x):
        return torch.where(x == 0, value, x)
    zero = torch.eq(x, 0, out=torch.empty_like(x))                       # 1.0 where x == ±0, else 0.0
    return torch.addcmul(x, zero, zero, value=value)                     # x + value·1 = value, or x + (±0) = x


def count_between(x: torch.Tensor, lo: float, hi: float, dim: int) -> torch.Tensor:
    """``((x > lo) & (x < hi)).sum(dim)``: how many entries along ``dim`` lie strictly between ``lo`` and ``hi``
    (NaN never), as int64.

    Example:
        >>> count_between(torch.tensor([[0.5, 1.0, float("nan"), 0.2]]), 0.0, 1.0, 1)
        tensor([2])
    """
    if not float_masks(x):
        return ((x > lo) & (x < hi)).sum(dim, dtype=torch.int32).to(torch.int64)
    above = torch.gt(x, lo, out=torch.empty_like(x))                     # 1.0 / 0.0
    above.mul_(torch.lt(x, hi, out=torch.empty_like(x)))
    return above.sum(dim).to(torch.int64)                                # exact: at most 2^24 ones per sum in float32


def inside_image(x: torch.Tensor, y: torch.Tensor, width: int, height: int) -> torch.Tensor:
    """``(x >= 0) & (x < width) & (y >= 0) & (y < height)`` of texel coordinates ``x``, ``y`` of one shape (NaN is
    outside): bool, or in the floating-point form (:func:`float_masks`) the same test as 1.0 / 0.0 in ``x``'s dtype.

    Example:
        >>> inside_image(torch.tensor([0.0, 3.0, 1.0, float("nan")]), torch.tensor([1.0, 0.0, 2.0, 0.0]), 3, 2)
        tensor([1., 0., 0., 0.])
    """
    if not float_masks(x):
        return (x >= 0) & (x < width) & (y >= 0) & (y < height)
    on = torch.ge(x, 0, out=torch.empty_like(x))
    test = torch.lt(x, width, out=torch.empty_like(x))
    on.mul_(test)
    on.mul_(torch.ge(y, 0, out=test))
    return on.mul_(torch.lt(y, height, out=test))


_BITS = {torch.float32: torch.int32, torch.float64: torch.int64}


def select(mask: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``torch.where(mask == 1, a, b)`` of a 0/1 floating-point ``mask`` (this module's form) and float32/float64 ``a``,
    ``b`` of one shape and dtype: picked bit by bit, ``b ^ ((a ^ b) & −mask)`` on the integers of their bits, so the
    same bits (NaN payloads and signed zeros too), in integer operations that vectorise.

    Example:
        >>> select(torch.tensor([1.0, 0.0]), torch.tensor([-0.0, 1.0]), torch.tensor([2.0, float("nan")]))
        tensor([-0., nan])
    """
    bits = _BITS[a.dtype]
    ones = mask.to(bits).neg_()                                          # 0, or every bit set
    b_bits = b.view(bits)
    return torch.bitwise_xor(a.view(bits), b_bits).bitwise_and_(ones).bitwise_xor_(b_bits).view(a.dtype)
