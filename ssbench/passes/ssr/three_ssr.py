"""three.js ``SSRPass``'s reflection shader (``SSRShader``, three.js ``examples/jsm/shaders/SSRShader.js``, after
lettier's "3D Game Shaders For Beginners: SSR"), transliterated: what a user of three.js ships, scored like the
article's marchers. Proven equal to the shader itself, run in headless Chromium (``ssbench/PARITY.md``).

Per pixel (GL conventions: ``xy`` in pixels from the bottom-left corner, ``uv = xy / resolution``):

1. ``viewPosition`` from the depth buffer (``getViewPosition``), ``viewIncidentDir = normalize(viewPosition)``,
   ``viewReflectDir = reflect(viewIncidentDir, viewNormal)``.
2. The ray's far end ``d1viewPosition = viewPosition + viewReflectDir · maxDistance / dot(−I, N)``, pulled back to
   the near plane when it crosses it; ``d0 = gl_FragCoord.xy``, ``d1`` its projection in pixels.
3. A pixel DDA: ``totalStep = max(|Δx|, |Δy|)`` steps of one pixel along the major axis; at step ``i`` the texel
   at ``d0 + i·span`` is read; the ray's depth is interpolated perspective-correctly (``1/z`` linear in
   ``s``); ``s`` advances by ``1/totalStep`` per step — **except after a background texel** (the shader's
   ``continue`` skips ``s += sStep``, so the ray's depth lags behind its pixel from then on; kept, as shipped).
4. Where the ray is behind the texel (``viewReflectRayZ ≤ vZ``): hit iff the texel's view point lies within
   ``max(thickness, 3 × the texel's width in view units)`` of the ray's *line* (``pointToLineDistance``), or
   always with ``infinite_thick``. On a hit, a texel facing away from the ray (``dot(R, vN) ≥ 0``) or farther
   than ``max_distance`` from the reflecting plane ends the ray without a hit.
5. ``op = opacity · (1 − distance/maxDistance)² · (dot(I, R) + 1)/2`` (distance attenuation, Fresnel-like term).

Outputs: ``raw_color`` the hit texel's colour, ``fade = op`` and ``color = raw_color · op`` (what ``SSRPass``
blends over the image with ``op`` as alpha). Terminations: ``OFF_SCREEN`` (left ``[0, resolution]``),
``MAX_DISTANCE`` (``i ≥ totalStep``, or stopped at a back face or beyond ``max_distance`` from the plane),
``OUT_OF_STEPS`` (``MAX_STEP``, by default ``⌊√(W² + H²)⌋`` as ``SSRPass`` sets it), ``NO_RAY`` off ``mask`` or at
the far plane.

The rays are set up (:mod:`.three_ssr_rays`) and marched :data:`RAY_CHUNK` at a time, so the working set stays
bounded at any image size (at 1920×1080 the whole image's set-up and working set peaked above 1 GiB); rays do not
interact, so the outputs are those of one chunk holding every ray (tested).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ...indices import flat_nonzero
from ..common import check_positive, index_dtype
from ..compiled import step_blocks
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from ..registry import Method, SpeedPanel
from .common import HIT, NO_RAY, OUT_OF_STEPS, SSRResult, compact_now, components, flat, unflat
from .three_ssr_rays import Shading, ThreeRays
from .three_ssr_step import MarchRays, MarchState, StepTextures, march_steps, take_rows

REQUIRES = ("view_z", "normal", "mask", "color")
DEFAULTS_SOURCE = "three.js SSRShader / SSRPass defaults (maxDistance 180, thickness 0.018, opacity 0.5)"
EQUAL_SETTINGS = {"thickness": "thickness", "ray_length": "max_distance"}


@dataclass(frozen=True)
class ThreeSSRParams:
    """Settings of :func:`ssr_three`, named after the shader's uniforms and defines.

    Args:
        max_distance: ``maxDistance``, the ray's length along the view axis and the plane-distance cut.
        thickness: ``thickness``, the smallest hit distance from the ray's line (view units).
        opacity: ``opacity``, the reflection's alpha before attenuation.
        max_step: ``MAX_STEP``; 0: ``⌊√(W² + H²)⌋``, as ``SSRPass`` sets it.
        distance_attenuation, fresnel: ``DISTANCE_ATTENUATION``, ``FRESNEL`` (both on in three.js).
        infinite_thick: ``INFINITE_THICK``: every sample behind the depth buffer hits.
    """

    max_distance: float = 180.0
    thickness: float = 0.018
    opacity: float = 0.5
    max_step: int = 0
    distance_attenuation: bool = True
    fresnel: bool = True
    infinite_thick: bool = False

    def __post_init__(self) -> None:
        check_positive(self.max_distance, "max_distance")
        check_positive(self.thickness, "thickness")
        if isinstance(self.opacity, bool) or not isinstance(self.opacity, (int, float)) or not 0 <= self.opacity <= 1:
            raise ValueError(f"opacity: must be a number in [0, 1], got {self.opacity!r}")
        if isinstance(self.max_step, bool) or not isinstance(self.max_step, int) or self.max_step < 0:
            raise ValueError(f"max_step: must be an integer >= 0 (0: the image diagonal), got {self.max_step!r}")
        for name in ("distance_attenuation", "fresnel", "infinite_thick"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected True or False, got {getattr(self, name)!r}")


#: rays set up and marched at once: the working set (about 40 values per ray) stays a few tens of MB at any size
RAY_CHUNK = 1 << 18


class RayEnds(NamedTuple):
    """Per ray, what the march hands the outputs, :math:`(m,)` or :math:`(m, C)`: ``term`` (int8), ``steps``
    (int32), the hit texel ``hit_k`` (flat in its batch item), the hit's ``hit_xy`` (GL pixels) and ``hit_vp``."""

    term: torch.Tensor
    steps: torch.Tensor
    hit_k: torch.Tensor
    hit_xy: torch.Tensor
    hit_vp: torch.Tensor


