"""Metric calibration: for every artifact metric, an experiment that induces its artifact with a knob and records
how the metric responds. A metric that does not move when its artifact grows measures something else.

Each experiment returns :class:`Response` curves (knob values, the metric's mean over repetitions and its
standard error) plus the direction the metric must move; :func:`verdict` checks it. The report's "How each
metric was calibrated" section draws these curves next to the tables that use the metrics, and the slow tests
(``tests/analysis/test_calibration.py``) pin the same responses.

AO experiments (SSAO article, mebiusbox, 「スクリーンスペース・アンビエント・オクルージョン (SSAO)」, 2022,
https://zenn.dev/mebiusbox/articles/c7ea4871698ada):

* :func:`banding_response` — the kernel size ``K`` of hemisphere SSAO with the rotation noise off
  (``noise_size = 1``, one kernel for every pixel: Fig. 5's bands) and on (4×4): banding must fall with ``K``
  and be lower with the rotation on;
* :func:`halo_response` — the range check ``max_distance``: the dark halo must rise with it (Figs. 7–9);
* :func:`flat_bias_response` — SSAO's ``min_distance`` (the article's Fig. 10 bias) on a floor seen at a grazing
  angle, where nearest-texel depth makes samples just above the surface read as occluded: flat bias must fall
  as the bias grows;
* :func:`noise_response` — the sample count with the 4×4 rotation on: the noise variance must fall;
* :func:`flicker_response` — the sample count, over frames whose noise advances (no jitter, so the noise is the
  only thing that moves): flicker must fall as the samples grow; with the noise frozen and no jitter it is 0.

SSR and implicit experiments are in :mod:`ssbench.analysis.calibration_hits`.
"""
from __future__ import annotations

import dataclasses
import math
import statistics
from typing import Iterable, Optional, Sequence

import torch

__all__ = ["Response", "verdict", "banding_response", "halo_response", "flat_bias_response", "noise_response",
           "flicker_response"]


