"""Linear view-space SSR march, transcribed from the SSR article (§1.1–1.5).

``rayOrg`` from the depth buffer, ``rayDir = reflect(normalize(rayOrg), N)`` (``reflection_rays``), the end
point clipped at the near plane (``clip_ray_length``), then ``Iterations`` equal view-space steps
``deltaStep = (rayEnd − rayOrg) / Iterations``. Each sample ``Q`` is projected (``clip = P·(Q, 1)``,
``hitPixel = clip.xy / clip.w · 0.5 + 0.5``) and tested against the depth buffer read ``NEAREST``:
``dist = Q.z − sceneZMax`` (ray z minus depth-buffer view z, both negative); **hit iff
``dist < 0 && dist > −Thickness``**: the sample is behind the visible surface by less than ``Thickness``. A hit is
refined by bisection (§1.3); ``color`` = hit texel's colour × fades (§1.4–1.5, :mod:`.fade`), ``raw_color``
unfaded.

**Back-face depth (§1.2, Fig. 7)**: hit iff ``back_z − Thickness < Q.z < sceneZ`` (kode80's
``zB ≤ frontZ && zA ≥ backZ − pixelZSize``). Back depth works only for closed objects, so the article combines
it with the fixed width: ``Thickness`` extends the object behind its back face. ``back_z = −inf`` (open
surfaces) is infinitely thick; off-``mask`` texels use ``back = sceneZ`` (a cleared back-face buffer holds the
far plane). ``back_z`` is read as view z (no GL-depth round trip).

**Departures from the article's code** (pinned in ``tests/passes/ssr/test_linear.py``):

* *Termination.* ``OFF_SCREEN`` when a sample's uv leaves [0, 1]² (the shader reads clamp-to-edge texels on);
  ``MAX_DISTANCE`` / ``BEHIND_CAMERA`` after the last sample of an unclipped / near-plane-clipped ray;
  ``OUT_OF_STEPS`` (never a hit) when ``iterations > max_iterations`` (the shader's ``MAX_ITERATIONS``) ends
  the loop before the end point; ``NO_RAY`` off ``mask``.
* *Bisection.* The text's ``deltaStep /= BinarySearchIterations`` with ``pixelStride·0.5`` strides searches only
  part of the step; like the demo source (``/= PixelStride``) we probe the mid-point of the last step, then
  ±1/4, ±1/8, … (back after a hit). The first step's bracket starts at ``rayOrg``; the reported hit is the
  **last probe that passed** (the shader keeps the last probe even if it failed).
* *Jitter* (off by default; §1 has none): ``ξ ~ U[0, 1)`` per pixel, start at ``rayOrg − jitter·ξ·deltaStep``,
  so the march never passes the clipped end point.
* No self-hit guard (as the article): a sample behind its own or the next texel's centre depth hits the surface
  the ray starts on — common on grazing floors when a step is shorter than a texel's footprint.
* Fades as the article: circular edge fade at the hit's uv, vignette at ``vUv`` (the reflecting pixel's own
  uv), distance fade at ``length(rayOrg − hitPoint)``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ...indices import flat_nonzero
from ...layout import contiguous
from ..common import check_positive
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from .common import HIT, NO_RAY, SSRResult, channel_rows, split_rays, unflat
from .fade import FadeParams
from .linear_march import MarchLog, march, refine
from .linear_rays import linear_rays
from ..registry import Method, SpeedPanel

REQUIRES = ("view_z", "normal", "mask", "color")
REQUIRES_BACKFACE = REQUIRES + ("back_z",)
#: where the defaults come from (shown by the report next to the parameters)
DEFAULTS_SOURCE = ("the article's demo (mebiusbox/ssr: Iterations 50, 4 bisections, PixelZSize 1, MaxRayDistance 20)")
#: the parameters that play the shared roles of an equal-settings comparison (:func:`ssbench.evaluate.equal_settings`)
EQUAL_SETTINGS = {"thickness": "thickness", "ray_length": "max_ray_distance"}
POSITION_FROM = ("depth", "view_z", "position")
MAX_BINARY_SEARCH_ITERATIONS = 64  # the shader's loop bound


def _integer(v, name: str, lo: int) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{name}: must be an integer >= {lo}, got {v!r}")


@dataclass(frozen=True)
class LinearSSRParams(FadeParams):
    """Parameters of :func:`ssr_linear`: the article's uniforms snake-cased, defaults from its demo (``ssr.html``).

    Attributes:
        max_ray_distance: ``MaxRayDistance``, view-space ray length before near-plane clipping.
        iterations: ``Iterations``, equal steps over the (clipped) ray.
        thickness: ``Thickness`` (the demo's ``PixelZSize``), view-space depth tolerance behind a surface.
        use_back_face_depth: test against ``(back_z − thickness, sceneZ)`` (§1.2, Fig. 7; needs ``back_z``).
        binary_search_iterations: ``BinarySearchIterations`` (0 = no refinement; at most 64 run).
        edge_distance, edge_exponent, edge_fade_mode, fade_distance, fade_exponent: the fades (§1.4–1.5),
            inherited keyword-only from :class:`~ssbench.passes.ssr.fade.FadeParams`.
        jitter, seed: start-offset jitter in [0, 1] steps (0 = off) and its seed when no generator is passed.
        position_from: ``"depth"`` (``getViewPosition`` and ``getViewZ(getDepth(uv))`` of the GL depth buffer,
            as the article), ``"view_z"`` (no depth round trip) or ``"position"`` (``rayOrg`` from ``position``).
        max_iterations: ``MAX_ITERATIONS``, the shader's loop bound (300).
    """

    max_ray_distance: float = 20.0
    iterations: int = 50
    thickness: float = 1.0
    use_back_face_depth: bool = False
    binary_search_iterations: int = 4
    jitter: float = 0.0
    seed: int = 0
    position_from: str = "depth"
    max_iterations: int = 300

    def __post_init__(self) -> None:
        super().__post_init__()                                                   # the fades
        for name in ("max_ray_distance", "thickness"):
            check_positive(getattr(self, name), name)
        check_positive(self.jitter, "jitter", allow_zero=True)
        if self.jitter > 1:
            raise ValueError(f"jitter: must lie in [0, 1] steps, got {self.jitter!r}")
        for name, lo in (("iterations", 1), ("max_iterations", 1), ("binary_search_iterations", 0), ("seed", 0)):
            _integer(getattr(self, name), name, lo)
        if not isinstance(self.use_back_face_depth, bool):
            raise ValueError(f"use_back_face_depth: expected a bool, got {self.use_back_face_depth!r}")
        if self.position_from not in POSITION_FROM:
            raise ValueError(f"position_from: expected one of {POSITION_FROM}, got {self.position_from!r}")


def required_channels(params: LinearSSRParams) -> tuple[str, ...]:
    """The G-buffer channels :func:`ssr_linear` reads with ``params``."""
    req = REQUIRES_BACKFACE if params.use_back_face_depth else REQUIRES
    return req + (("position",) if params.position_from == "position" else ())


def check_inputs(gbuffer: GBuffer, params: LinearSSRParams) -> None:
    """Type checks of ``params`` and the shared G-buffer contract (:func:`~ssbench.passes.gbuffer_checks.check_gbuffer`)."""
    if not isinstance(params, LinearSSRParams):
        raise TypeError(f"params: expected LinearSSRParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, required_channels(params), finite=("color", "back_z", "position"),
                  meta_ok=False)


@autograd_free
@half_in_float32
def ssr_linear(gbuffer: GBuffer, params: LinearSSRParams = LinearSSRParams(), *,
               generator: Optional[torch.Generator] = None, debug: bool = False,
               trace_pixel: Optional[tuple[int, int]] = None) -> SSRResult:
    """Screen-space reflections by a linear view-space march (SSR article §1), vectorised over rays.

    .. math::
        Q_i = O + (i + 1 - j\\xi)\\,\\frac{E - O}{N}, \\qquad
        \\text{hit} \\iff -T < Q_i.z - z_{\\text{scene}}(\\pi(Q_i)) < 0

    Args:
        gbuffer: :data:`REQUIRES` (+ ``back_z`` with back-face depth, ``position`` with
            ``position_from="position"``), all :math:`(B, C, H, W)`; ``mask`` bool.
        params: :class:`LinearSSRParams`.
        generator: draws the jitter (default: a CPU generator seeded with ``params.seed``).
        debug: also return ``visits`` :math:`(B, 1, H, W)` int32 (how many samples, refinement included, read
            each texel: the visit map of the article's Fig. 11), ``ray_length`` :math:`(B, 1, H, W)` (after
            near-plane clipping) and ``jitter`` (ξ or ``None``).
        trace_pixel: ``(col, row)``: ``debug["trace"][b]`` holds that pixel's samples in order: ``view``
            :math:`(K, 3)`, ``pixel`` :math:`(K, 2)`, ``hit`` :math:`(K,)` bool, ``refine`` :math:`(K,)` bool.

    Returns:
        :class:`~ssbench.passes.ssr.common.SSRResult`; ``steps`` counts samples (an off-screen one included) plus
        refinement probes.

    Raises:
        ValueError: missing channels, bad shapes, dtypes or values (the message names the argument).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> z, n = torch.full((1, 1, 6, 8), -2.0), torch.zeros(1, 3, 6, 8); n[:, 2] = 1   # a wall facing the eye
        >>> r = ssr_linear(GBuffer(cam, view_z=z, normal=n, mask=z < 0, color=n))
        >>> r.color.shape, bool(r.hit.any())                           # rays come back toward the eye
        (torch.Size([1, 3, 6, 8]), False)
    """
    check_inputs(gbuffer, params)
    cam, view_z = gbuffer.camera, gbuffer.view_z
    B, _, H, W = view_z.shape
    dtype, dev, HW = view_z.dtype, view_z.device, H * W
    N_it = params.iterations

    rays = linear_rays(gbuffer, params, generator)
    ray, O, dS, Q, base, test = rays.ray, rays.origin, rays.delta, rays.start, rays.base, rays.test
    counting = debug or trace_pixel is not None                                   # visits: a debug buffer only
    log = MarchLog(counting, torch.zeros(B * HW if counting else 0, dtype=torch.int64, device=dev))
    if trace_pixel is not None:
        pid = torch.arange(B, device=dev) * HW + trace_pixel[1] * W + trace_pixel[0]
        log.trace_ids = {int(b): int(k) for b, k in zip(*torch.nonzero(ray[None] == pid[:, None], as_tuple=True))}
        log.trace = {b: [] for b in log.trace_ids}                                # b -> [(Q, hit, refine)]

    # ---- the march (§1.2), then the binary search refinement (§1.3) of the hits ----
    out = march(test, log, Q, dS, base, rays.clipped, N_it, params.max_iterations)
    term, steps = out.term, out.steps
    h = flat_nonzero(term == HIT)                                                # the hit rays (index_select below:
    at_hits = lambda x: contiguous(x.T.index_select(1, h).T)                     # noqa: E731  advanced indexing is
    Oh, base_h = at_hits(O), base.index_select(0, h)                             # ~5x slower; O, dS: views of rows)
    best, n_bs = out.hit_q.index_select(0, h), min(params.binary_search_iterations, MAX_BINARY_SEARCH_ITERATIONS)
    if n_bs > 0 and h.numel() > 0:
        best = refine(test, log, h, Oh, at_hits(dS), base_h, best, out.hit_step.index_select(0, h), n_bs)
        steps.index_add_(0, h, torch.full_like(h, n_bs, dtype=steps.dtype))

    # ---- colour at the hit texel and fades (§1.4, §1.5) ----
    uv, t = test.project(best, base_h)
    hit_pixel = cam.uv_to_pixel(uv, dim=-1)                                       # (m, 2)
    raw = contiguous(channel_rows(gbuffer.color).index_select(1, t).T)          # (m, 3)
    rh = ray.index_select(0, h)
    centre = contiguous(cam.pixel_centers_at(split_rays(rh, B, HW)[1], dtype).T)  # vUv of each ray's pixel
    fade = params.fade(hit_pixel, centre, W, H, (Oh - best).norm(dim=1, keepdim=True))

    def scatter(values, rows, fill, C, dt):       # per-ray values -> (B, C, H, W)
        return unflat(values.reshape(len(rows), C), rows, fill, (B, H, W), dt)

    termination = scatter(term, ray, NO_RAY, 1, torch.int8)
    dbg = {}
    if debug or trace_pixel is not None:
        dbg = {"visits": log.visits.to(torch.int32).reshape(B, 1, H, W), "ray_length": rays.ray_length,
               "jitter": rays.jitter}
    if trace_pixel is not None:
        dbg["trace"] = {b: {"view": torch.stack([s[0] for s in v]), "hit": torch.tensor([s[1] for s in v]),
                            "refine": torch.tensor([s[2] for s in v])} for b, v in log.trace.items() if v}
        for d in dbg["trace"].values():
            d["pixel"] = cam.view_to_pixel(d["view"], dim=-1)
    return SSRResult(color=scatter(raw * fade, rh, 0.0, 3, dtype), hit=termination == HIT,
                     hit_pixel=scatter(hit_pixel, rh, -1.0, 2, dtype), hit_view=scatter(best, rh, 0.0, 3, dtype),
                     steps=scatter(steps, ray, 0, 1, torch.int32), termination=termination,
                     fade=scatter(fade, rh, 1.0, 1, dtype), raw_color=scatter(raw, rh, 0.0, 3, dtype), debug=dbg)


class LinearSSR(nn.Module):
    """``nn.Module`` wrapper of :func:`ssr_linear`; ``forward(gbuffer)`` returns its :class:`SSRResult`."""

    def __init__(self, params: LinearSSRParams = LinearSSRParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> SSRResult:
        return ssr_linear(gbuffer, self.params, generator=generator, debug=self.debug)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("linear", ssr_linear, LinearSSRParams, LinearSSR, order=10,
                title="linear view-space march (mebiusbox 2022)")

#: the debug buffers the report draws (``debug=True`` results): buffer -> caption; each is a per-pixel count
#: shown on a log scale (the SSR article's Fig. 11 visit map)
DEBUG_VIEWS = {"visits": "depth fetches per texel"}
#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"iterations": [16, 64], "thickness": 0.1}, {"iterations": 64, "thickness": 1.0},
                        {"iterations": 64, "thickness": 0.1, "jitter": 1.0}]}
SPEED_PANELS = (SpeedPanel("hits", "iterations", (("jitter", 0.0), ("thickness", 0.1))),
                SpeedPanel("hits", "thickness", (("jitter", 0.0), ("iterations", 64))),
                SpeedPanel("hits", "jitter", (("iterations", 64), ("thickness", 0.1))))
#: the depth-read budget of an equal-reads comparison (ssbench.analysis.equal_reads): the parameter that caps
#: reads, and the settings that make every read count:
#: one depth read per step; no bisection, whose probes would be reads beyond the budget
READ_BUDGET = ("iterations", {"binary_search_iterations": 0})
