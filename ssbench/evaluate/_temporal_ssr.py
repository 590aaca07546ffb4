"""Frames of one SSR method (mirror or glossy), raw and temporally accumulated, as a renderer produces them.

The frame loop is the AO one (:mod:`ssbench.evaluate._frames`: Halton sub-pixel jitter, a turning camera, a moving
object, the resolve of :mod:`ssbench.passes.temporal`); what changes per frame is the method's reflected
radiance (``raw_color``, before the edge fade and the Fresnel resolve), drawn with a fresh generator per frame
(``seed + t``: new GGX directions for the stochastic glossy pass, as it ships with temporal accumulation).

The truth of each frame is the screen-space oracle of :func:`ssbench.reference.glossy.glossy_reflections`: the
G-buffer colour where each lobe direction's first hit projects, when the camera sees it — for a mirror
(roughness 0) the colour at the mirror hit. It is what a screen-space method can reach, so ghosting measures the
resolve, not the information the G-buffer lacks.

Reflections are reprojected with the motion of the *reflecting* surface (its depth and motion vectors), as
engines do; what is reflected moves with its own parallax, so under a turning camera or a moving reflected
object the history lags. ``ghosting`` shows that lag; the clamp bounds it.

Scores are on luminance (Rec. 709) over the pixels a renderer gives reflections (metallic ≥ 0.5 or roughness ≤
0.5), valid in every frame for flicker.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
from typing import Optional

import torch

from ..metrics.image import luminance
from ..metrics.temporal import flicker, ghosting
from ..passes.temporal import AccumulationParams
from ..scenes.motion import Motion
from ._common import resolve_params
from ._frames import FramePlan, run_frames
from ._temporal import check_truth_rays

__all__ = ["SSRFrames", "ssr_frames"]


@dataclasses.dataclass(frozen=True)
class SSRFrames:
    """What :func:`ssr_frames` produced (frames on a leading time axis).

    Attributes:
        color: :math:`(T, 1, 3, H, W)` the method's reflected radiance per frame.
        mask: :math:`(T, 1, 1, H, W)` bool, the pixels given reflections.
        offsets, cameras: each frame's jitter and camera.
        params: the method's parameters.
        flicker: :func:`ssbench.metrics.flicker` of the luminance over the pixels given reflections in every frame.
        accumulated: :math:`(T, 1, 3, H, W)` the temporally resolved frames (``None`` without ``accumulation``).
        flicker_accumulated: their flicker.
        history_valid: where the resolve trusted the history.
        truth: :math:`(T, 1, 3, H, W)` the screen-space oracle per frame (``None`` without ``truth_rays``).
        ghosting, ghosting_edges, ghosting_moving: :func:`ssbench.metrics.temporal.ghosting` of the luminance
            over every trusted reflecting pixel, those near depth edges and those near the moving object.
    """

    color: torch.Tensor
    mask: torch.Tensor
    offsets: tuple
    cameras: tuple
    params: object
    flicker: float
    accumulated: Optional[torch.Tensor] = None
    flicker_accumulated: float = math.nan
    history_valid: Optional[torch.Tensor] = None
    truth: Optional[torch.Tensor] = None
    ghosting: float = math.nan
    ghosting_edges: float = math.nan
    ghosting_moving: float = math.nan


def ssr_frames(scene, method: str, params=None, *, frames: int = 8, jitter: bool = True, width: int = 160,
               height: int = 120, seed: int = 0, spp: int = 16, use_cache: bool = True, orbit_deg: float = 0.0,
               accumulation: Optional[AccumulationParams] = None, truth_rays: int = 0,
               moving: Optional[Motion] = None, motion_vectors: bool = True) -> SSRFrames:
    """Run SSR ``method`` on ``frames`` frames of ``scene`` (see the module docstring).

    Args:
        scene, method, params: as :func:`ssbench.evaluate.ssr`.
        frames, jitter, width, height, orbit_deg, moving, motion_vectors, accumulation: as
            :func:`ssbench.evaluate.ao_frames`.
        seed: seeds frame 0's pass (frame ``t``: ``seed + t``) and the truth.
        spp: path-traced samples of the G-buffer colour the passes reflect.
        truth_rays: lobe directions per pixel of each frame's truth, for ghosting (0: none; needs
            ``accumulation``).
    """
    from ..passes import ssr_method
    from ..reference.glossy import GLOSSY_CHANNELS, glossy_reflections
    from ..scenes import load as load_scene
    from ._ssr import accepted_kwargs, pass_channels
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    if isinstance(spp, bool) or not isinstance(spp, int) or spp < 1:
        raise ValueError(f"spp: must be an integer >= 1, got {spp!r}")
    fn, params_cls, _ = ssr_method(method)
    p = resolve_params(params_cls, params, method)
    check_truth_rays(truth_rays, accumulation)
    needs = pass_channels(importlib.import_module(fn.__module__), p)
    sc = load_scene(scene)
    plan = FramePlan(sc, sc.camera.with_resolution(width, height), frames, jitter, orbit_deg, moving,
                     motion_vectors)
    chans = tuple(dict.fromkeys(needs + GLOSSY_CHANNELS))                     # GLOSSY_CHANNELS: roughness, metallic

    def render(t, _scene, g):
        gen = torch.Generator().manual_seed(seed + t)
        return fn(g.select(needs), p, **accepted_kwargs(fn, generator=gen)).raw_color

    def truth(_t, scene_t, g):
        return glossy_reflections(scene_t, g, rays=truth_rays, seed=seed, use_cache=use_cache).oracle

    def reflecting(g):
        return g.mask & ((g.metallic >= 0.5) | (g.roughness <= 0.5))

    run = run_frames(plan, chans, render, accumulation=accumulation, truth=truth if truth_rays else None,
                     use_cache=use_cache, spp=spp, seed=seed, valid=reflecting)
    refl, lum = run.mask, luminance(run.out)
    if accumulation is None:
        return SSRFrames(run.out, refl, run.offsets, run.cameras, p, float(flicker(lum, refl)))
    lum_acc = luminance(run.accumulated)
    ghost = (math.nan,) * 3
    if truth_rays:
        lum_truth, trusted = luminance(run.truth), run.history_valid & refl
        ghost = (ghosting(lum_acc, lum, lum_truth, trusted), ghosting(lum_acc, lum, lum_truth, trusted, run.edges),
                 math.nan if run.near_moving is None else ghosting(lum_acc, lum, lum_truth, trusted, run.near_moving))
    return SSRFrames(run.out, refl, run.offsets, run.cameras, p, float(flicker(lum, refl)), run.accumulated,
                     float(flicker(lum_acc, refl)), run.history_valid, run.truth, *ghost)
