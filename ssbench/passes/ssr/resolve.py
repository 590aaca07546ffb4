"""SSR resolve: blur the reflection buffer by roughness and blend it into the scene colour (SSR article §1.4–1.5).

A simple, explicit model, enough to show what the hit buffer is worth in a picture:

.. math::

    F = F_0 + (1 - F_0)(1 - \\cos\\theta)^5, \\quad F_0 = \\mathrm{lerp}(0.04, \\text{albedo}, \\text{metallic})

    \\text{out} = \\text{color} + F \\cdot (1 - \\text{roughness}) \\cdot \\text{blur}_{\\sigma(\\text{roughness})}(\\text{reflection})

``cos θ = n · (−P/|P|)`` (Schlick's Fresnel at the viewing angle). ``base`` is the colour *without* specular
reflections (an engine's lit diffuse buffer). ssbench's reference ``color`` is path traced and already holds
the reflections of metals, so the default base is ``color · (1 − metallic)``: a perfect mirror then shows only
what SSR found, which is directly comparable with the path-traced image. The blur is a Gaussian (``kornia``) whose
σ grows linearly with roughness, evaluated on a few σ levels and interpolated per pixel. The reflection
buffer is expected *with* the pass's fades (``SSRResult.color``); pixels where the pass found nothing add 0.
"""
from __future__ import annotations

from dataclasses import dataclass

import kornia
import torch
from torch import nn

from ... import checks
from ...gbuffer import GBuffer
from ..common import length

REQUIRES = ("position", "normal", "albedo", "roughness", "metallic", "color")


@dataclass(frozen=True)
class ResolveParams:
    """``max_sigma``: blur σ in pixels at roughness 1; ``levels``: σ levels interpolated per pixel;
    ``f0_dielectric``: Fresnel reflectance at normal incidence of non-metals."""

    max_sigma: float = 8.0
    levels: int = 5
    f0_dielectric: float = 0.04

    def __post_init__(self) -> None:
        if not self.max_sigma >= 0:
            raise ValueError(f"max_sigma: must be >= 0, got {self.max_sigma!r}")
        if isinstance(self.levels, bool) or not isinstance(self.levels, int) or self.levels < 2:
            raise ValueError(f"levels: must be an integer >= 2, got {self.levels!r}")
        if not 0 <= self.f0_dielectric <= 1:
            raise ValueError(f"f0_dielectric: must lie in [0, 1], got {self.f0_dielectric!r}")


def schlick_fresnel(cos_theta: torch.Tensor, f0: torch.Tensor) -> torch.Tensor:
    """Schlick's approximation ``F0 + (1 − F0)(1 − cos θ)^5``; ``cos θ`` is clamped to [0, 1]."""
    return f0 + (1.0 - f0) * (1.0 - cos_theta.clamp(0.0, 1.0)) ** 5


def roughness_blur(reflection: torch.Tensor, roughness: torch.Tensor, max_sigma: float, levels: int) -> torch.Tensor:
    """Blur :math:`(B, C, H, W)` with σ = roughness · max_sigma, by per-pixel interpolation between ``levels`` σ
    levels ``0 … max_sigma`` (:func:`kornia.filters.gaussian_blur2d`): ``a + (b − a)·frac`` of the two levels around
    the pixel's σ. Only the levels some pixel weighs are blurred (a scene of mirrors and one rough material needs
    two of five): a level read only with weight ``frac = 0`` stands in unblurred, which gives the same bits for a
    finite ``reflection`` (``a + (b − a)·0 = a``). A NaN roughness is a ``ValueError`` naming ``roughness``."""
    checks.check_finite(roughness, "roughness")
    pos = roughness.clamp(0, 1) * (levels - 1)                         # (B, 1, H, W)
    lo = pos.floor().long().clamp(max=levels - 2)
    frac = pos - lo
    weight = torch.bincount(lo.reshape(-1), minlength=levels) + \
        torch.bincount((lo + 1).reshape(-1), weights=frac.reshape(-1), minlength=levels)   # (not a sort: unique's)
    weighed = set(weight.nonzero().reshape(-1).tolist())
    blurred = {}                                                       # level -> image, for the blurred levels
    for i, s in enumerate(torch.linspace(0.0, max_sigma, levels).tolist()):   # a handful of levels, not pixels
        if s >= 1e-3 and i in weighed:
            k = 2 * int(3 * s) + 1
            blurred[i] = kornia.filters.gaussian_blur2d(reflection, (k, k), (s, s), border_type="replicate")

    def level(index: torch.Tensor) -> torch.Tensor:                    # each pixel's level ``index`` (B, 1, H, W)
        out = reflection                                               # σ = 0 and the levels no pixel weighs
        for i, image in blurred.items():
            out = torch.where(index == i, image, out)
        return out

    a, b = level(lo), level(lo + 1)
    return a + (b - a) * frac


