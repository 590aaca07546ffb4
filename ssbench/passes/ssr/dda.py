"""Screen-space reflections by perspective-correct DDA (McGuire & Mara 2014), after the SSR article (§2.2) and G3D.

The mirror ray (``reflection_rays``) is clipped at the near plane (``clip_ray_length``); both ends are projected
to **pixels** (``H = M_pix·(c, 1)``, ``k = 1/H.w``, ``Q = c·k``, ``P = H.xy·k``); ``P0 → P1`` is walked one
``pixelStride`` at a time along its major axis (``permute`` swaps x and y for steep lines). ``Q`` and ``k`` are
linear in screen space (appendix A), so the ray's view z at a sample is ``Q.z / k``:

.. math::
    \\{\\text{rayZMin}, \\text{rayZMax}\\} = \\{\\frac{Q.z \\mp \\tfrac12 dQ.z}{k \\mp \\tfrac12 dk}\\}, \\qquad
    \\text{hit} \\iff \\text{rayZMax} \\ge \\text{sceneZMax} - \\text{zThickness} \\wedge
    \\text{rayZMin} \\le \\text{sceneZMax}

**The half step** (which the article admits not understanding) makes the tested interval the ray's z extent over
the sample's own footprint ``[P − ½dP, P + ½dP]`` (one pixel column at stride 1): ``rayZMax`` is z half a step
ahead, ``rayZMin`` the previous step's (``prevZMaxEstimate``), swapped for rays toward the camera. Each texel is a
solid box ``[sceneZMax − zThickness, sceneZMax]``. ``rayZMax`` is clamped to the segment's z range (G3D): half a
step past the end ``k`` can reach 0.

Fixes and choices (against McGuire & Mara 2014, G3D's ``screenSpaceRayTrace.glsl`` and kode80;
``ssbench/REFERENCES.md``):

* ``P`` is in pixels (py down, ``CONVENTIONS.md``): the 0.01 px nudge and the stride are pixels, not NDC units.
  ``pixel_stride`` is pixels per step near the camera, ``1 + s·(pixel_stride − 1)``, ``s = 1 − min(1, −rayOrg.z /
  PixelStrideZCutoff)`` (kode80's ``1 + s·PixelStride`` is one more than its comment says). The PDF's
  ``dP += pixelStride`` is ``*=`` (web twin, G3D). ``fit_stride_to_steps`` (ours) raises each ray's stride to
  ``ceil(|P1 − P0|_major / max_steps)`` (after near clipping), so ``max_steps`` samples span the whole segment:
  ``OUT_OF_STEPS`` only if sample ``max_steps`` lands exactly on ``P1``; the cutoff scales only the
  ``pixel_stride`` floor, so it never shrinks a stride below the fitted one.
* The article and G3D start the interval at the origin (``zB = Q0.z``, homogeneous, in the text; ``rayOrg.z``
  in code), which self-hits a wall facing the camera on step 1; here ``prevZMaxEstimate`` starts at the first
  sample's footprint edge ``z(P0 + (jitter + ½)·dP)``.
* The loop advances before it tests (the origin pixel is never sampled) and stops at ``P1`` (G3D). The hit point
  is ``Q/k`` with ``Q.xy = Q0.xy + dQ.xy·n`` for the ``n`` advances made (the article's ``count = i`` lags one).
* Past ``P1`` → ``MAX_DISTANCE`` (``BEHIND_CAMERA`` if the near plane clipped the ray); off screen →
  ``OFF_SCREEN``; budget spent → ``OUT_OF_STEPS``, never a hit. Background texels (−far) are never hit.
  (ours) A sample whose centre passes ``stop`` = ``P1`` or the viewport edge, whichever comes first, while its
  footprint starts before it, is still tested once over the shortened footprint ``[P − ½dP, stop]``, fetched at
  that part's centre; the reason, if it misses, is the full step's. Without it the strip between the last
  footprint and the edge (up to ½ stride, e.g. a target in row 0) was never tested, and which targets were
  caught depended on the stride's phase (K = 64 missed more than K = 32 under ``fit_stride_to_steps``).
* Refinement only where the stride exceeds 1 px (as both anchors): ``"binary"`` is the article's ±stride walk
  over the hit sample's footprint (the article backs off a whole step and misses crossings in the far half, which
  the coarse test accepts) with the predicate "ray at or behind the probe's texel" (:func:`refine_hits`);
  ``"remarch"`` is G3D's: back off one stride, walk single pixels up to ``1.4·stride`` until ``rayZMin ≤
  sceneZMax``.
* Jitter: every pixel draws ``U[0, 1)·jitter`` strides from the seeded generator (the article dithers
  ``mod((x + y)/4, 1)``). Fades as the article and :mod:`.linear`: vignette at ``vUv``, circular at the hit.
* Limits (pinned in the tests): one sample per major-axis pixel line, so pixels whose corner the segment clips
  are skipped (Fig. 11's "no oversampling", not a supercover: :mod:`.dda_supercover` walks every crossed
  pixel once, :mod:`.visits` draws both); a stride wider than a feature steps over it
  (punch-through); a ray grazing the surface it hits stops up to ~½/slope px early (texels are flat boxes).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import check_count, make_generator
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from .common import SSRResult, nan_off_mask
from .dda_assemble import assemble
from .dda_march import dda_march
from .dda_rays import dda_rays, ray_pixels
from .dda_state import DepthTexels, march_in_chunks
from .fade import FadeParams
from ..registry import Method, SpeedPanel

REQUIRES = ("view_z", "normal", "mask", "color")
REQUIRES_BACKFACE = ("back_z",)
REQUIRES_SECOND_LAYER = ("second_z",)
#: where the defaults come from (shown by the report next to the parameters)
DEFAULTS_SOURCE = ('McGuire & Mara, "Efficient GPU Screen-Space Ray Tracing", JCGT 3(4), 2014, as kode80 and '
                   'mebiusbox/ssr ship it (thickness 0.1, max distance 10, stride 1, 4 bisections)')
#: the parameters that play the shared roles of an equal-settings comparison (:func:`ssbench.evaluate.equal_settings`)
EQUAL_SETTINGS = {"thickness": "z_thickness", "ray_length": "max_ray_distance"}
REFINEMENTS = ("binary", "remarch", "none")


@dataclass(frozen=True)
class DDASSRParams(FadeParams):
    """Parameters of :func:`ssr_dda`: the article's / G3D's names snake-cased (defaults: kode80, mebiusbox).

    Attributes:
        max_ray_distance: ``MaxRayDistance``, view-space ray length before near-plane clipping.
        max_steps: ``Iterations`` / ``maxSteps``, the most DDA samples per ray.
        pixel_stride: pixels per step near the camera (≥ 1); ``pixel_stride_z_cutoff``: ``PixelStrideZCutoff``,
            origins at ``z ≤ −cutoff`` step 1 px (``math.inf``: ``pixel_stride`` everywhere).
        fit_stride_to_steps: per ray, stride = max(that stride, ``ceil(major-axis px of the clipped segment /
            max_steps)``): the budget always reaches ``P1`` (at the default ``pixel_stride=1``: ``max(1, ceil(…))``).
        z_thickness: ``zThickness`` / ``PixelZSize``, view-space depth of every depth texel.
        jitter: the start moves ``jitter·U[0, 1)`` strides along the ray (0 = off); ``seed`` seeds it.
        binary_search_iterations, refinement: ``"binary"`` (article, that many probes), ``"remarch"`` (G3D) or
            ``"none"``.
        use_back_face_depth: layered depth (kode80's back-face buffer): a texel is the slab from its depth down to
            ``back_z − z_thickness`` (needs ``back_z``) instead of ``z_thickness`` deep.
        use_second_layer: also test the second depth layer (``second_z``, the surface behind the first object,
            ``z_thickness`` deep; G3D's ``traceScreenSpaceRay2``): rays pass behind a thin object and still hit
            what it hides.
        edge_distance, edge_exponent, edge_fade_mode, fade_distance, fade_exponent: the fades (§1.4–1.5),
            inherited keyword-only from :class:`~ssbench.passes.ssr.fade.FadeParams`.
    """

    max_ray_distance: float = 10.0
    max_steps: int = 256
    pixel_stride: float = 1.0
    pixel_stride_z_cutoff: float = 100.0
    fit_stride_to_steps: bool = False
    z_thickness: float = 0.1
    jitter: float = 0.0
    binary_search_iterations: int = 4
    refinement: str = "binary"
    seed: int = 0
    use_back_face_depth: bool = False
    use_second_layer: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()                                                   # the fades
        check_count(self.max_steps, "max_steps")
        n = self.binary_search_iterations
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f"binary_search_iterations: must be an integer >= 0, got {n!r}")
        if not isinstance(self.fit_stride_to_steps, bool):
            raise ValueError(f"fit_stride_to_steps: must be a bool, got {self.fit_stride_to_steps!r}")
        for name in ("use_back_face_depth", "use_second_layer"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: must be a bool, got {getattr(self, name)!r}")
        for name, lo, strict in (("max_ray_distance", 0, 1), ("pixel_stride", 1, 0), ("pixel_stride_z_cutoff", 0, 1),
                                 ("z_thickness", 0, 0), ("jitter", 0, 0)):
            v = getattr(self, name)
            ok = not isinstance(v, bool) and isinstance(v, (int, float)) and v == v and v >= lo
            if not ok or (strict and v == lo) or (v == math.inf and name != "pixel_stride_z_cutoff"):
                raise ValueError(f"{name}: must be a finite number {'>' if strict else '>='} {lo}, got {v!r}")
        if self.refinement not in REFINEMENTS:
            raise ValueError(f"refinement: expected one of {REFINEMENTS}, got {self.refinement!r}")


def jitter_fractions(params: DDASSRParams, shape, generator: torch.Generator) -> torch.Tensor:
    """``jitter·U[0, 1)`` per pixel, float64 :math:`(B, 1, H, W)`; one ``torch.rand`` call (twin draws the same)."""
    return torch.rand(tuple(shape), generator=generator, dtype=torch.float64) * params.jitter


def check_inputs(gbuffer: GBuffer, params: DDASSRParams) -> None:
    """Type checks of ``params`` and the shared G-buffer contract
    (:func:`~ssbench.passes.gbuffer_checks.check_gbuffer`)."""
    if not isinstance(params, DDASSRParams):
        raise TypeError(f"params: expected DDASSRParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, required_channels(params), finite=("color",), meta_ok=False)


def required_channels(params: DDASSRParams) -> tuple[str, ...]:
    """The channels :func:`ssr_dda` reads with ``params`` (``back_z`` with ``use_back_face_depth``, ``second_z``
    with ``use_second_layer``)."""
    return REQUIRES + (REQUIRES_BACKFACE if params.use_back_face_depth else ()) + \
        (REQUIRES_SECOND_LAYER if params.use_second_layer else ())


#: rays marched at once: a bounded working set (~600 MiB at 1080p) in few chunks, each paying per-step overhead
#: for its long tail (2¹⁸ rather than 2¹⁶: compiled 1.4× faster at 640×360, eager 1.2× at 1080p)
MARCH_CHUNK = 1 << 18


def depth_texels(gbuffer: GBuffer, params: DDASSRParams) -> DepthTexels:
    """``view_z``, ``mask``, ``back_z`` (or None) and ``second_z`` (or None) flattened, and the step kernel's
    NaN-off-mask copies of the depths: what the march reads per texel (:class:`DepthTexels`)."""
    flat = lambda x, on: x.to(gbuffer.view_z.dtype).reshape(-1) if on else None   # noqa: E731
    z, mask = gbuffer.view_z.reshape(-1), gbuffer.mask.reshape(-1)
    back, second = flat(gbuffer.back_z, params.use_back_face_depth), flat(gbuffer.second_z, params.use_second_layer)
    marched = tuple(None if x is None else nan_off_mask(x, mask) for x in (z, back, second))
    return DepthTexels(z, mask, back, second, marched)


@autograd_free
@half_in_float32
def ssr_dda(gbuffer: GBuffer, params: DDASSRParams = DDASSRParams(), *, generator: Optional[torch.Generator] = None,
            debug: bool = False) -> SSRResult:
    """Screen-space reflections by perspective-correct DDA (SSR article §2.2), vectorised over pixels.

    Args:
        gbuffer: needs ``view_z``, ``normal`` (unit, view space), ``mask`` and ``color``, all :math:`(B, C, H, W)`.
        params: :class:`DDASSRParams`.
        generator: draws the jitter (default: a CPU generator seeded with ``params.seed``).
        debug: add ``visits`` :math:`(B, 1, H, W)` (depth fetches per texel over all rays, refinement included)
            and ``ray_end`` :math:`(B, 2, H, W)` (``P1`` in pixels after the nudge, −1 off ``mask``).

    Returns:
        :class:`~ssbench.passes.ssr.common.SSRResult`; ``color`` is ``gbuffer.color`` at the hit texel times
        ``edge_fade · distance_fade(|hit_view − rayOrg|)`` (``ssbench.passes.ssr.fade``); ``steps`` counts depth
        fetches (DDA samples and refinement probes).

    Raises:
        ValueError: missing channels, bad values (the message names the argument).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n,
        ...             mask=torch.ones(1, 1, 6, 8, dtype=torch.bool), color=torch.ones(1, 3, 6, 8))
        >>> r = ssr_dda(g)                          # a wall facing the camera reflects toward the camera
        >>> r.hit.any().item(), r.termination.unique().tolist(), r.color.shape
        (False, [2], torch.Size([1, 3, 6, 8]))
    """
    check_inputs(gbuffer, params)
    B, _, H, W = gbuffer.view_z.shape
    jitter = jitter_fractions(params, (B, 1, H, W), make_generator(params.seed, generator))
    sel = ray_pixels(gbuffer)
    visits = torch.zeros(B * H * W, dtype=torch.int32, device=gbuffer.view_z.device) if debug else None
    tex = depth_texels(gbuffer, params)
    o, P1 = march_in_chunks(sel, lambda part: dda_rays(gbuffer, params, jitter, part),
                            lambda rays: dda_march(rays, tex, params, H, W, visits), chunk=MARCH_CHUNK)
    return assemble(gbuffer, params, sel, P1, o, visits)


class DDASSR(nn.Module):
    """``nn.Module`` wrapper of :func:`ssr_dda`; ``forward(gbuffer)`` returns its :class:`SSRResult`."""

    def __init__(self, params: DDASSRParams = DDASSRParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> SSRResult:
        return ssr_dda(gbuffer, self.params, generator=generator, debug=self.debug)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("dda", ssr_dda, DDASSRParams, DDASSR, order=20, title="perspective-correct DDA (McGuire & Mara 2014)")

#: the debug buffers the report draws (``debug=True`` results): buffer -> caption; each is a per-pixel count
#: shown on a log scale (the SSR article's Fig. 11 visit map)
DEBUG_VIEWS = {"visits": "depth fetches per texel"}
#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"max_steps": [32, 128], "pixel_stride": 1}, {"max_steps": 128, "pixel_stride": 4},
                        {"max_steps": 128, "pixel_stride": 1, "z_thickness": [0.02, 0.5]},
                        {"max_steps": 128, "pixel_stride": 4, "jitter": 1.0}]}
SPEED_PANELS = (SpeedPanel("hits", "max_steps", (("jitter", 0.0), ("z_thickness", 0.1), ("pixel_stride", 1.0))),
                SpeedPanel("hits", "pixel_stride", (("jitter", 0.0), ("z_thickness", 0.1), ("max_steps", 128))),
                SpeedPanel("hits", "z_thickness", (("max_steps", 128), ("pixel_stride", 1.0))),
                SpeedPanel("hits", "jitter", (("max_steps", 128), ("pixel_stride", 4.0), ("z_thickness", 0.1))))
#: the depth-read budget of an equal-reads comparison (ssbench.analysis.equal_reads): the parameter that caps
#: reads, and the settings that make every read count:
#: the stride is fitted so the budget spans the whole ray; no refinement probes
READ_BUDGET = ("max_steps", {"fit_stride_to_steps": True, "refinement": "none"})
