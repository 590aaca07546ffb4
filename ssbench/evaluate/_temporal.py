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

from ..camera import Camera
from ..metrics.ao import edge_band
from ..metrics.temporal import flicker, ghosting
from ..passes.temporal import AccumulationParams, TemporalAccumulator
from ._common import resolve_params

__all__ = ["AOFrames", "ao_frames", "halton", "orbit"]

#: ``ghosting_edges`` counts the pixels within this many pixels of a depth edge (a relative jump above
#: :data:`EDGE_JUMP`; silhouettes against the background included): where trails show
EDGE_BAND, EDGE_JUMP = 2, 0.05


def orbit(camera: Camera, degrees: float) -> Camera:
    """``camera`` turned about the vertical (world y) axis through its target by ``degrees`` (eye and up).

    Example:
        >>> cam = Camera.from_look_at((0, 0, 2), (0, 0, 0), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> [round(v, 6) for v in orbit(cam, 90.0).eye]
        [2.0, 0.0, 0.0]
    """
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    turn = lambda v: (c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2])               # noqa: E731
    t = camera.target
    d = turn(tuple(e - q for e, q in zip(camera.eye, t)))
    return dataclasses.replace(camera, eye=tuple(q + x for q, x in zip(t, d)), up=turn(camera.up))


def halton(index: int, base: int) -> float:
    """The radical inverse of ``index`` in ``base`` (Halton sequence), in [0, 1).

    Example:
        >>> [halton(i, 2) for i in range(1, 5)]
        [0.5, 0.25, 0.75, 0.125]
    """
    f, r, i = 1.0, 0.0, index
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r


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


def ao_frames(scene, method: str, params=None, *, frames: int = 8, jitter: bool = True,
              advance_noise: bool = True, width: int = 160, height: int = 120, radius: Optional[float] = None,
              seed: int = 0, use_cache: bool = True, orbit_deg: float = 0.0,
              accumulation: Optional[AccumulationParams] = None, truth_rays: int = 0) -> AOFrames:
    """Run AO ``method`` on ``frames`` frames of a static ``scene`` (see the module docstring).

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
    """
    from .. import reference
    from ..passes import ao_method, declared
    from ..scenes import load as load_scene
    from ._ao import radius_param
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 2:
        raise ValueError(f"frames: must be an integer >= 2, got {frames!r}")
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
    if accumulation is not None and not isinstance(accumulation, AccumulationParams):
        raise TypeError(f"accumulation: expected AccumulationParams or None, got {type(accumulation).__name__}")
    if isinstance(orbit_deg, bool) or not isinstance(orbit_deg, (int, float)) or not math.isfinite(orbit_deg):
        raise ValueError(f"orbit_deg: must be a finite number, got {orbit_deg!r}")
    frame_param = declared(fn, "FRAME_PARAM")
    sc = load_scene(scene)
    cam = sc.camera.with_resolution(width, height)
    resolve = TemporalAccumulator(accumulation) if accumulation is not None else None
    if isinstance(truth_rays, bool) or not isinstance(truth_rays, int) or truth_rays < 0 or truth_rays == 1:
        raise ValueError(f"truth_rays: must be 0 or an integer >= 2, got {truth_rays!r}")
    if truth_rays and resolve is None:
        raise ValueError("truth_rays: ghosting needs accumulation")
    flavour = declared(fn, "FLAVOUR") or "cosine"
    truth_radius = float(getattr(p, rname)) if rname else 0.5
    aos, masks, offsets, acc, trusted, cams, truths, edges = [], [], [], [], [], [], [], []
    channels = tuple(dict.fromkeys(tuple(requires) + ("mask", "view_z")))
    for t in range(frames):
        dx, dy = (halton(t + 1, 2) - 0.5, halton(t + 1, 3) - 0.5) if jitter else (0.0, 0.0)
        cams.append(orbit(cam, orbit_deg * t).jittered(dx, dy))
        g = reference.gbuffer(sc.with_camera(cams[-1]), width, height, channels=channels, use_cache=use_cache)
        k = t if advance_noise else 0
        pt = dataclasses.replace(p, **{frame_param: k}) if frame_param else p
        out = fn(g, pt, generator=torch.Generator().manual_seed(seed + k)).ao.detach().float().cpu()
        aos.append(out)
        masks.append(g.mask.cpu())
        offsets.append((dx, dy))
        if resolve is not None:
            acc.append(resolve.step(out, g))
            trusted.append(resolve.valid.cpu())
            if truth_rays:
                truths.append(reference.ambient_occlusion(sc.with_camera(cams[-1]), g, truth_radius, truth_rays,
                                                          flavour, seed, use_cache=use_cache).ao.float())
                edges.append(edge_band(g.view_z, g.mask, EDGE_BAND, EDGE_JUMP, silhouettes=True))
    ao, mask = torch.stack(aos), torch.stack(masks)
    if resolve is None:
        return AOFrames(ao, mask, tuple(offsets), float(flicker(ao, mask)), p, cameras=tuple(cams))
    accumulated, valid = torch.stack(acc), torch.stack(trusted)
    ghost = ghost_edges = math.nan
    truth = None
    if truth_rays:
        truth = torch.stack(truths)
        ghost = ghosting(accumulated, ao, truth, valid)
        ghost_edges = ghosting(accumulated, ao, truth, valid, torch.stack(edges))
    return AOFrames(ao, mask, tuple(offsets), float(flicker(ao, mask)), p, accumulated,
                    float(flicker(accumulated, mask)), valid, tuple(cams), ghost, ghost_edges, truth)
