"""Glossy reflections the SSR article's way: the mirror march, then a blur whose width grows with roughness.

The article's demo (and many engines before stochastic SSR) traces one mirror ray per pixel with the linear
view-space march (:mod:`.linear`, §1.1–1.5) and approximates a rough surface by blurring the reflection buffer
(:func:`~ssbench.passes.ssr.resolve.roughness_blur`: a Gaussian of ``σ = roughness · max_sigma`` pixels, ``kornia``),
before the Fresnel and roughness blend of :func:`~ssbench.passes.ssr.resolve.resolve`. The blur is a screen-space
footprint: it neither widens with the ray's length nor respects depth edges, which is what the SSR-glossy section
measures against the path-traced lobe (``ssbench.reference.glossy``).

``raw_color`` and ``color`` are the blurred raw and faded reflections; the hit buffers are the mirror march's.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..gbuffer_checks import check_gbuffer
from ..inference import autograd_free
from ..registry import Method, SpeedPanel
from .common import SSRResult
from .linear import LinearSSRParams, ssr_linear
from .linear import REQUIRES as LINEAR_REQUIRES
from .resolve import roughness_blur

REQUIRES = tuple(LINEAR_REQUIRES) + ("roughness",)
DEFAULTS_SOURCE = "the SSR article's linear march at its demo's defaults, blurred by roughness (σ = 8 px at roughness 1)"
EQUAL_SETTINGS = {"thickness": "thickness", "ray_length": "max_ray_distance"}


@dataclass(frozen=True)
class BlurSSRParams(LinearSSRParams):
    """:class:`~ssbench.passes.ssr.linear.LinearSSRParams` plus the blur: ``max_sigma`` (pixels at roughness 1,
    ≥ 0) and ``levels`` (σ levels interpolated per pixel, ≥ 2)."""

    max_sigma: float = 8.0
    levels: int = 5

    def __post_init__(self) -> None:
        super().__post_init__()
        ok = not isinstance(self.max_sigma, bool) and isinstance(self.max_sigma, (int, float))
        if not ok or not 0 <= self.max_sigma <= 64:
            raise ValueError(f"max_sigma: must be a number in [0, 64] pixels, got {self.max_sigma!r}")
        if isinstance(self.levels, bool) or not isinstance(self.levels, int) or not 2 <= self.levels <= 32:
            raise ValueError(f"levels: must be an integer in [2, 32], got {self.levels!r}")

    def linear(self) -> LinearSSRParams:
        """The mirror march's parameters."""
        return LinearSSRParams(**{f.name: getattr(self, f.name) for f in dataclasses.fields(LinearSSRParams)})


def required_channels(params: BlurSSRParams) -> tuple[str, ...]:
    """The linear march's channels for ``params`` plus ``roughness``."""
    from .linear import required_channels as linear_channels
    return tuple(linear_channels(params.linear())) + ("roughness",)


@autograd_free
def ssr_glossy_blur(gbuffer: GBuffer, params: BlurSSRParams = BlurSSRParams(), *,
                    generator: Optional[torch.Generator] = None, debug: bool = False) -> SSRResult:
    """The mirror linear march, its colours blurred by roughness (module docstring).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n, mask=torch.ones(1, 1, 6, 8,
        ...             dtype=torch.bool), color=torch.ones(1, 3, 6, 8), roughness=torch.full((1, 1, 6, 8), 0.3))
        >>> ssr_glossy_blur(g).raw_color.shape
        torch.Size([1, 3, 6, 8])
    """
    if not isinstance(params, BlurSSRParams):
        raise TypeError(f"params: expected BlurSSRParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, required_channels(params), finite=("color", "roughness"), meta_ok=False)
    r = ssr_linear(gbuffer, params.linear(), generator=generator, debug=debug)
    rough = gbuffer.roughness.to(r.raw_color.dtype)
    blur = lambda x: roughness_blur(x, rough, float(params.max_sigma), params.levels)   # noqa: E731
    return dataclasses.replace(r, raw_color=blur(r.raw_color), color=blur(r.color))


class BlurSSR(nn.Module):
    """``nn.Module`` wrapper of :func:`ssr_glossy_blur`."""

    def __init__(self, params: BlurSSRParams = BlurSSRParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> SSRResult:
        return ssr_glossy_blur(gbuffer, self.params, generator=generator, debug=self.debug)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("glossy_blur", ssr_glossy_blur, BlurSSRParams, BlurSSR, order=55,
                title="the article's mirror march blurred by roughness")
#: a glossy method: the SSR-glossy section scores its colour against the path-traced lobe
GLOSSY = True
SPEED_GRIDS = {"cost": [{"max_sigma": [4.0, 8.0, 16.0]}]}
SPEED_PANELS = (SpeedPanel("hits", "max_sigma", ()),)
