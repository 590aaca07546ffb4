"""Stochastic (glossy) screen-space reflections: GGX rays per pixel, marched with Hi-Z, resolved with ray reuse.

After Stachowiak, "Stochastic Screen-Space Reflections" (SIGGRAPH 2015, Frostbite) and FidelityFX SSSR:

1. **Rays.** Per pixel, ``rays_per_pixel`` microfacet normals from the GGX distribution of normals visible from
   the viewer (:func:`~ssbench.passes.ssr.ggx.sample_vndf`, ``α = roughness²``), reflected; each ray is marched by
   the Hi-Z traversal (:func:`~ssbench.passes.ssr.hiz.march_hiz`). A ray below the surface returns nothing. At
   roughness 0 the only normal is ``n``: the pass is the mirror Hi-Z march.
2. **Resolve** (``reuse``):

   * ``"none"``: the mean of the rays' hit colours (a miss adds 0): an unbiased estimate of the lobe-averaged
     radiance the G-buffer can show, noisy with one ray per pixel;
   * ``"neighbours"`` (Stachowiak's ray reuse): pixel ``i`` also takes the hits of its neighbours ``j`` within
     ``reuse_radius``, each weighted by how likely *its own* lobe was to send a ray there, divided by how likely
     ``j``'s lobe was: ``w = p_i(l_ij) / p_j(l_j)`` with ``l_ij`` the direction from ``i`` to ``j``'s hit
     (``p`` = :func:`~ssbench.passes.ssr.ggx.reflection_pdf`), and returns ``Σ w·C / Σ w`` (a ratio estimator:
     consistent, lower variance, slightly biased). For a mirror pixel ``p_i`` is a spike and only its own ray
     counts.
     The sums are :func:`~ssbench.passes.ssr.glossy_reuse.reuse_ray`, a compilable kernel.

Outputs (:class:`~ssbench.passes.ssr.common.SSRResult`): ``raw_color`` the resolved lobe estimate, ``color`` the
same with each ray's fades; the hit buffers (``hit``, ``hit_pixel``, ``termination`` …) are those of the first
ray (the mirror ray at roughness 0), ``steps`` the reads of all rays. ``ssbench.evaluate.ssr_glossy`` scores the
colour against the path-traced lobe (``ssbench.reference.glossy``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import check_count, make_generator, vector_norm
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from ..registry import Method, SpeedPanel
from .common import SSRResult
from .fade import FadeParams
from .ggx import alpha_of, frame, from_local, reflection_pdf, sample_vndf, to_local
from .glossy_reuse import RaySample, ReuseFrame, ReuseSums, padded, reuse_ray
from .hiz import HiZSSRParams, march_hiz

REQUIRES = ("view_z", "normal", "mask", "color", "roughness")
DEFAULTS_SOURCE = ("Stachowiak 2015 / FidelityFX SSSR: one GGX (VNDF) ray per pixel, Hi-Z march at FidelityFX's "
                   "defaults, ray reuse over the 3×3 neighbourhood")
EQUAL_SETTINGS = {"thickness": "depth_buffer_thickness", "ray_length": "max_ray_distance"}
REUSE = ("none", "neighbours")


@dataclass(frozen=True)
class StochasticSSRParams(FadeParams):
    """Parameters of :func:`ssr_glossy_stochastic`.

    Attributes:
        rays_per_pixel: GGX rays traced per pixel.
        reuse: ``"neighbours"`` (Stachowiak's ray reuse) or ``"none"``; ``reuse_radius``: the window's half size.
        max_traversal_intersections, depth_buffer_thickness, max_ray_distance, reject_backfaces: each ray's Hi-Z
            march (:class:`~ssbench.passes.ssr.hiz.HiZSSRParams`).
        seed: seeds the directions when no generator is passed.
        edge_distance, edge_exponent, edge_fade_mode, fade_distance, fade_exponent: the article's fades.
    """

    rays_per_pixel: int = 1
    reuse: str = "neighbours"
    reuse_radius: int = 1
    max_traversal_intersections: int = 128
    depth_buffer_thickness: float = 0.015
    max_ray_distance: float = 1000.0
    reject_backfaces: bool = True
    seed: int = 0

    def __post_init__(self) -> None:
        super().__post_init__()
        check_count(self.rays_per_pixel, "rays_per_pixel")
        if self.reuse not in REUSE:
            raise ValueError(f"reuse: expected one of {REUSE}, got {self.reuse!r}")
        r = self.reuse_radius
        if isinstance(r, bool) or not isinstance(r, int) or not 0 <= r <= 8:
            raise ValueError(f"reuse_radius: must be an integer in [0, 8], got {r!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed: must be a non-negative integer, got {self.seed!r}")
        self.march()                                                              # checks the march's fields

    def march(self) -> HiZSSRParams:
        """Each ray's Hi-Z march."""
        fades = {f.name: getattr(self, f.name) for f in dataclasses.fields(FadeParams)}
        return HiZSSRParams(max_traversal_intersections=self.max_traversal_intersections,
                            depth_buffer_thickness=self.depth_buffer_thickness, max_ray_distance=self.max_ray_distance,
                            reject_backfaces=self.reject_backfaces, **fades)


def required_channels(params: StochasticSSRParams) -> tuple[str, ...]:
    """The channels :func:`ssr_glossy_stochastic` reads (``reject_backfaces`` reads normals, not ``back_z``)."""
    return REQUIRES


def ggx_ray(v_loc: torch.Tensor, alpha: torch.Tensor, basis: tuple, gen: torch.Generator) -> tuple:
    """One GGX ray per pixel (step 1): a visible normal ``m`` drawn from ``gen``, ``v`` reflected about it.
    Returns ``(l_dir, above, pdf)``: the view-space direction :math:`(B, 3, H, W)`, whether it leaves above the
    surface and its density :math:`(B, 1, H, W)` (the draws and the local frame's intermediates die here, before
    the ray is marched)."""
    t, b, n = basis
    B, _, H, W = v_loc.shape
    u = torch.rand((2, B, H, W), generator=gen, dtype=torch.float64).to(v_loc.dtype).to(v_loc.device)
    m = sample_vndf(v_loc, alpha, u[0], u[1])
    cos_vm = (v_loc * m).sum(1, keepdim=True)
    l_loc = 2.0 * cos_vm * m - v_loc
    return from_local(l_loc, t, b, n), l_loc[:, 2:] > 0, reflection_pdf(v_loc[:, 2], m[:, 2], alpha)[:, None]


@autograd_free
@half_in_float32
def ssr_glossy_stochastic(gbuffer: GBuffer, params: StochasticSSRParams = StochasticSSRParams(), *,
                          generator: Optional[torch.Generator] = None, debug: bool = False) -> SSRResult:
    """Glossy SSR by GGX rays and ray reuse (module docstring).

    Args:
        gbuffer: ``view_z``, ``normal``, ``mask``, ``color``, ``roughness``, all :math:`(B, C, H, W)`.
        params: :class:`StochasticSSRParams`. generator: draws the directions (default: seeded by ``params.seed``).
        debug: the first ray's debug buffers (``visits`` …).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n, mask=torch.ones(1, 1, 6, 8,
        ...             dtype=torch.bool), color=torch.ones(1, 3, 6, 8), roughness=torch.full((1, 1, 6, 8), 0.3))
        >>> r = ssr_glossy_stochastic(g)
        >>> r.raw_color.shape, bool(r.hit.any())
        (torch.Size([1, 3, 6, 8]), False)
    """
    if not isinstance(params, StochasticSSRParams):
        raise TypeError(f"params: expected StochasticSSRParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES, finite=("color", "roughness"), meta_ok=False)
    cam, p = gbuffer.camera, params
    B, _, H, W = gbuffer.view_z.shape
    dt, dev = gbuffer.view_z.dtype, gbuffer.view_z.device
    gen = make_generator(p.seed, generator)
    pos = cam.uv_to_view(cam.uv_grid(dt, dev)[None], gbuffer.view_z)
    v = -pos / vector_norm(pos).clamp_min(torch.finfo(dt).tiny)                    # toward the eye
    n = gbuffer.normal.to(dt)
    t, b = frame(n)
    v_loc = to_local(v, t, b, n)
    alpha = alpha_of(gbuffer.roughness.to(dt))[:, 0]                               # (B, H, W)
    march = p.march()
    samples, first = [], None
    for _ in range(p.rays_per_pixel):
        l_dir, above, pdf = ggx_ray(v_loc, alpha, (t, b, n), gen)
        r = march_hiz(gbuffer, march, l_dir, debug and first is None)
        samples.append((r, above, pdf, l_dir))
        first = first or r
    del t, b
    zero = torch.zeros(B, 3, H, W, dtype=dt, device=dev)
    sums = ReuseSums(zero, torch.zeros_like(zero), torch.zeros(B, 1, H, W, dtype=dt, device=dev))
    reuse = ReuseFrame(pos, v, v_loc[:, 2].contiguous(), n, alpha, gbuffer.mask)
    radius = p.reuse_radius if p.reuse == "neighbours" else 0
    steps = sum(s[0].steps for s in samples)
    while samples:                                              # each ray's buffers are freed once it is summed
        r, above, pdf, l_dir = samples.pop(0)
        ok = r.hit & above
        raw, faded = torch.where(ok, r.raw_color, 0.0), torch.where(ok, r.raw_color * r.fade, 0.0)
        ray, mask = padded(RaySample(ok, raw, faded, r.hit_view, l_dir, pdf), gbuffer.mask, radius)
        del r, ok, raw, faded, above, pdf, l_dir
        sums = reuse_ray(sums, ray, reuse, mask, radius)
        del ray
    num_raw, num_fade, den = sums
    safe = den.clamp_min(torch.finfo(dt).tiny)
    raw_c, faded_c = torch.where(den > 0, num_raw / safe, 0.0), torch.where(den > 0, num_fade / safe, 0.0)
    return dataclasses.replace(first, color=faded_c, raw_color=raw_c, steps=steps)


class StochasticSSR(nn.Module):
    """``nn.Module`` wrapper of :func:`ssr_glossy_stochastic`."""

    def __init__(self, params: StochasticSSRParams = StochasticSSRParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> SSRResult:
        return ssr_glossy_stochastic(gbuffer, self.params, generator=generator, debug=self.debug)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("glossy_stochastic", ssr_glossy_stochastic, StochasticSSRParams, StochasticSSR, order=50,
                title="stochastic glossy SSR: GGX rays, Hi-Z march, ray reuse (Stachowiak 2015)")
#: a glossy method: the SSR-glossy section scores its colour against the path-traced lobe
GLOSSY = True
DEBUG_VIEWS = {"visits": "level-0 pyramid reads per texel (first ray)"}
SPEED_GRIDS = {"cost": [{"rays_per_pixel": [1, 4], "reuse": "neighbours"}, {"rays_per_pixel": 1, "reuse": "none"}]}
SPEED_PANELS = (SpeedPanel("hits", "rays_per_pixel", (("reuse", "neighbours"),)),)
