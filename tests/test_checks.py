"""ssbench.checks: named shape checks, wildcards, switching checks off."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
import torch

from ssbench import checks
from ssbench.checks import check_finite, check_same_size, check_shape, check_tensor


def test_exact_pattern_passes_and_fails():
    check_shape(torch.zeros(2, 3, 4, 5), ["B", "3", "H", "W"], "normal")
    check_shape(torch.zeros(7, 3), ["N", "3"], "points")
    with pytest.raises(ValueError) as info:
        check_shape(torch.zeros(2, 1, 4, 5), ["B", "3", "H", "W"], "normal")
    msg = str(info.value)
    assert msg.startswith("normal:")
    assert "dimension C" in msg and "index 1" in msg and "must be 3" in msg
    assert "(2, 1, 4, 5)" in msg and "(B, 3, H, W)" in msg


def test_size_checks_on_h_and_w_label_the_dimension():
    with pytest.raises(ValueError) as info:
        check_shape(torch.zeros(1, 1, 4, 6), ["B", "1", "4", "5"], "depth")
    msg = str(info.value)
    assert msg.startswith("depth:") and "dimension W" in msg and "index 3" in msg and "must be 5" in msg
    with pytest.raises(ValueError, match=r"^depth: dimension H \(index 2\) must be 3"):
        check_shape(torch.zeros(1, 1, 4, 5), ["B", "1", "3", "5"], "depth")


def test_wrong_rank_message():
    with pytest.raises(ValueError) as info:
        check_shape(torch.zeros(3, 4, 5), ["B", "3", "H", "W"], "position")
    msg = str(info.value)
    assert msg.startswith("position:") and "expected 4 dimensions" in msg and "(3, 4, 5)" in msg
    with pytest.raises(ValueError, match="expected 2 dimensions"):
        check_shape(torch.zeros(2, 3, 1), ["N", "3"], "points")


def test_leading_wildcard():
    pattern = ["*", "3", "H", "W"]
    for shape in ((3, 4, 5), (2, 3, 4, 5), (6, 2, 3, 4, 5)):
        check_shape(torch.zeros(shape), pattern, "x")
    with pytest.raises(ValueError) as info:
        check_shape(torch.zeros(6, 2, 1, 4, 5), pattern, "x")             # the 3 is checked from the end
    assert "index 2" in str(info.value) and "must be 3" in str(info.value)
    with pytest.raises(ValueError, match="expected 3 dimensions"):
        check_shape(torch.zeros(4, 5), pattern, "x")                      # too few
    check_shape(torch.zeros(9, 2), ["*", "2"], "uv")
    check_shape(torch.zeros(4, 5, 2), ["*", "2"], "uv")
    with pytest.raises(ValueError, match=r"^uv:.*must be 2"):
        check_shape(torch.zeros(4, 2, 5), ["*", "2"], "uv")


def test_trailing_wildcard():
    pattern = ["B", "3", "*"]
    for shape in ((2, 3), (2, 3, 4), (2, 3, 4, 5, 6)):
        check_shape(torch.zeros(shape), pattern, "x")
    with pytest.raises(ValueError, match=r"index 1.*must be 3"):
        check_shape(torch.zeros(2, 4, 5), pattern, "x")
    with pytest.raises(ValueError, match="expected 2 dimensions"):
        check_shape(torch.zeros(3), pattern, "x")


def test_wildcard_only_accepts_anything():
    for shape in ((), (1,), (2, 3, 4)):
        check_shape(torch.zeros(shape), ["*"], "x")


def test_letters_are_free():
    check_shape(torch.zeros(1, 3, 100, 1), ["B", "3", "H", "W"], "x")
    check_shape(torch.zeros(0, 3, 0, 0), ["B", "3", "H", "W"], "x")


def test_non_tensor_is_type_error():
    with pytest.raises(TypeError, match="^depth: expected a torch.Tensor, got list"):
        check_shape([1, 2, 3], ["3"], "depth")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="^x:"):
        check_tensor(None, "x")
    check_tensor(torch.zeros(1), "x")


def test_check_same_size():
    a = torch.zeros(2, 3, 4, 5)
    check_same_size(a, torch.zeros(2, 1, 4, 5), "position", "mask")
    for bad in (torch.zeros(1, 1, 4, 5), torch.zeros(2, 1, 5, 5), torch.zeros(2, 1, 4, 6)):
        with pytest.raises(ValueError) as info:
            check_same_size(a, bad, "position", "mask")
        msg = str(info.value)
        assert msg.startswith("mask:") and "position" in msg and str(tuple(bad.shape)) in msg


def test_check_finite():
    check_finite(torch.tensor([1.0, float("inf"), -float("inf")]), "back_z")   # infinities allowed
    check_finite(torch.tensor([1, 2]), "ids")                                   # integer tensors pass
    with pytest.raises(ValueError, match="^back_z: contains NaN"):
        check_finite(torch.tensor([1.0, float("nan")]), "back_z")


def test_disable_and_context_manager():
    assert checks.checks_enabled()
    bad = torch.zeros(2, 1, 4, 5)
    with checks.checks_disabled():
        assert not checks.checks_enabled()
        check_shape(bad, ["B", "3", "H", "W"], "normal")
        check_shape("not a tensor", ["B"], "normal")  # type: ignore[arg-type]
        check_finite(torch.tensor([float("nan")]), "x")
        check_same_size(bad, torch.zeros(3, 1, 1, 1), "a", "b")
    assert checks.checks_enabled()
    with pytest.raises(ValueError):
        check_shape(bad, ["B", "3", "H", "W"], "normal")
    # restored even when the block raises, and nesting keeps the outer state
    with pytest.raises(RuntimeError):
        with checks.checks_disabled():
            raise RuntimeError("boom")
    assert checks.checks_enabled()
    try:
        checks.disable_checks()
        with checks.checks_disabled():
            pass
        assert not checks.checks_enabled()
    finally:
        checks.enable_checks()
    assert checks.checks_enabled()


@pytest.mark.parametrize("value,enabled", [("off", False), ("1", True)])
def test_environment_variable(value, enabled):
    env = {**os.environ, "SSBENCH_CHECKS": value}
    out = subprocess.run([sys.executable, "-c", "import ssbench.checks as c; print(c.checks_enabled())"],
                         env=env, capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == str(enabled)


@pytest.mark.parametrize("dtype", [torch.float16, torch.float32, torch.float64])
def test_the_fast_finiteness_tests_agree_with_isfinite(dtype):
    from ssbench.checks import all_finite, finite_vectors, has_nan
    g = torch.Generator().manual_seed(0)
    x = (torch.randn(2, 3, 20, 30, generator=g) * 100).to(dtype)
    flat = x.view(-1)
    assert not has_nan(x) and all_finite(x)
    assert bool(finite_vectors(x).all())
    big = torch.full_like(x, torch.finfo(dtype).max)                    # finite, but its sum overflows
    assert all_finite(big) and not has_nan(big) and bool(finite_vectors(big).all())
    spots = torch.randperm(flat.numel(), generator=g)[:60]
    flat[spots[:20]], flat[spots[20:40]], flat[spots[40:]] = float("inf"), -float("inf"), float("nan")
    assert has_nan(x) and not all_finite(x)
    assert torch.equal(finite_vectors(x), torch.isfinite(x).all(1, keepdim=True))
    infs = x.nan_to_num(nan=1.0, posinf=float("inf"), neginf=-float("inf"))
    assert not has_nan(infs) and not all_finite(infs)                  # +inf beside -inf: a NaN sum, no NaN value
