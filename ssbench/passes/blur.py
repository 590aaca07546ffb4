"""AO blurs: the SSAO article's 5×5 box blur (§2.3), its 2-pass cross-bilateral blur (§3.2) and kornia's
joint bilateral blur guided by depth.

All take an AO buffer :math:`(B, 1, H, W)` (any channel count works) and keep its shape and dtype. Borders
replicate the edge texel: the article's render targets are three.js ``WebGLRenderTarget``\\ s, whose default wrap
mode is ``ClampToEdgeWrapping``, and every tap lands on a texel centre (``vUv + i·texelSize``), so a clamped
fetch returns the edge texel exactly.

**Background.** The box blur is not depth-aware (it smears AO across silhouettes, the halo of three.js PR
#15243); pass ``mask`` to renormalise over geometry only. The cross-bilateral blur rejects background taps by its
``|Δz| < threshold`` test, because background ``view_z`` is ``−far``; the joint bilateral blur only down-weights
them (a Gaussian in depth never reaches 0), so pass ``mask`` to exclude them exactly. With ``mask``, off-mask taps
get weight 0 and off-mask pixels keep their input value.
"""
from __future__ import annotations

import math
from typing import Optional

import kornia.filters as KF
import torch
import torch.nn.functional as F
from torch import nn

from .. import checks
from .common import check_count

BORDER_TYPES = ("constant", "reflect", "replicate", "circular")


def _check_ao(ao: torch.Tensor, name: str = "ao") -> None:
    checks.check_shape(ao, ["B", "C", "H", "W"], name)
    if checks.checks_enabled() and not ao.is_floating_point():
        raise ValueError(f"{name}: expected a floating-point dtype, got {ao.dtype}")


def _check_guide(ao: torch.Tensor, guide: torch.Tensor, name: str) -> None:
    checks.check_shape(guide, ["B", "1", "H", "W"], name)
    checks.check_same_size(ao, guide, "ao", name)
    if checks.checks_enabled() and not guide.is_floating_point():
        raise ValueError(f"{name}: expected a floating-point dtype, got {guide.dtype}")


def _check_mask(ao: torch.Tensor, mask: Optional[torch.Tensor]) -> None:
    if mask is None:
        return
    checks.check_shape(mask, ["B", "1", "H", "W"], "mask")
    checks.check_same_size(ao, mask, "ao", "mask")
    if checks.checks_enabled() and mask.dtype != torch.bool:
        raise ValueError(f"mask: expected dtype torch.bool, got {mask.dtype}")


def _scalar(value, name: str, positive: bool):
    """``value`` checked as a finite real number (``> 0`` or ``>= 0``): a Python number or a one-element floating
    tensor, returned as given so a tensor keeps its autograd graph (the blurs use it arithmetically)."""
    if isinstance(value, torch.Tensor) and value.numel() == 1 and value.is_floating_point():
        v = float(value.detach())
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        v = float(value)
    else:
        v = math.nan
    if not (math.isfinite(v) and (v > 0 if positive else v >= 0)):
        raise ValueError(f"{name}: must be a finite number {'>' if positive else '>='} 0, got {value!r}")
    return value


def _odd(value: int, name: str) -> None:
    check_count(value, name)
    if value % 2 == 0:
        raise ValueError(f"{name}: must be odd, got {value}")


def _masked(blur, ao: torch.Tensor, mask: Optional[torch.Tensor]) -> torch.Tensor:
    """``blur(ao·m) / blur(m)`` on ``mask`` (exact for any filter linear in its input), ``ao`` elsewhere."""
    if mask is None:
        return blur(ao)
    m = mask.to(ao.dtype)
    num, den = blur(ao * m), blur(m)
    return torch.where(mask & (den > 0), num / den.clamp_min(torch.finfo(ao.dtype).tiny), ao)