def march_rays(ray: torch.Tensor, b: torch.Tensor, r: ThreeRays, shade: Shading, textures: StepTextures,
               p: "ThreeSSRParams", max_step: int, out: RayEnds) -> None:
    """Steps 3–4 for the rays ``ray`` (their rows of ``out``; ``b`` their batch items in the texel index dtype, ``r``
    their set-up): the pixel DDA, :data:`~ssbench.passes.compiled.STEPS_PER_CALL` steps per compiled call, stopped
    rays dropped now and then; each ray's end and hit written into ``out``."""
    dt, dev, m = r.vp.dtype, r.vp.device, len(ray)
    ws = MarchRays(ray, b, components(r.d0), components(r.span), r.total, r.recip, r.recip_end, components(r.vp),
                   components(r.d1v), (r.d1v - r.vp).norm(dim=1), components(r.refl), components(r.n), r.s_step)
    zeros = lambda *shape, dtype=dt: torch.zeros(m, *shape, dtype=dtype, device=dev)   # noqa: E731
    st = MarchState(torch.ones(m, dtype=torch.int32, device=dev), zeros(dtype=torch.int32).fill_(OUT_OF_STEPS),
                    zeros(dtype=torch.int32), r.s_step.clone(), zeros(dtype=out.hit_k.dtype), components(zeros(2)),
                    components(zeros(3)))

    def write_back(rows: torch.Tensor) -> None:   # the working set's rays at ``rows``: their ends and hits
        at = ws.ray.index_select(0, rows)
        out.term.index_copy_(0, at, st.term.index_select(0, rows).to(out.term.dtype))
        out.steps.index_copy_(0, at, st.steps.index_select(0, rows))
        out.hit_k.index_copy_(0, at, st.hit_tex.index_select(0, rows))
        out.hit_xy.index_copy_(0, at, take_rows(st.hit_xy, rows))
        out.hit_vp.index_copy_(0, at, take_rows(st.hit_vp, rows))

    thickness = torch.tensor(p.thickness, dtype=dt, device=dev)
    i = 1
    for count, left in step_blocks(max_step - 1, False, dev):          # steps i = 1 … max_step − 1
        if ws.ray.numel() == 0:
            break
        at = i if left is None else torch.tensor(i, device=dev)    # the number 1 would specialise the first call
        st = march_steps(at, ws, st, textures, shade.size, shade.camera.far, thickness, p.infinite_thick,
                         p.max_distance, count, left)
        i += count
        alive = st.alive32 != 0
        if compact_now(int(alive.sum()), ws.ray.numel()):                 # drop the stopped rays now and then
            write_back(flat_nonzero(~alive))
            keep = flat_nonzero(alive)
            ws, st = ws.take(keep), st.take(keep)
    write_back(torch.arange(ws.ray.numel(), device=dev))


