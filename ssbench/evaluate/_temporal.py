"""Frames of one AO method on a static scene, as a real-time renderer produces them: the noise advanced every
frame and the camera jittered by a sub-pixel offset, so :func:`ssbench.metrics.flicker` can say how much the
output changes from frame to frame.

* the noise advances as the method does it: a pass module that declares ``FRAME_PARAM`` (GTAO: ``frame``,
  XeGTAO's ``288·(frame mod 64)`` Hilbert offset) gets the frame index there; every pass also gets a fresh
  generator per frame (``seed + frame``), which redraws the kernels and rotation textures drawn from it (an
  animated noise texture). ``advance_noise=False`` keeps frame 0's noise (three.js ``SSAOPass`` ships a static
  texture: its flicker comes from the jitter alone);
* the jitter is the Halton (2, 3) sequence of TAA, centred on the pixel (offsets in [−½, ½)), applied with
  :meth:`ssbench.camera.Camera.jittered`; each frame's G-buffer is rendered by Mitsuba from the jittered camera;
* ``orbit_deg`` turns the camera about its target's vertical axis by that many degrees per frame (a camera
  path: edges move, surfaces are disoccluded);
* ``moving`` (:class:`~ssbench.scenes.motion.Motion`) moves one object frame by frame; the resolve gets its motion
  vectors unless ``motion_vectors=False`` (the frame loop: :mod:`ssbench.evaluate._frames`);
* ``accumulation`` (:class:`~ssbench.passes.temporal.AccumulationParams`) also resolves the frames temporally
  (reprojection, depth rejection, neighbourhood clamp, blend: :mod:`ssbench.passes.temporal`), so flicker is
  measured raw and accumulated side by side.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
from typing import Optional

import torch

from ..metrics.temporal import flicker, ghosting
from ..passes.temporal import AccumulationParams
from ..scenes.motion import Motion
from ._common import resolve_params
from ._frames import EDGE_BAND, EDGE_JUMP, FramePlan, halton, orbit, run_frames

__all__ = ["AOFrames", "ao_frames", "halton", "orbit", "EDGE_BAND", "EDGE_JUMP", "check_truth_rays"]


@dataclasses.dataclass(frozen=True)
class AOFrames:
    """What :func:`ao_frames` produced.

    Attributes:
        ao: :math:`(T, 1, 1, H, W)` the method's AO per frame.
        mask: :math:`(T, 1, 1, H, W)` bool valid pixels per frame.
        offsets: the ``(dx, dy)`` pixel jitter of each frame.
        flicker: :func:`ssbench.metrics.flicker` of ``ao`` over the pixels valid in every frame.
        params: the parameters of frame 0.
        accumulated: :math:`(T, 1, 1, H, W)` the temporally resolved frames (``None`` without ``accumulation``).
        flicker_accumulated: their flicker (NaN without ``accumulation``).
        history_valid: :math:`(T, 1, 1, H, W)` where the resolve trusted the reprojected history.
        cameras: each frame's camera.
        ghosting, ghosting_edges: :func:`ssbench.metrics.temporal.ghosting` against each frame's ray-traced truth
            of the method's flavour (``truth_rays > 0``), over every trusted pixel / those near depth edges.
        truth: :math:`(T, 1, 1, H, W)` that truth (``None`` without ``truth_rays``).
        ghosting_moving: ghosting within :data:`~ssbench.evaluate._frames.MOVING_BAND` pixels of the moving object
            (NaN without ``moving``).
    """

    ao: torch.Tensor
    mask: torch.Tensor
    offsets: tuple
    flicker: float
    params: object
    accumulated: Optional[torch.Tensor] = None
    flicker_accumulated: float = math.nan
    history_valid: Optional[torch.Tensor] = None
    cameras: tuple = ()
    ghosting: float = math.nan
    ghosting_edges: float = math.nan
    truth: Optional[torch.Tensor] = None
    ghosting_moving: float = math.nan


def check_truth_rays(truth_rays, accumulation) -> None:
    if isinstance(truth_rays, bool) or not isinstance(truth_rays, int) or truth_rays < 0 or truth_rays == 1:
        raise ValueError(f"truth_rays: must be 0 or an integer >= 2, got {truth_rays!r}")
    if truth_rays and accumulation is None:
        raise ValueError("truth_rays: ghosting needs accumulation")


def ao_frames(scene, method: str, params=None, *, frames: int = 8, jitter: bool = True,
              advance_noise: bool = True, width: int = 160, height: int = 120, radius: Optional[float] = None,
              seed: int = 0, use_cache: bool = True, orbit_deg: float = 0.0,
              accumulation: Optional[AccumulationParams] = None, truth_rays: int = 0,
              moving: Optional[Motion] = None, motion_vectors: bool = True) -> AOFrames:
    """Run AO ``method`` on ``frames`` frames of ``scene`` (see the module docstring).

    Args:
        scene: catalog name, scene file, dict or :class:`~ssbench.scenes.Scene`.
        method: a name of :data:`ssbench.passes.AO_METHODS`.
        params: ``None``, the params dataclass or a dict of overrides.
        frames: number of frames (≥ 2).
        jitter: jitter the camera by the Halton (2, 3) sub-pixel offsets (``False``: the same pixel centres).
        advance_noise: advance the noise every frame (``False``: frame 0's noise throughout).
        width, height: image size.
        radius: sets the pass's radius parameter (as :func:`ssbench.evaluate.ao`).
        seed: the generator seed of frame 0 (frame ``t`` uses ``seed + t`` when the noise advances).
        use_cache: let the G-buffer renders use the disk cache.
        orbit_deg: camera turn per frame about the target's vertical axis (0: a still camera).
        accumulation: temporal resolve settings (``None``: raw frames only).
        truth_rays: rays per pixel of each frame's ground truth (the method's flavour at its radius), for
            ghosting (0: none; needs ``accumulation``).
        moving: an object moving frame by frame (``None``: a static scene).
        motion_vectors: give the resolve the moving object's motion vectors (``False``: reproject by the
            camera alone, as a renderer without a velocity buffer).
    """
    from .. import reference
    from ..passes import ao_method, declared
    from ..scenes import load as load_scene
    from ._ao import radius_param
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    fn, params_cls, requires = ao_method(method)
    module = importlib.import_module(fn.__module__)
    p = resolve_params(params_cls, params, method)
    rname = radius_param(params_cls, module)
    if radius is not None:
        if rname is None:
            raise ValueError(f"radius: method {method!r} has no radius parameter")
        p = dataclasses.replace(p, **{rname: float(radius)})
    check_truth_rays(truth_rays, accumulation)
    sc = load_scene(scene)
    plan = FramePlan(sc, sc.camera.with_resolution(width, height), frames, jitter, orbit_deg, moving,
                     motion_vectors)
    frame_param = declared(fn, "FRAME_PARAM")
    flavour = declared(fn, "FLAVOUR") or "cosine"
    truth_radius = float(getattr(p, rname)) if rname else 0.5

    def render(t, _scene, g):
        k = t if advance_noise else 0
        pt = dataclasses.replace(p, **{frame_param: k}) if frame_param else p
        return fn(g, pt, generator=torch.Generator().manual_seed(seed + k)).ao

    def truth(_t, scene_t, g):
        return reference.ambient_occlusion(scene_t, g, truth_radius, truth_rays, flavour, seed,
                                           use_cache=use_cache).ao

    run = run_frames(plan, tuple(requires), render, accumulation=accumulation,
                     truth=truth if truth_rays else None, use_cache=use_cache)
    ao, mask = run.out, run.mask
    if accumulation is None:
        return AOFrames(ao, mask, run.offsets, float(flicker(ao, mask)), p, cameras=run.cameras)
    ghost = ghost_edges = ghost_moving = math.nan
    if truth_rays:
        ghost = ghosting(run.accumulated, ao, run.truth, run.history_valid)
        ghost_edges = ghosting(run.accumulated, ao, run.truth, run.history_valid, run.edges)
        if run.near_moving is not None:
            ghost_moving = ghosting(run.accumulated, ao, run.truth, run.history_valid, run.near_moving)
    return AOFrames(ao, mask, run.offsets, float(flicker(ao, mask)), p, run.accumulated,
                    float(flicker(run.accumulated, mask)), run.history_valid, run.cameras, ghost, ghost_edges,
                    run.truth, ghost_moving)
