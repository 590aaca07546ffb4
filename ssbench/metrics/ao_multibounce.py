"""Multi-bounce AO: Jimenez et al.'s fit from single-bounce visibility and albedo, and its error against the
path-traced truth (:func:`ssbench.reference.multibounce.multibounce_ao`).

Jimenez, Wu, Pesce, Jarabo. *Practical Real-Time Strategies for Accurate Indirect Occlusion.* SIGGRAPH 2016 course
"Physically Based Shading in Theory and Practice", §5,
https://www.activision.com/cdn/research/Practical_Real_Time_Strategies_for_Accurate_Indirect_Occlusion_NEW%20VERSION_COLOR.pdf:
a cubic in the visibility ``V`` whose coefficients are linear in the albedo ``ρ``, fitted to ray-traced
interreflections:

.. math::  V_m = \\max\\bigl(V,\\ ((a V + b) V + c) V\\bigr), \\quad a = 2.0404ρ − 0.3324,\\ b = −4.7951ρ + 0.6417,
           \\ c = 2.7552ρ + 0.6903.
"""
from __future__ import annotations

import math

import torch

from .. import checks
from .image import bias, rmse

__all__ = ["jimenez_multibounce", "multibounce_error"]


def jimenez_multibounce(visibility: torch.Tensor, albedo: torch.Tensor) -> torch.Tensor:
    """Multi-bounce visibility :math:`(B, 3, H, W)` from single-bounce ``visibility`` :math:`(B, 1, H, W)` and the
    pixel's ``albedo`` :math:`(B, 3, H, W)` (per channel, as the course applies it).

    Example:
        >>> v, rho = torch.full((1, 1, 1, 1), 0.5), torch.full((1, 3, 1, 1), 0.5)
        >>> round(float(jimenez_multibounce(v, rho)[0, 0]), 5)
        0.68096
    """
    checks.check_shape(visibility, ["B", "1", "H", "W"], "visibility")
    checks.check_shape(albedo, ["B", "3", "H", "W"], "albedo")
    a = 2.0404 * albedo - 0.3324
    b = -4.7951 * albedo + 0.6417
    c = 2.7552 * albedo + 0.6903
    v = visibility
    return torch.maximum(v.expand_as(albedo), ((a * v + b) * v + c) * v)


def multibounce_error(pred: torch.Tensor, truth: torch.Tensor, mask: torch.Tensor,
                      truth_stderr: torch.Tensor | None = None) -> dict:
    """``{"rmse", "bias", "pixels", "truth_stderr"}`` of a :math:`(B, 3, H, W)` multi-bounce estimate against the
    truth over ``mask`` (all three channels); ``truth_stderr`` is the truth's RMS standard error over the same
    pixels (NaN when not given), the floor below which an RMSE is the truth's own noise.

    Example:
        >>> t, m = torch.full((1, 3, 2, 2), 0.8), torch.ones(1, 1, 2, 2, dtype=torch.bool)
        >>> multibounce_error(t + 0.1, t, m)["rmse"] == multibounce_error(t - 0.1, t, m)["rmse"]
        True
    """
    checks.check_shape(pred, ["B", "3", "H", "W"], "pred")
    checks.check_same_size(pred, truth, "pred", "truth")
    m = mask.bool()
    n = int(m.expand_as(pred[:, :1]).sum())
    se = math.nan
    if truth_stderr is not None and n:
        se = float(rmse(truth_stderr.double(), torch.zeros_like(truth_stderr, dtype=torch.float64), m))
    if n == 0:
        return {"rmse": math.nan, "bias": math.nan, "pixels": 0, "truth_stderr": se}
    return {"rmse": float(rmse(pred.double(), truth.double(), m)), "bias": float(bias(pred.double(), truth.double(), m)),
            "pixels": n, "truth_stderr": se}