@autograd_free
@half_in_float32
def ssr_three(gbuffer: GBuffer, params: ThreeSSRParams = ThreeSSRParams(), *,
              generator: Optional[torch.Generator] = None, debug: bool = False) -> SSRResult:
    """three.js ``SSRShader`` on a G-buffer (see the module docstring); ``generator`` is unused (no jitter).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> z, n = torch.full((1, 1, 6, 8), -2.0), torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> r = ssr_three(GBuffer(cam, view_z=z, normal=n, mask=z < 0, color=n))
        >>> r.color.shape, bool(r.hit.any())
        (torch.Size([1, 3, 6, 8]), False)
    """
    if not isinstance(params, ThreeSSRParams):
        raise TypeError(f"params: expected ThreeSSRParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES, finite=("color",), meta_ok=False)
    cam, p = gbuffer.camera, params
    view_z = gbuffer.view_z
    B, _, H, W = view_z.shape
    dt, dev, HW = view_z.dtype, view_z.device, H * W
    far = cam.far
    depth = cam.view_z_to_depth(view_z).reshape(B, HW)                            # tDepth
    normal = flat(gbuffer.normal.to(dt)).reshape(B, HW, 3)                       # contiguous: fast row gathers
    colour = flat(gbuffer.color.to(dt)).reshape(B, HW, 3)
    vz_tex = cam.depth_to_view_z(depth)                                           # getViewZ of every texel
    max_step = p.max_step or int(math.sqrt(W * W + H * H))
    shade = Shading(cam, p.max_distance, (H, W), depth, vz_tex, normal)
    b, k = torch.nonzero(gbuffer.mask.reshape(B, HW) & (-vz_tex < far), as_tuple=True)   # rays: no early return
    m = len(k)
    out = RayEnds(term=torch.full((m,), OUT_OF_STEPS, dtype=torch.int8, device=dev),
                  steps=torch.zeros(m, dtype=torch.int32, device=dev),
                  hit_k=torch.zeros(m, dtype=index_dtype(B * HW), device=dev),
                  hit_xy=torch.zeros(m, 2, dtype=dt, device=dev), hit_vp=torch.zeros(m, 3, dtype=dt, device=dev))
    textures = StepTextures(depth.reshape(-1), vz_tex.reshape(-1), shade.minv, normal.reshape(B * HW, 3))
    ends = torch.zeros(m, 3, dtype=dt, device=dev) if debug else None
    for c0 in range(0, m, RAY_CHUNK):                       # a bounded working set: RAY_CHUNK rays at a time
        c1 = min(m, c0 + RAY_CHUNK)
        r = shade.rays(b[c0:c1], k[c0:c1])
        if ends is not None:
            ends[c0:c1] = r.d1v
        march_rays(torch.arange(c0, c1, device=dev), b[c0:c1].to(index_dtype(B * HW)), r, shade, textures, p, max_step,
                   out)
    term, steps, hit_k, hit_xy, hit_vp = out

    # ---- outputs ----
    h = flat_nonzero(term == HIT)
    raw = colour[b[h], hit_k[h]]
    rh = shade.rays(b[h], k[h])                                     # the hit rays' set-up again (per ray: the same)
    op = torch.full((len(h),), float(p.opacity), dtype=dt, device=dev)
    if p.distance_attenuation:
        plane = (rh.n * hit_vp[h]).sum(1) - (rh.n * rh.vp).sum(1)
        op = op * (1.0 - plane / p.max_distance) ** 2
    if p.fresnel:
        op = op * ((rh.inc * rh.refl).sum(1) + 1.0) / 2.0
    op = op.clamp(0.0, 1.0)                     # the blend's alpha: a hit behind the reflecting plane gives ratio > 1
    pixel = torch.stack([hit_xy[h, 0], H - hit_xy[h, 1]], -1)                   # ssbench pixels (y down)
    ray_pixel = b * HW + k

    def scatter(values, rows, fill, C, dtype):    # per-ray values -> (B, C, H, W)
        return unflat(values.reshape(len(rows), C), rows, fill, (B, H, W), dtype)

    termination = scatter(term, ray_pixel, NO_RAY, 1, torch.int8)
    rows = ray_pixel[h]
    return SSRResult(color=scatter(raw * op[:, None], rows, 0.0, 3, dt), hit=termination == HIT,
                     hit_pixel=scatter(pixel, rows, -1.0, 2, dt), hit_view=scatter(hit_vp[h], rows, 0.0, 3, dt),
                     steps=scatter(steps, ray_pixel, 0, 1, torch.int32), termination=termination,
                     fade=scatter(op, rows, 1.0, 1, dt), raw_color=scatter(raw, rows, 0.0, 3, dt),
                     debug={"ray_end": scatter(ends, ray_pixel, 0.0, 3, dt)} if debug else {})


class ThreeSSR(nn.Module):
    """``nn.Module`` wrapper of :func:`ssr_three`."""

    def __init__(self, params: ThreeSSRParams = ThreeSSRParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> SSRResult:
        return ssr_three(gbuffer, self.params, generator=generator, debug=self.debug)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("three_ssr", ssr_three, ThreeSSRParams, ThreeSSR, order=40,
                title="three.js SSRPass shader (pixel DDA, distance-to-line thickness)")
SPEED_GRIDS = {"cost": [{"thickness": [0.018, 0.1]}]}
SPEED_PANELS = (SpeedPanel("hits", "thickness", ()),)
#: the depth-read budget of an equal-reads comparison (ssbench.analysis.equal_reads): the parameter that caps
#: reads, and the settings that make every read count:
#: one read per pixel step
READ_BUDGET = ("max_step", {})