@dataclasses.dataclass(frozen=True)
class Response:
    """One calibration curve: ``metric`` (a row key) against ``knob`` on ``scene``.

    Attributes:
        metric, knob, scene: what was measured, what was turned, where.
        series: the curve's label within its experiment (e.g. ``"rotation off"``).
        x: knob values.
        y: the metric at each knob value (mean over the repetitions).
        err: standard error of each ``y`` over the repetitions (0 with one repetition).
        expect: ``"falls"`` or ``"rises"`` as the knob grows (more samples: less artifact).
        reps: repetitions per point (kernel seeds, noise frames, …).
        note: settings and what the experiment holds fixed.
    """

    metric: str
    knob: str
    scene: str
    series: str
    x: tuple
    y: tuple
    err: tuple
    expect: str
    reps: int
    note: str = ""

    def as_row(self) -> dict:
        """A JSON-able dict (tuples as lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}


def verdict(r: Response, tol: float = 0.0) -> dict:
    """Does ``r`` move the way it must? ``{"monotone": bool, "ratio": first/last (falls) or last/first
    (rises), "ratio_err": its standard error from the two points' errors (delta method; 0 without errors)}``;
    ``tol`` is the step in the wrong direction tolerated (absolute)."""
    pts = [(v, e) for v, e in zip(r.y, r.err) if not math.isnan(v)]
    y = [v for v, _ in pts]
    steps = list(zip(y, y[1:]))
    if r.expect == "falls":
        mono = all(b <= a + tol for a, b in steps)
        (num, ne), (den, de) = (pts[0], pts[-1]) if pts else ((math.nan, 0.0), (math.nan, 0.0))
    else:
        mono = all(b >= a - tol for a, b in steps)
        (num, ne), (den, de) = (pts[-1], pts[0]) if pts else ((math.nan, 0.0), (math.nan, 0.0))
    ratio = num / den if pts and den > 0 else math.inf
    rel = math.hypot(ne / num, de / den) if pts and num > 0 and den > 0 else 0.0
    ratio_err = ratio * rel if math.isfinite(ratio) and not math.isnan(rel) else math.nan
    return {"monotone": bool(mono and len(y) == len(r.y)), "ratio": float(ratio), "ratio_err": float(ratio_err)}


def _pooled(values: Sequence[float]) -> tuple[float, float]:
    """Root of the mean square of per-draw rms values (the banding of all draws pooled into one region) and
    its standard error (delta method: ``se(mean b²) / 2y``)."""
    sq = [v * v for v in values if not math.isnan(v)]
    if not sq:
        return math.nan, math.nan
    y = math.sqrt(statistics.fmean(sq))
    if len(sq) == 1 or y == 0:
        return y, 0.0
    return y, statistics.stdev(sq) / math.sqrt(len(sq)) / (2 * y)


def banding_response(scene: str = "sphere_on_plane", kernel_sizes: Sequence[int] = (4, 8, 16, 32, 64),
                     noise_sizes: Sequence[int] = (1, 4), seeds: Iterable[int] = range(256), *, width: int = 160,
                     height: int = 120, radius: float = 1.5, max_distance: float = 0.05, rays: int = 256,
                     method: str = "ssao", use_cache: bool = True, chunk: int = 64) -> list[Response]:
    """``banding`` of hemisphere SSAO against the oracle of its flavour, over the kernel size, one curve per
    noise size.

    One draw is one kernel, and with the rotation off every pixel uses it, so one draw's banding depends on
    where its few points happen to fall: at ``K = 4`` on ``sphere_on_plane`` the per-draw value has a
    coefficient of variation near 30 %, and a mean over 16 draws moves the K=4 / K=64 ratio by ±0.4. Each
    point is therefore the banding of ``seeds`` draws *pooled* (:func:`ssbench.metrics.banding` with
    ``reduction="mean"`` over the stacked draws: the root of the mean energy), with its standard error; the
    default 256 draws put the ratio's standard error near 0.09.

    The ground truth and the oracle are traced once (seed 0), so only the pass changes along a curve; draws
    are scored ``chunk`` at a time.
    """
    from .. import metrics, reference
    from ..evaluate import flavour
    from ..passes import ao_method
    fn, params_cls, _ = ao_method(method)
    seeds = list(seeds)
    flav = flavour(fn)
    g = reference.gbuffer(scene, width, height, use_cache=use_cache)
    orc = reference.screen_space_oracle(g, radius, rays, flav, 0, use_cache=use_cache)
    target, se = orc.ao.double(), orc.stderr.double()
    out = []
    for ns in noise_sizes:
        ys, es = [], []
        for k in kernel_sizes:
            p = params_cls(kernel_size=k, noise_size=ns, kernel_radius=radius, max_distance=max_distance)
            vals: list[float] = []
            for i in range(0, len(seeds), chunk):
                part = seeds[i:i + chunk]
                ao = torch.cat([fn(g, p, generator=torch.Generator().manual_seed(s)).ao.double() for s in part])
                vals += metrics.banding(ao, target, g.view_z, g.mask, target_stderr=se, reduction="none").tolist()
            m, e = _pooled(vals)
            ys.append(m)
            es.append(e)
        label = "rotation off (one kernel)" if ns == 1 else f"rotation on ({ns}×{ns} noise)"
        out.append(Response("banding", "kernel_size", scene, label, tuple(kernel_sizes), tuple(ys), tuple(es),
                            "falls", len(seeds), f"{method}, radius {radius}, max_distance {max_distance}, "
                            f"{width}×{height}, vs the {flav} oracle ({rays} rays); each point pools "
                            f"{len(seeds)} kernel draws"))
    return out


def halo_response(scenes: Sequence[str] = ("fence", "sphere_on_plane", "cornell_box"),
                  max_distances: Sequence[float] = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05), *, width: int = 96,
                  height: int = 72, rays: int = 64, method: str = "ssao",
                  use_cache: bool = True) -> list[Response]:
    """``halo_dark_flavour`` (false occlusion next to depth edges) and ``halo_missing_flavour`` over SSAO's range
    check ``max_distance``: the dark halo must rise as occluders ever farther in front are counted."""
    from ..evaluate import run_ao
    out = []
    for scene in scenes:
        refs: dict = {}
        g = None
        dark, missing = [], []
        for md in max_distances:
            ev = run_ao(scene, method, {"max_distance": md}, width=width, height=height, rays=rays, repeats=1,
                        warmup=False, references=refs, gbuffer=g, flip=False, oracle=False, use_cache=use_cache)
            g = ev.gbuffer
            dark.append(ev.row["halo_dark_flavour"])
            missing.append(ev.row["halo_missing_flavour"])
        note = f"{method} defaults otherwise, {width}×{height}, vs its flavour ground truth ({rays} rays)"
        zeros = tuple(0.0 for _ in max_distances)
        out.append(Response("halo_dark_flavour", "max_distance", scene, "dark halo", tuple(max_distances),
                            tuple(dark), zeros, "rises", 1, note))
        out.append(Response("halo_missing_flavour", "max_distance", scene, "missing occlusion",
                            tuple(max_distances), tuple(missing), zeros, "falls", 1, note))
    return out


def _ssao_curve(scene: str, param: str, values: Sequence, key: str, *, width: int, height: int, rays: int,
                use_cache: bool) -> tuple:
    from ..evaluate import run_ao
    refs: dict = {}
    g, ys = None, []
    for v in values:
        ev = run_ao(scene, "ssao", {param: v}, width=width, height=height, rays=rays, repeats=1, warmup=False,
                    references=refs, gbuffer=g, flip=False, oracle=False, use_cache=use_cache)
        g = ev.gbuffer
        ys.append(ev.row[key])
    return tuple(ys)


def flat_bias_response(scene: str = "grazing_floor", min_distances: Sequence[float] = (0.0, 1e-4, 5e-4, 2e-3, 5e-3),
                       *, width: int = 96, height: int = 72, rays: int = 64, use_cache: bool = True) -> list[Response]:
    """``flat_bias_flavour`` (occlusion added where the truth has none) over SSAO's ``min_distance``."""
    ys = _ssao_curve(scene, "min_distance", min_distances, "flat_bias_flavour", width=width, height=height,
                     rays=rays, use_cache=use_cache)
    return [Response("flat_bias_flavour", "min_distance", scene, "self-occlusion", tuple(min_distances), ys,
                     tuple(0.0 for _ in ys), "falls", 1,
                     f"ssao defaults otherwise, {width}×{height}, vs its flavour ground truth ({rays} rays)")]


def noise_response(scene: str = "grazing_floor", kernel_sizes: Sequence[int] = (8, 16, 32, 64), *, width: int = 96,
                   height: int = 72, rays: int = 64, use_cache: bool = True) -> list[Response]:
    """``noise`` (variance of AO minus its 5×5 box blur) over SSAO's kernel size, rotation on."""
    ys = _ssao_curve(scene, "kernel_size", kernel_sizes, "noise", width=width, height=height, rays=rays,
                     use_cache=use_cache)
    return [Response("noise", "kernel_size", scene, "rotation on (4×4 noise)", tuple(kernel_sizes), ys,
                     tuple(0.0 for _ in ys), "falls", 1, f"ssao defaults otherwise, {width}×{height}")]


def flicker_response(scene: str = "sphere_on_plane", knobs: Optional[dict] = None, *, frames: int = 8,
                     width: int = 160, height: int = 120, radius: float = 1.0,
                     use_cache: bool = True) -> list[Response]:
    """``flicker`` over each method's sample-count knob (``knobs``: method -> (parameter, values); default SSAO
    ``kernel_size`` 8…64 and GTAO ``quality`` low…ultra), over ``frames`` frames whose noise advances, no jitter;
    plus one point per method with the noise frozen (must be exactly 0) and with jitter alone."""
    from ..evaluate import ao_frames
    knobs = knobs or {"ssao": ("kernel_size", (8, 16, 32, 64)), "gtao": ("quality", ("low", "medium", "high",
                                                                                     "ultra"))}
    out = []
    for method, (param, values) in knobs.items():
        ys = [ao_frames(scene, method, {param: v}, frames=frames, jitter=False, radius=radius, width=width,
                        height=height, use_cache=use_cache).flicker for v in values]
        frozen = ao_frames(scene, method, frames=frames, jitter=False, advance_noise=False, radius=radius,
                           width=width, height=height, use_cache=use_cache).flicker
        jitter = ao_frames(scene, method, frames=frames, jitter=True, advance_noise=False, radius=radius,
                           width=width, height=height, use_cache=use_cache).flicker
        note = (f"{method}, radius {radius}, {frames} frames, {width}×{height}; at defaults: noise frozen and no "
                f"jitter {frozen:.2g}, sub-pixel jitter alone {jitter:.2g}")
        out.append(Response("flicker", param, scene, f"{method}, noise advancing", tuple(values), tuple(ys),
                            tuple(0.0 for _ in values), "falls", 1, note))
    return out


def ghosting_response(scene: str = "stairs", method: str = "ssao", alphas: tuple = (0.05, 0.1, 0.2, 0.5), *,
                      frames: int = 8, width: int = 96, height: int = 72, radius: float = 0.5, orbit_deg: float = 1.5,
                      truth_rays: int = 32, use_cache: bool = True) -> list[Response]:
    """``ghosting`` (:func:`ssbench.metrics.temporal.ghosting`) over the temporal resolve's blend weight ``alpha``
    on a camera turning ``orbit_deg`` per frame: once with a resolve that keeps stale history (no clamp, depth
    tolerance 10: nothing rejected) and once with the default resolve (3×3 clamp, 2 % depth tolerance). Less weight
    on the current frame keeps history longer, so ghosting must fall as ``alpha`` grows."""
    from ..evaluate import ao_frames
    from ..passes.temporal import AccumulationParams
    out = []
    for series, extra in (("stale history (no clamp, nothing rejected)", {"clamp": "none", "depth_tolerance": 10.0}),
                          ("default resolve (clamp, depth rejection)", {})):
        ys = [ao_frames(scene, method, frames=frames, width=width, height=height, radius=radius,
                        orbit_deg=orbit_deg, truth_rays=truth_rays, use_cache=use_cache,
                        accumulation=AccumulationParams(alpha=a, **extra)).ghosting for a in alphas]
        note = (f"{method}, radius {radius}, {frames} frames at {width}×{height}, camera turning {orbit_deg}° per "
                f"frame, {truth_rays}-ray truth per frame")
        out.append(Response("ghosting", "alpha", scene, series, tuple(alphas), tuple(ys), tuple(0.0 for _ in alphas),
                            "falls", 1, note))
    return out