def specular_weight(gbuffer: GBuffer, params: ResolveParams = ResolveParams()) -> torch.Tensor:
    """The blend weight of the reflection, ``F · (1 − roughness)`` :math:`(B, 3, H, W)`: Schlick's Fresnel at the
    viewing angle, ``F0 = lerp(f0_dielectric, albedo, metallic)``, times the article demo's roughness fade.
    Applied to a glossy reflection (the lobe-averaged radiance), it is this resolve's estimate of the specular
    radiance (``ssbench.reference.glossy``'s ``specular``)."""
    gbuffer.require("position", "normal", "albedo", "roughness", "metallic")
    p = gbuffer.position
    v = -p / length(p).clamp_min(torch.finfo(p.dtype).tiny)
    cos_theta = (gbuffer.normal * v).sum(1, keepdim=True)
    f0 = params.f0_dielectric + (gbuffer.albedo - params.f0_dielectric) * gbuffer.metallic
    return schlick_fresnel(cos_theta, f0) * (1.0 - gbuffer.roughness)


def resolve(gbuffer: GBuffer, reflection: torch.Tensor, params: ResolveParams = ResolveParams(),
            base: torch.Tensor | None = None) -> torch.Tensor:
    """Scene colour plus the Fresnel-weighted, roughness-blurred reflection.

    Args:
        gbuffer: with ``position``, ``normal``, ``albedo``, ``roughness``, ``metallic``, ``color``.
        reflection: :math:`(B, 3, H, W)` reflection colour from an SSR pass (``SSRResult.color``).
        base: :math:`(B, 3, H, W)` colour without specular reflections (default ``color · (1 − metallic)``).

    Returns:
        :math:`(B, 3, H, W)` resolved colour (background pixels keep ``gbuffer.color``).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
        >>> z = lambda c, v=0.0: torch.full((1, c, 3, 4), v)
        >>> g = GBuffer(cam, position=z(3, -1.0), normal=torch.cat([z(2), z(1, 1.0)], 1), albedo=z(3, 0.5),
        ...             roughness=z(1), metallic=z(1, 1.0), color=z(3), mask=torch.ones(1, 1, 3, 4, dtype=torch.bool))
        >>> resolve(g, z(3, 1.0)).shape
        torch.Size([1, 3, 3, 4])
    """
    gbuffer.require(*REQUIRES)
    checks.check_shape(reflection, ["B", "3", str(gbuffer.height), str(gbuffer.width)], "reflection")
    blurred = roughness_blur(reflection, gbuffer.roughness, params.max_sigma, params.levels)
    if base is None:
        base = gbuffer.color * (1.0 - gbuffer.metallic)
    checks.check_shape(base, ["B", "3", str(gbuffer.height), str(gbuffer.width)], "base")
    out = base + specular_weight(gbuffer, params) * blurred
    mask = gbuffer.mask if gbuffer.mask is not None else torch.ones_like(blurred[:, :1], dtype=torch.bool)
    return torch.where(mask, out, gbuffer.color)


class Resolve(nn.Module):
    """Module form of :func:`resolve`."""

    def __init__(self, params: ResolveParams = ResolveParams()) -> None:
        super().__init__()
        self.params = params

    def forward(self, gbuffer: GBuffer, reflection: torch.Tensor, base: torch.Tensor | None = None) -> torch.Tensor:
        return resolve(gbuffer, reflection, self.params, base)