def box_blur(ao: torch.Tensor, kernel_size: int = 5, *, border_type: str = "replicate",
             mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    """The SSAO article's blur (§2.3): the mean of the ``kernel_size²`` texels around each pixel (``kornia`` box blur).

    .. math::
        \\text{out}(x, y) = \\frac{1}{k^2} \\sum_{i,j=-\\lfloor k/2 \\rfloor}^{\\lfloor k/2 \\rfloor} ao(x + i, y + j)

    Args:
        ao: :math:`(B, C, H, W)` ambient visibility.
        kernel_size: odd ``k`` (5 in the article).
        border_type: kornia padding; ``"replicate"`` is the article's CLAMP_TO_EDGE.
        mask: optional :math:`(B, 1, H, W)` bool; averages over geometry taps only (not in the article).

    Returns:
        :math:`(B, C, H, W)` blurred AO.

    Example:
        >>> box_blur(torch.ones(1, 1, 6, 7)).allclose(torch.ones(1, 1, 6, 7))
        True
    """
    _check_ao(ao)
    _odd(kernel_size, "kernel_size")
    _check_mask(ao, mask)
    if border_type not in BORDER_TYPES:
        raise ValueError(f"border_type: expected one of {BORDER_TYPES}, got {border_type!r}")
    return _masked(lambda x: KF.box_blur(x, kernel_size, border_type=border_type), ao, mask)


def default_blur_falloff(kernel_radius: int) -> float:
    """``1/(2σ²)`` with ``σ = (KERNEL_RADIUS + 1)/2`` (NVIDIA's HBAO / HBAO+ convention; the article gives none)."""
    sigma = (kernel_radius + 1) / 2.0
    return 1.0 / (2.0 * sigma * sigma)


def _cross_bilateral_pass(ao: torch.Tensor, z: torch.Tensor, m: Optional[torch.Tensor], kernel_radius: int,
                          blur_falloff, threshold, article_loop: bool, dim: int) -> torch.Tensor:
    """One pass of ``Blur(texScale)`` along ``dim`` (-1: x, -2: y), vectorised by ``unfold``; ``blur_falloff`` and
    ``threshold`` are floats or 0-d tensors (the Gaussian stays on the autograd tape; the depth test is a step)."""
    R = kernel_radius
    pad = (R, R, 0, 0) if dim == -1 else (0, 0, R, R)
    taps = lambda t: F.pad(t, pad, mode="replicate").unfold(dim, 2 * R + 1, 1)      # (B, C, H, W, 2R+1)
    r = torch.arange(-R, R + 1, dtype=ao.dtype, device=ao.device)
    g = torch.exp(-r * r * blur_falloff)                                             # exp(-r²·BlurParams.z)
    if article_loop:                                   # for (i = -KERNEL_RADIUS; i < KERNEL_RADIUS; i++)
        g = torch.cat([g[:-1], g.new_zeros(1)])        # not in place: exp's backward reads its output
    w = g * ((taps(z) - z.unsqueeze(-1)).abs() < threshold).to(ao.dtype)           # (B, 1, H, W, 2R+1)
    if m is not None:
        w = w * taps(m)
    total = (taps(ao) * w).sum(-1)                                                   # (B, C, H, W)
    weight = w.sum(-1)
    if article_loop:                                   # weightTotal = 1.0, totalAO = centre AO
        total, weight = total + ao, weight + 1.0
    return total / weight.clamp_min(torch.finfo(ao.dtype).tiny)


def cross_bilateral_blur(ao: torch.Tensor, view_z: torch.Tensor, kernel_radius: int = 15,
                         blur_falloff: Optional[float] = None, threshold: float = 0.1, *,
                         article_loop: bool = True, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    """The article's separable cross-bilateral blur (§3.2): a horizontal then a vertical pass of

    .. math::
        \\text{out} = \\frac{ao_0 + \\sum_i w_i\\, ao_i}{1 + \\sum_i w_i}, \\qquad
        w_i = e^{-i^2 \\cdot \\text{blurFalloff}} \\cdot [\\,|z_i - z_0| < \\text{threshold}\\,],
        \\quad i = -\\text{KERNEL\\_RADIUS} \\ldots \\text{KERNEL\\_RADIUS} - 1

    transcribed literally (``article_loop=True``): ``weightTotal`` starts at 1 with the centre's AO, and the loop
    runs ``i < KERNEL_RADIUS`` from ``−KERNEL_RADIUS``, so the centre counts twice and the kernel is one tap
    longer on the negative side. ``article_loop=False`` is the symmetric kernel ``i = −R … R``, centre once.
    The depth carried in the AO buffer's ``.y`` is the view z (the article's "カメラ座標系での Z 値"); the
    second pass reads the same z.

    Args:
        ao: :math:`(B, C, H, W)` ambient visibility.
        view_z: :math:`(B, 1, H, W)` view z (background ``−far``, so ``threshold`` rejects it).
        kernel_radius: ``KERNEL_RADIUS`` (15 in the article).
        blur_falloff: ``BlurParams.z`` (``blurFalloff``); default :func:`default_blur_falloff`. A 0-d tensor
            stays on the autograd tape (the blur is smooth in it).
        threshold: ``BlurParams.w`` (``threshold``), the largest ``|Δz|`` still blurred, in scene units
            (the article gives no value; 0.1 suits the metre-scale catalog scenes). A number or a 0-d tensor;
            the blur is a step function of it, so autograd finds no path through it.
        article_loop: keep the article's loop bounds and doubled centre (see above).
        mask: optional :math:`(B, 1, H, W)` bool; off-mask taps get weight 0 (not in the article).

    Returns:
        :math:`(B, C, H, W)` blurred AO.

    Example:
        >>> ao, z = torch.rand(1, 1, 8, 9), torch.full((1, 1, 8, 9), -2.0)
        >>> cross_bilateral_blur(ao, z, 3).shape
        torch.Size([1, 1, 8, 9])
    """
    _check_ao(ao)
    _check_guide(ao, view_z, "view_z")
    _check_mask(ao, mask)
    check_count(kernel_radius, "kernel_radius")
    falloff = default_blur_falloff(kernel_radius) if blur_falloff is None else blur_falloff
    falloff, threshold = (_scalar(v, n, False) for n, v in (("blur_falloff", falloff), ("threshold", threshold)))
    falloff, threshold = (v.reshape(()).to(ao.dtype) if isinstance(v, torch.Tensor) else float(v)
                          for v in (falloff, threshold))
    z = view_z.to(ao.dtype)
    m = None if mask is None else mask.to(ao.dtype)
    out = ao
    for dim in (-1, -2):                                    # BlurParams.xy = (1/W, 0), then (0, 1/H)
        out = _cross_bilateral_pass(out, z, m, kernel_radius, falloff, threshold, article_loop, dim)
    return out if mask is None else torch.where(mask, out, ao)


def joint_bilateral_blur(ao: torch.Tensor, guide_depth: torch.Tensor, kernel_size: int = 5,
                         sigma_color: float = 0.01, sigma_space: tuple[float, float] = (1.5, 1.5), *,
                         border_type: str = "replicate", mask: Optional[torch.Tensor] = None) -> torch.Tensor:
    """``kornia.filters.joint_bilateral_blur`` of AO guided by depth (not in the article).

    .. math::
        \\text{out}(p) = \\frac{\\sum_q G_{\\sigma_s}(\\|p - q\\|)\\, G_{\\sigma_c}(|d_p - d_q|)\\, ao(q)}
                              {\\sum_q G_{\\sigma_s}(\\|p - q\\|)\\, G_{\\sigma_c}(|d_p - d_q|)}

    Args:
        ao: :math:`(B, C, H, W)` ambient visibility.
        guide_depth: :math:`(B, 1, H, W)` guide, normally the linear depth ``GBuffer.linear_depth`` in [0, 1]
            (``sigma_color`` is in its units; background is 1).
        kernel_size: odd window side.
        sigma_color: Gaussian width on depth differences (a number or a one-element tensor, kept differentiable).
        sigma_space: Gaussian widths (y, x) in pixels (numbers or one-element tensors; one tensor: both axes).
        border_type: kornia padding (``"replicate"`` = CLAMP_TO_EDGE).
        mask: optional :math:`(B, 1, H, W)` bool; off-mask taps get weight 0 (renormalised).

    Returns:
        :math:`(B, C, H, W)` blurred AO.

    Example:
        >>> joint_bilateral_blur(torch.rand(1, 1, 6, 6), torch.rand(1, 1, 6, 6)).shape
        torch.Size([1, 1, 6, 6])
    """
    _check_ao(ao)
    _check_guide(ao, guide_depth, "guide_depth")
    _check_mask(ao, mask)
    _odd(kernel_size, "kernel_size")
    _scalar(sigma_color, "sigma_color", True)
    if isinstance(sigma_space, torch.Tensor) and sigma_space.numel() == 1:
        sigma_space = (sigma_space, sigma_space)                      # one tensor width for both axes
    try:
        ok = len(sigma_space) == 2 and all(_scalar(s, "sigma_space", True) is not None for s in sigma_space)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"sigma_space: expected two numbers > 0, got {sigma_space!r}")
    if border_type not in BORDER_TYPES:
        raise ValueError(f"border_type: expected one of {BORDER_TYPES}, got {border_type!r}")
    guide = guide_depth.to(ao.dtype)
    if isinstance(sigma_color, torch.Tensor) or any(isinstance(s, torch.Tensor) for s in sigma_space):
        # kornia takes tensor sigmas of shape (B,) and (B, 2) and keeps them on the autograd tape
        as_t = lambda v: (v if isinstance(v, torch.Tensor) else torch.tensor(float(v))).reshape(()).to(ao.dtype)  # noqa: E731
        sc, ss = as_t(sigma_color).reshape(1), torch.stack([as_t(s) for s in sigma_space]).reshape(1, 2)
    else:
        sc, ss = float(sigma_color), (float(sigma_space[0]), float(sigma_space[1]))
    blur = lambda x: KF.joint_bilateral_blur(x, guide, kernel_size, sc, ss, border_type)   # noqa: E731
    return _masked(blur, ao, mask)


class BoxBlur(nn.Module):
    """:func:`box_blur` as a module."""

    def __init__(self, kernel_size: int = 5, border_type: str = "replicate") -> None:
        super().__init__()
        self.kernel_size, self.border_type = kernel_size, border_type

    def forward(self, ao: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
        return box_blur(ao, self.kernel_size, border_type=self.border_type, mask=mask)


class CrossBilateralBlur(nn.Module):
    """:func:`cross_bilateral_blur` as a module."""

    def __init__(self, kernel_radius: int = 15, blur_falloff: Optional[float] = None, threshold: float = 0.1,
                 article_loop: bool = True) -> None:
        super().__init__()
        self.kernel_radius, self.blur_falloff, self.threshold = kernel_radius, blur_falloff, threshold
        self.article_loop = article_loop

    def forward(self, ao: torch.Tensor, view_z: torch.Tensor, mask: Optional[torch.Tensor] = None) -> torch.Tensor:
        return cross_bilateral_blur(ao, view_z, self.kernel_radius, self.blur_falloff, self.threshold,
                                    article_loop=self.article_loop, mask=mask)


class JointBilateralBlur(nn.Module):
    """:func:`joint_bilateral_blur` as a module."""

    def __init__(self, kernel_size: int = 5, sigma_color: float = 0.01,
                 sigma_space: tuple[float, float] = (1.5, 1.5), border_type: str = "replicate") -> None:
        super().__init__()
        self.kernel_size, self.sigma_color, self.sigma_space = kernel_size, sigma_color, sigma_space
        self.border_type = border_type

    def forward(self, ao: torch.Tensor, guide_depth: torch.Tensor,
                mask: Optional[torch.Tensor] = None) -> torch.Tensor:
        return joint_bilateral_blur(ao, guide_depth, self.kernel_size, self.sigma_color, self.sigma_space,
                                    border_type=self.border_type, mask=mask)
