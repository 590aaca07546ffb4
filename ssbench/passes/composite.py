"""Composite AO onto a colour buffer, the SSAO article's final pass (§2.4).

The article's fragment shader::

    float occlusion = pow(texture2D(OcclusionSampler, vUv).x, OcclusionPower);
    gl_FragColor = vec4(mix(OcclusionColor, color.xyz, occlusion), 1.0);

``mix(a, b, t) = a·(1 − t) + b·t``: fully visible pixels (``ao = 1``) keep their colour, fully occluded ones
(``ao = 0``) become ``OcclusionColor``. ssbench colour buffers are linear RGB, so the blend happens in linear
space (the article's three.js demo blends whatever its colour target holds). The alpha of 1 is dropped.
"""
from __future__ import annotations

import math
from typing import Sequence, Union

import torch
from torch import nn

from .. import checks

ColorSpec = Union[Sequence[float], torch.Tensor]


def _occlusion_color(value: ColorSpec, like: torch.Tensor) -> torch.Tensor:
    if isinstance(value, torch.Tensor):
        c = value.to(dtype=like.dtype, device=like.device)
        if c.dim() == 1:
            c = c.view(1, -1, 1, 1)
    else:
        try:
            c = torch.tensor([float(v) for v in value], dtype=like.dtype, device=like.device).view(1, -1, 1, 1)
        except (TypeError, ValueError):
            raise ValueError(f"occlusion_color: expected three numbers, got {value!r}") from None
    try:
        torch.broadcast_shapes(c.shape, like.shape)
    except RuntimeError:
        raise ValueError(f"occlusion_color: shape {tuple(c.shape)} does not broadcast to color "
                         f"{tuple(like.shape)}") from None
    if c.dim() != 4 or c.shape[1] != like.shape[1]:
        raise ValueError(f"occlusion_color: needs {like.shape[1]} components, got shape {tuple(c.shape)}")
    return c


def composite(color: torch.Tensor, ao: torch.Tensor, occlusion_color: ColorSpec = (0.0, 0.0, 0.0),
              occlusion_power: float = 1.0) -> torch.Tensor:
    """``mix(OcclusionColor, color, ao^OcclusionPower)`` per pixel (§2.4).

    .. math::
        \\text{out} = c_{occ}\\,(1 - ao^{p}) + \\text{color}\\cdot ao^{p}

    Args:
        color: :math:`(B, 3, H, W)` colour (linear RGB).
        ao: :math:`(B, 1, H, W)` ambient visibility in [0, 1].
        occlusion_color: ``OcclusionColor``, three numbers or a tensor broadcastable to ``color``.
        occlusion_power: ``OcclusionPower`` (> 0).

    Returns:
        :math:`(B, 3, H, W)` composited colour.

    Raises:
        ValueError: bad shapes, dtypes, ``ao`` outside [0, 1] or a non-positive power (names the argument).

    Example:
        >>> color, ao = torch.ones(1, 3, 2, 2), torch.full((1, 1, 2, 2), 0.25)
        >>> composite(color, ao, (1.0, 0.0, 0.0), 0.5)[0, :, 0, 0].tolist()
        [1.0, 0.5, 0.5]
    """
    checks.check_shape(color, ["B", "C", "H", "W"], "color")
    checks.check_shape(ao, ["B", "1", "H", "W"], "ao")
    checks.check_same_size(color, ao, "color", "ao")
    if checks.checks_enabled():
        for name, t in (("color", color), ("ao", ao)):
            if not t.is_floating_point():
                raise ValueError(f"{name}: expected a floating-point dtype, got {t.dtype}")
        if bool(((ao < 0) | (ao > 1) | torch.isnan(ao)).any()):
            raise ValueError("ao: must lie in [0, 1]")
    if isinstance(occlusion_power, bool) or not isinstance(occlusion_power, (int, float)) \
            or not (0 < occlusion_power < math.inf):
        raise ValueError(f"occlusion_power: must be a finite number > 0, got {occlusion_power!r}")
    occ = _occlusion_color(occlusion_color, color)
    t = ao.to(color.dtype) ** occlusion_power                                       # (B, 1, H, W)
    return occ * (1.0 - t) + color * t                                               # mix(a, b, t)


class Composite(nn.Module):
    """:func:`composite` as a module.

    Example:
        >>> Composite(occlusion_power=2.0)(torch.ones(1, 3, 2, 2), torch.full((1, 1, 2, 2), 0.5)).max().item()
        0.25
    """

    def __init__(self, occlusion_color: ColorSpec = (0.0, 0.0, 0.0), occlusion_power: float = 1.0) -> None:
        super().__init__()
        self.occlusion_color, self.occlusion_power = occlusion_color, occlusion_power

    def forward(self, color: torch.Tensor, ao: torch.Tensor) -> torch.Tensor:
        return composite(color, ao, self.occlusion_color, self.occlusion_power)
