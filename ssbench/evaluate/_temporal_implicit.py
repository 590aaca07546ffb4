"""TXAA for the implicit ray casters: a sub-pixel jitter every frame, resolved temporally, scored against the
supersampled image it should converge to (progressive-tracing article, 補足: アンチエイリアシング — "TXAA" with a
jittered camera; the article leaves the resolve to the engine).

Per frame ``k`` of a static implicit scene, :func:`implicit_frames` draws the article's TXAA offset
(:func:`ssbench.passes.implicit.progressive_notes.txaa_jitter`, ``U[−½, ½)`` pixels, its own generator), casts the
method through the jittered pixel (the progressive method carries its ``t'`` state across frames, as the article's
frame loop does), shades the hits (:func:`~ssbench.passes.implicit.gbuffer.to_gbuffer`, the scene's materials and
lights) and resolves the colour with :class:`ssbench.passes.temporal.TemporalAccumulator` (a still camera: the
history stays in place, so the resolve averages the jittered samples over the pixel's area, as TXAA does).

The truth is the box-filtered image: the certified reference (:func:`ssbench.reference.implicit.implicit`) cast at
``truth_factor``² samples per pixel, shaded the same way and averaged (the article's supersampling,
:func:`~ssbench.passes.implicit.gbuffer.supersample`). Scores, on luminance, per frame: the mean |error| over the
silhouette pixels (those the truth covers only partly, and their neighbours), raw and accumulated — aliasing is the raw error there; the flicker of both over the silhouettes.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Optional

import torch
import torch.nn.functional as F

from ..metrics.image import luminance
from ..metrics.temporal import flicker
from ..passes.temporal import AccumulationParams, TemporalAccumulator
from ._common import resolve_params

__all__ = ["ImplicitFrames", "implicit_frames", "supersampled_truth", "TXAA", "LATE_FRAMES"]

#: :meth:`ImplicitFrames.late_error` averages the accumulated error over this many last frames
LATE_FRAMES = 4

#: the TXAA resolve of a still camera: no depth rejection (the jitter moves silhouettes every frame, so a depth
#: test would drop the history exactly where it anti-aliases), the background resolved too, the 3×3 clamp kept
TXAA = AccumulationParams(depth_tolerance=math.inf, background=True)


@dataclasses.dataclass(frozen=True)
class ImplicitFrames:
    """What :func:`implicit_frames` produced.

    Attributes:
        color, accumulated: :math:`(T, 1, 3, H, W)` shaded frames raw and resolved.
        truth: :math:`(1, 3, H, W)` the supersampled image; coverage :math:`(1, 1, H, W)` its hit share.
        silhouettes: :math:`(1, 1, H, W)` bool, the pixels the truth covers partly, dilated by one pixel.
        error_raw, error_accumulated: per-frame mean |luminance error| over the silhouettes.
        flicker, flicker_accumulated: :func:`ssbench.metrics.flicker` of the luminance over the silhouettes.
        offsets: each frame's jitter ``(dx, dy)`` in pixels.
        params: the method's parameters.
    """

    color: torch.Tensor
    accumulated: torch.Tensor
    truth: torch.Tensor
    coverage: torch.Tensor
    silhouettes: torch.Tensor
    error_raw: tuple
    error_accumulated: tuple
    flicker: float
    flicker_accumulated: float
    offsets: tuple
    params: object

    def raw_error(self) -> float:
        """The mean silhouette error of the raw frames (the aliasing)."""
        return sum(self.error_raw) / len(self.error_raw)

    def late_error(self, frames: int = LATE_FRAMES) -> float:
        """The mean silhouette error of the last ``frames`` accumulated frames (what the resolve converged to)."""
        last = self.error_accumulated[-frames:]
        return sum(last) / len(last)


def supersampled_truth(scene, camera, factor: int, use_cache: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
    """``(color, coverage)``: the certified reference at ``factor``× the resolution, shaded with the scene's
    materials and lights and average-pooled (:func:`~ssbench.passes.implicit.gbuffer.supersample`)."""
    from ..passes.implicit.common import ImplicitResult
    from ..passes.implicit.gbuffer import supersample
    from ..reference.implicit import implicit as trace

    def cast(cam):
        ref = trace(scene.surface(0), cam, use_cache=use_cache)
        zeros = torch.zeros_like(ref.t, dtype=torch.int32)
        return ImplicitResult(ref.t, ref.hit, zeros, zeros, zeros.to(torch.int8), ref.normal, ref.object_index)

    color, coverage, _ = supersample(cast, camera, factor, scene.materials, scene.lights)
    return color, coverage


def _silhouettes(coverage: torch.Tensor) -> torch.Tensor:
    partial = (coverage > 0) & (coverage < 1)
    return F.max_pool2d(partial.float(), 3, 1, 1) > 0


def implicit_frames(scene, method: str, params=None, *, frames: int = 8, width: Optional[int] = None,
                    height: Optional[int] = None, seed: int = 0,
                    accumulation: AccumulationParams = TXAA, truth_factor: int = 4,
                    use_cache: bool = True) -> ImplicitFrames:
    """Cast implicit ``method`` on ``frames`` TXAA-jittered frames of a static ``scene`` (module docstring).

    Args:
        scene: implicit catalog name, file, dict or ``ImplicitScene`` (frame 0's pose is used throughout).
        method: a name of :data:`ssbench.passes.IMPLICIT_METHODS`; ``params``: overrides.
        frames: ≥ 2. width, height: image size (default the scene camera's).
        seed: seeds the jitter (and the method's own randomness).
        accumulation: the temporal resolve (default :data:`TXAA`).
        truth_factor: supersampling factor of the truth (samples per pixel: its square).
        use_cache: let the reference read/write its disk cache.
    """
    from ..implicit.scene import load
    from ..passes import declared, implicit_method
    from ..passes.implicit.common import camera_rays
    from ..passes.implicit.gbuffer import to_gbuffer
    from ..passes.implicit.progressive_notes import txaa_jitter
    for name, v, lo in (("frames", frames, 2), ("seed", seed, 0), ("truth_factor", truth_factor, 1)):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name}: must be an integer >= {lo}, got {v!r}")
    if not isinstance(accumulation, AccumulationParams):
        raise TypeError(f"accumulation: expected AccumulationParams, got {type(accumulation).__name__}")
    fn, params_cls = implicit_method(method)
    p = resolve_params(params_cls, params, method)
    sc = load(scene)
    cam = sc.camera_at(0)
    cam = cam.with_resolution(width or cam.width, height or cam.height)
    surface = sc.surface(0)
    stateful = bool(declared(fn, "STATEFUL", False))
    truth, coverage = supersampled_truth(sc, cam, truth_factor, use_cache)
    sil = _silhouettes(coverage)
    g_jitter, g_method = torch.Generator().manual_seed(seed), torch.Generator().manual_seed(seed + 1)
    resolve = TemporalAccumulator(accumulation)
    raw, acc, offsets, state = [], [], [], None
    for _ in range(frames):
        jit = txaa_jitter(g_jitter, 1, torch.float32)
        offsets.append((float(jit[0, 0]), float(jit[0, 1])))
        rays = camera_rays(cam, jitter=jit, dtype=torch.float32)
        res = fn(surface, rays, p, state=state if stateful else None, generator=g_method)
        state = res.state
        g = to_gbuffer(res, rays, cam, sc.materials, sc.lights)
        raw.append(g.color.float())
        acc.append(resolve.step(g.color.float(), g))
    color, accumulated = torch.stack(raw), torch.stack(acc)
    lum_t = luminance(truth.float())
    err = lambda xs: tuple(float((luminance(x) - lum_t).abs()[sil].mean()) if bool(sil.any()) else math.nan  # noqa
                           for x in xs)
    m = sil.unsqueeze(0).expand(frames, *sil.shape)
    return ImplicitFrames(color, accumulated, truth, coverage, sil, err(raw), err(acc),
                          float(flicker(luminance(color), m)), float(flicker(luminance(accumulated), m)),
                          tuple(offsets), p)
