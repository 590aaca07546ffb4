"""Screen-space reflections by hierarchical depth (Hi-Z) traversal, as FidelityFX SSSR and Unity HDRP ship it.

The article's marchers read one texel per step (:mod:`.linear`, :mod:`.dda`); a Hi-Z march reads a *pyramid* of
closest depths (:mod:`.hiz_pyramid`) and skips every tile the ray passes in front of, climbing one level after
each skip and descending when the ray reaches a tile's closest depth — ``O(log n)`` reads for a ray over empty
space instead of ``O(n)`` (Uludag, "Hi-Z Screen-Space Cone-Traced Reflections", GPU Pro 5, 2014; the stackless
form of AMD's FidelityFX SSSR, 2020, ``FFX_SSSR_HierarchicalRaymarch``). The traversal, step by step, is in
:mod:`.hiz_march`; its per-pixel teaching twin is :mod:`ssbench.passes.teaching.ssr_hiz_basic`.

What differs from the anchors (each pinned by a test in ``tests/passes/ssr/test_hiz.py``):

* the ray is clipped at the near plane before it is projected (FidelityFX ``ProjectDirection(o + d)`` flips for
  rays toward the camera that cross ``w = 0``);
* running out of iterations is ``OUT_OF_STEPS``, never a hit (FidelityFX's ``valid_hit`` is always true);
* the thickness is in view units (``"constant"``, FidelityFX's confidence band) or relative to the surface's
  depth (``"relative"``, HDRP's ``(1 + thickness)·linZ``, which is ``100×`` thicker at ``z = −100`` than at
  ``z = −1``); with ``use_back_face_depth`` the surface reaches down to ``back_z`` (layered depth, as in
  :mod:`.linear`);
* cells are addressed in pixels, so any image size works (see :mod:`.hiz_pyramid`).

Outputs, fades and colours as the DDA's (:func:`~ssbench.passes.ssr.dda_assemble.assemble`); ``steps`` counts
pyramid reads. ``debug=True`` adds ``visits`` (level-0 reads per texel), ``ray_end`` and ``reads_per_level``
(:math:`(L,)` reads summed over all rays, level 0 first).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import check_count, check_positive
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from ..registry import Method, SpeedPanel
from .common import SSRResult
from .dda_rays import ray_pixels
from .dda_assemble import assemble
from .dda_state import march_in_chunks
from .fade import FadeParams
from .hiz_march import RAY_CHUNK, HiZTexels, hiz_march, hiz_rays, index_dtype, march_layers
from .hiz_pyramid import depth_pyramid, reversed_depth

REQUIRES = ("view_z", "normal", "mask", "color")
REQUIRES_BACKFACE = ("back_z",)
REQUIRES_SECOND_LAYER = ("second_z",)
DEFAULTS_SOURCE = ("FidelityFX SSSR (AMD, 2020): 128 traversal iterations, depth-buffer thickness 0.015, "
                   "back faces rejected, no ray-length limit (here 1000 view units); the article's fades")
EQUAL_SETTINGS = {"thickness": "depth_buffer_thickness", "ray_length": "max_ray_distance"}
THICKNESS_MODES = ("constant", "relative")


@dataclass(frozen=True)
class HiZSSRParams(FadeParams):
    """Parameters of :func:`ssr_hiz`, FidelityFX SSSR's names snake-cased.

    Attributes:
        max_traversal_intersections: ``max_traversal_intersections``, the most pyramid reads per ray.
        depth_buffer_thickness: ``depth_buffer_thickness``: how far behind a surface (view units) a ray still
            hits it; with ``thickness_mode="relative"``, a fraction of the surface's ``|z|`` (HDRP).
        max_ray_distance: view-space ray length before near-plane clipping.
        max_mip: the highest pyramid level the ray climbs to (the FidelityFX SDK builds 7 levels, 0–6).
        reject_backfaces: a texel facing away from the ray is not a hit (FidelityFX ``dot(n, d) > 0``).
        trace_behind: a rejected candidate does not end the ray; it crosses the texel and goes on (HDRP).
        use_back_face_depth: a surface extends from its depth down to ``back_z`` (needs ``back_z``).
        use_second_layer: a ray behind a level-0 texel but in front of the second depth layer (``second_z``: the
            surface the first object hides; −inf, nothing behind it) crosses the texel and goes on, and hits that
            layer where it reaches it inside the texel or within the thickness behind it (G3D's multi-layer
            tracing; needs ``second_z``).
        edge_distance, edge_exponent, edge_fade_mode, fade_distance, fade_exponent: the article's fades, inherited
            keyword-only from :class:`~ssbench.passes.ssr.fade.FadeParams`.
    """

    max_traversal_intersections: int = 128
    depth_buffer_thickness: float = 0.015
    thickness_mode: str = "constant"
    max_ray_distance: float = 1000.0
    max_mip: int = 6
    reject_backfaces: bool = True
    trace_behind: bool = False
    use_back_face_depth: bool = False
    use_second_layer: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        check_count(self.max_traversal_intersections, "max_traversal_intersections")
        check_positive(self.depth_buffer_thickness, "depth_buffer_thickness", allow_zero=True)
        check_positive(self.max_ray_distance, "max_ray_distance")
        for name in ("depth_buffer_thickness", "max_ray_distance"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: must be finite, got {getattr(self, name)!r}")
        if isinstance(self.max_mip, bool) or not isinstance(self.max_mip, int) or self.max_mip < 0:
            raise ValueError(f"max_mip: must be an integer >= 0, got {self.max_mip!r}")
        if self.thickness_mode not in THICKNESS_MODES:
            raise ValueError(f"thickness_mode: expected one of {THICKNESS_MODES}, got {self.thickness_mode!r}")
        for name in ("reject_backfaces", "trace_behind", "use_back_face_depth", "use_second_layer"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected True or False, got {getattr(self, name)!r}")


def required_channels(params: HiZSSRParams) -> tuple[str, ...]:
    """The channels :func:`ssr_hiz` reads with ``params`` (``back_z`` only with ``use_back_face_depth``,
    ``second_z`` only with ``use_second_layer``)."""
    return REQUIRES + (REQUIRES_BACKFACE if params.use_back_face_depth else ()) + \
        (REQUIRES_SECOND_LAYER if params.use_second_layer else ())


def check_inputs(gbuffer: GBuffer, params: HiZSSRParams) -> None:
    """Type checks of ``params`` and the G-buffer contract (``back_z`` when layered depth is on)."""
    if not isinstance(params, HiZSSRParams):
        raise TypeError(f"params: expected HiZSSRParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, required_channels(params), finite=("color",), meta_ok=False)


def texels(gbuffer: GBuffer, params: HiZSSRParams) -> HiZTexels:
    """The flat per-texel buffers candidates are validated against."""
    dt = gbuffer.view_z.dtype
    back = gbuffer.back_z.to(dt).reshape(-1) if params.use_back_face_depth else None
    second = gbuffer.second_z.to(dt).reshape(-1) if params.use_second_layer else None
    return HiZTexels(view_z=gbuffer.view_z.reshape(-1), normal=gbuffer.normal.to(dt).transpose(0, 1).reshape(3, -1),
                     back_z=back, second_z=second)


@autograd_free
@half_in_float32
def ssr_hiz(gbuffer: GBuffer, params: HiZSSRParams = HiZSSRParams(), *, generator: Optional[torch.Generator] = None,
            debug: bool = False) -> SSRResult:
    """Hi-Z screen-space reflections (module docstring), vectorised over pixels; ``generator`` is unused.

    Args:
        gbuffer: ``view_z``, ``normal`` (unit, view space), ``mask``, ``color`` (and ``back_z`` with
            ``use_back_face_depth``), all :math:`(B, C, H, W)`.
        params: :class:`HiZSSRParams`.
        debug: add ``visits`` :math:`(B, 1, H, W)`, ``ray_end`` :math:`(B, 2, H, W)` and ``reads_per_level``.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n,
        ...             mask=torch.ones(1, 1, 6, 8, dtype=torch.bool), color=torch.ones(1, 3, 6, 8))
        >>> r = ssr_hiz(g)                          # a wall facing the camera reflects toward the camera
        >>> r.hit.any().item(), r.termination.unique().tolist()
        (False, [2])
    """
    check_inputs(gbuffer, params)
    return march_hiz(gbuffer, params, None, debug)


def march_hiz(gbuffer: GBuffer, params: HiZSSRParams, directions: Optional[torch.Tensor] = None,
              debug: bool = False) -> SSRResult:
    """The Hi-Z march of :func:`ssr_hiz` along ``directions`` :math:`(B, 3, H, W)` (unit, view space; ``None``:
    the mirror rays), inputs already checked. Glossy SSR (:mod:`.glossy_stochastic`) marches sampled rays."""
    B, _, H, W = gbuffer.view_z.shape
    dev = gbuffer.view_z.device
    pyr = depth_pyramid(reversed_depth(gbuffer.view_z, gbuffer.mask, gbuffer.camera.near))
    tex = texels(gbuffer, params)
    layers = march_layers(pyr, params.max_mip, gbuffer)                          # (once: every chunk reads it)
    sel = ray_pixels(gbuffer)
    visits = torch.zeros(B * H * W, dtype=torch.int32, device=dev) if debug else None
    level_reads = torch.zeros(pyr.count, dtype=torch.long, device=dev) if debug else None
    index = index_dtype(layers)                                                  # int32 while indices fit
    o, P1 = march_in_chunks(sel, lambda part: hiz_rays(gbuffer, params.max_ray_distance, part, directions, index),
                            lambda rays: hiz_march(rays, layers, tex, params, gbuffer, visits, level_reads),
                            chunk=RAY_CHUNK)
    result = assemble(gbuffer, params, sel, P1, o, visits)
    if debug:
        result.debug["reads_per_level"] = level_reads.cpu()
    return result


class HiZSSR(nn.Module):
    """``nn.Module`` wrapper of :func:`ssr_hiz`; ``forward(gbuffer)`` returns its :class:`SSRResult`."""

    def __init__(self, params: HiZSSRParams = HiZSSRParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> SSRResult:
        return ssr_hiz(gbuffer, self.params, generator=generator, debug=self.debug)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("hiz", ssr_hiz, HiZSSRParams, HiZSSR, order=35,
                title="hierarchical-depth (Hi-Z) traversal (FidelityFX SSSR / HDRP)")
DEBUG_VIEWS = {"visits": "level-0 pyramid reads per texel"}
SPEED_GRIDS = {"cost": [{"max_traversal_intersections": [16, 32, 64, 128]},
                        {"max_traversal_intersections": 128, "trace_behind": True}]}
SPEED_PANELS = (SpeedPanel("hits", "max_traversal_intersections", (("trace_behind", False),)),)
#: the depth-read budget of an equal-reads comparison (ssbench.analysis.equal_reads): the parameter that caps
#: reads, and the settings that make every read count:
#: one pyramid read per iteration; back faces accepted like the other marchers
READ_BUDGET = ("max_traversal_intersections", {"reject_backfaces": False})
