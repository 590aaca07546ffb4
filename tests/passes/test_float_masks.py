"""ssbench.passes.float_masks: the floating-point forms give the bits of their boolean twins."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.passes import compiled as C
from ssbench.passes.float_masks import (count_between, float_flags, float_masks, inside_image, replace_zeros,
                                       select)


def _bits(x: torch.Tensor) -> torch.Tensor:
    return x.view(torch.int64 if x.dtype == torch.float64 else torch.int32)


def _hard(dtype: torch.dtype, n: int = 4096) -> torch.Tensor:
    """Random values around 0, mixed with ±0, ±inf, NaN, subnormals and the extremes of ``dtype``."""
    g = torch.Generator().manual_seed(5)
    x = (torch.randn(n, generator=g, dtype=torch.float64) * 0.02).to(dtype)
    tiny, big = torch.finfo(dtype).tiny, torch.finfo(dtype).max
    special = torch.tensor([0.0, -0.0, math.inf, -math.inf, math.nan, tiny / 4, -tiny / 4, tiny, big, -big, 0.01,
                            0.02, -0.0005, 0.0005], dtype=dtype)
    x[torch.randperm(n, generator=g)[:len(special) * 20]] = special.repeat(20)
    return x


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_replace_zeros_gives_the_bits_of_where(dtype):
    x = _hard(dtype)
    tiny = torch.finfo(dtype).tiny
    for value in (-tiny, tiny, 2.5):
        got, want = replace_zeros(x, value), torch.where(x == 0, value, x)
        assert float_masks(x) and got.dtype == want.dtype and torch.equal(_bits(got), _bits(want))
    assert int((x == 0).sum()) >= 40                              # zeros of both signs were replaced


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("lo, hi", [(0.0, 0.02), (0.0005, 0.02), (-0.02, -0.0), (-math.inf, 0.01)])
def test_count_between_counts_what_the_boolean_test_counts(dtype, lo, hi):
    x = _hard(dtype).view(8, 16, 32)
    for dim in (0, 1, -1):
        got, want = count_between(x, lo, hi, dim), ((x > lo) & (x < hi)).sum(dim)
        assert got.dtype == want.dtype == torch.int64 and torch.equal(got, want)
    assert 0 < int(count_between(x, lo, hi, 0).sum()) < x.numel()    # some counted, some not


def test_the_boolean_forms_run_with_gradients_and_inside_compile():
    x = _hard(torch.float32)[:64].nan_to_num(0.0, 1.0, -1.0).requires_grad_(True)
    assert not float_masks(x)
    replace_zeros(x, 3.0).sum().backward()                        # where's gradient: 0 at the replaced zeros
    assert torch.equal(x.grad, (x != 0).float())

    @C.kernel
    def both(v):
        return float_masks(v), replace_zeros(v, -1.0), count_between(v, 0.0, 0.02, 0)

    v = _hard(torch.float32)
    with C.compiling(True):
        fast, replaced, count = both(v)
    assert not fast and torch.equal(_bits(replaced), _bits(torch.where(v == 0, -1.0, v)))
    assert torch.equal(count, ((v > 0) & (v < 0.02)).sum(0))


@pytest.mark.parametrize("dtype", [torch.bfloat16, torch.float16])
def test_half_precision_takes_the_boolean_forms_whose_counts_stay_exact(dtype):
    """bfloat16 sums of ones stop being exact at 256, float16 at 2048: such inputs count with the boolean form."""
    x = torch.full((3000, 2), 0.5, dtype=dtype)
    assert not float_masks(x)
    assert count_between(x, 0.0, 1.0, 0).tolist() == [3000, 3000]
    assert torch.equal(replace_zeros(torch.tensor([0.0, 2.0], dtype=dtype), 1.0), torch.tensor([1.0, 2.0], dtype=dtype))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_inside_image_is_the_boolean_bounds_test(dtype):
    g = torch.Generator().manual_seed(7)
    x = torch.randint(-5, 14, (4096,), generator=g).to(dtype)
    y = torch.randint(-5, 11, (4096,), generator=g).to(dtype)
    special = torch.tensor([math.nan, math.inf, -math.inf, -0.0, 0.5, -0.5, 9.5, 8.9999, 1e30, -1e30], dtype=dtype)
    x[:100], y[100:200] = special.repeat(10), special.repeat(10)
    got, want = inside_image(x, y, 9, 6), (x >= 0) & (x < 9) & (y >= 0) & (y < 6)
    assert float_masks(x) and got.dtype == dtype and torch.equal(got, want.to(dtype))
    assert 0 < int(want.sum()) < x.numel()
    with C.compiling(True):
        assert torch.equal(C.kernel(inside_image)(x, y, 9, 6), want)        # compiled: the boolean form


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_select_gives_the_bits_of_where(dtype):
    a, b = _hard(dtype), _hard(dtype).flip(0)
    mask = (torch.rand(a.shape, generator=torch.Generator().manual_seed(9)) < 0.5).to(dtype)
    got, want = select(mask, a, b), torch.where(mask == 1, a, b)
    assert got.dtype == dtype and torch.equal(_bits(got), _bits(want))
    assert torch.equal(_bits(a), _bits(_hard(dtype))) and 0 < int(mask.sum()) < mask.numel()   # inputs untouched
    row = select(mask.view(64, 64)[:1], a.view(64, 64), b.view(64, 64))                  # a mask broadcast on rows
    assert torch.equal(_bits(row), _bits(torch.where(mask.view(64, 64)[:1] == 1, a.view(64, 64), b.view(64, 64))))


def test_float_flags_only_eager_and_exact():
    x = torch.zeros(3)
    assert float_flags(x, 2 ** 24) and not float_flags(x, 2 ** 24 + 1) and float_flags(x.double(), 2 ** 40)
    assert not float_flags(x.half(), 10) and not float_flags(torch.zeros(3, requires_grad=True), 10)
    with C.compiling(True):
        assert not float_flags(x, 10)                            # a compiled step keeps int32 flags
