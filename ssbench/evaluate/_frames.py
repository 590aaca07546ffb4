"""The frame loop behind the temporal evaluations (AO, SSR): what changes from frame to frame, and the loop that
renders each frame's G-buffer, runs an effect on it, resolves it temporally and traces its truth.

A :class:`FramePlan` says how frame ``t`` differs from frame 0:

* the camera jitters by the Halton (2, 3) sub-pixel offset of TAA (:func:`halton`, centred on the pixel);
* the camera turns ``orbit_deg`` degrees per frame about its target's vertical axis (:func:`orbit`);
* one object moves (:class:`ssbench.scenes.motion.Motion`), and the resolve is given its motion vectors
  (:func:`ssbench.passes.temporal.object_motion`) unless ``motion_vectors=False`` (a renderer that reprojects by
  the camera alone).

:func:`run_frames` is the loop; each evaluation supplies what one frame of its effect is.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable, Optional

import torch
import torch.nn.functional as F

from ..camera import Camera
from ..gbuffer import GBuffer
from ..metrics.ao import edge_band
from ..passes.temporal import AccumulationParams, TemporalAccumulator, object_motion
from ..scenes import Scene
from ..scenes.motion import Motion

__all__ = ["FramePlan", "Frames", "run_frames", "halton", "orbit", "EDGE_BAND", "EDGE_JUMP", "MOVING_BAND"]

#: ``ghosting_edges`` counts the pixels within this many pixels of a depth edge (a relative jump above
#: :data:`EDGE_JUMP`; silhouettes against the background included): where trails show
EDGE_BAND, EDGE_JUMP = 2, 0.05
#: ``ghosting_moving`` counts the pixels within this many pixels of the moving object (its contact shadow and the
#: background it uncovers)
MOVING_BAND = 8


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
class FramePlan:
    """How frame ``t`` of a sequence differs from frame 0 (see the module docstring).

    Attributes:
        scene: the scene of frame 0.
        camera: its camera at the image size.
        frames: number of frames (≥ 2).
        jitter: Halton sub-pixel jitter (``False``: the same pixel centres every frame).
        orbit_deg: camera turn per frame (0: a still camera).
        moving: the moving object (``None``: a static scene).
        motion_vectors: give the resolve the moving object's motion vectors.
    """

    scene: Scene
    camera: Camera
    frames: int
    jitter: bool = True
    orbit_deg: float = 0.0
    moving: Optional[Motion] = None
    motion_vectors: bool = True

    def __post_init__(self) -> None:
        f = self.frames
        if isinstance(f, bool) or not isinstance(f, int) or f < 2:
            raise ValueError(f"frames: must be an integer >= 2, got {f!r}")
        o = self.orbit_deg
        if isinstance(o, bool) or not isinstance(o, (int, float)) or not math.isfinite(o):
            raise ValueError(f"orbit_deg: must be a finite number, got {o!r}")
        if self.moving is not None:
            if not isinstance(self.moving, Motion):
                raise TypeError(f"moving: expected ssbench.scenes.motion.Motion or None, "
                                f"got {type(self.moving).__name__}")
            self.moving.index(self.scene)                   # the shape exists and can move
        for name in ("jitter", "motion_vectors"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected a bool, got {getattr(self, name)!r}")

    def offset(self, t: int) -> tuple[float, float]:
        """Frame ``t``'s sub-pixel jitter ``(dx, dy)`` in [−½, ½)."""
        return (halton(t + 1, 2) - 0.5, halton(t + 1, 3) - 0.5) if self.jitter else (0.0, 0.0)

    def camera_at(self, t: int) -> Camera:
        return orbit(self.camera, self.orbit_deg * t).jittered(*self.offset(t))

    def scene_at(self, t: int) -> Scene:
        """Frame ``t``'s scene (moved object, frame ``t``'s camera)."""
        sc = self.scene if self.moving is None else self.moving.at(self.scene, t)
        return sc.with_camera(self.camera_at(t))

    def motion(self, t: int, gbuffer: GBuffer) -> Optional[torch.Tensor]:
        """Motion vectors from frame ``t − 1`` to ``t`` for the resolve (``None``: the camera's alone)."""
        if self.moving is None or not self.motion_vectors or t == 0:
            return None
        step = tuple(a - b for a, b in zip(self.moving.offset(t), self.moving.offset(t - 1)))
        return object_motion(gbuffer, self.moving.index(self.scene), step)


@dataclasses.dataclass(frozen=True)
class Frames:
    """What :func:`run_frames` produced; frames are stacked on a leading time axis :math:`(T, B, C, H, W)`.

    Attributes:
        out: the effect's output per frame.
        mask: bool valid pixels per frame, :math:`(T, B, 1, H, W)`.
        offsets, cameras: each frame's jitter and camera.
        accumulated: the temporally resolved frames (``None`` without accumulation).
        history_valid: where the resolve trusted the history (``None`` without accumulation).
        truth: each frame's truth (``None`` without a truth).
        edges: pixels near depth edges per frame (``None`` without a truth).
        near_moving: pixels within :data:`MOVING_BAND` of the moving object per frame (``None`` without one).
    """

    out: torch.Tensor
    mask: torch.Tensor
    offsets: tuple
    cameras: tuple
    accumulated: Optional[torch.Tensor] = None
    history_valid: Optional[torch.Tensor] = None
    truth: Optional[torch.Tensor] = None
    edges: Optional[torch.Tensor] = None
    near_moving: Optional[torch.Tensor] = None


def _near(gbuffer: GBuffer, index: int) -> torch.Tensor:
    on = (gbuffer.shape_id == index).float()
    return F.max_pool2d(on, 2 * MOVING_BAND + 1, 1, MOVING_BAND) > 0


def run_frames(plan: FramePlan, channels: tuple, render: Callable[[int, Scene, GBuffer], torch.Tensor], *,
               accumulation: Optional[AccumulationParams] = None,
               truth: Optional[Callable[[int, Scene, GBuffer], torch.Tensor]] = None,
               use_cache: bool = True, spp: int = 16, seed: int = 0,
               valid: Optional[Callable[[GBuffer], torch.Tensor]] = None) -> Frames:
    """Frame by frame: render the G-buffer ``channels`` of ``plan.scene_at(t)`` (Mitsuba, disk-cached; ``spp``
    and ``seed`` path trace its ``color`` when asked for), call ``render(t, scene, gbuffer)`` for the effect's
    :math:`(1, C, H, W)` output, resolve it temporally with ``accumulation`` (and the plan's motion vectors), and
    call ``truth(t, scene, gbuffer)`` when given. ``valid(gbuffer)`` gives the pixels the effect covers
    (default: the G-buffer's hits), returned as ``mask``."""
    from .. import reference
    if accumulation is not None and not isinstance(accumulation, AccumulationParams):
        raise TypeError(f"accumulation: expected AccumulationParams or None, got {type(accumulation).__name__}")
    if truth is not None and accumulation is None:
        raise ValueError("truth: ghosting needs accumulation")
    extra = ("mask", "view_z") + (("shape_id",) if plan.moving is not None else ())
    channels = tuple(dict.fromkeys(tuple(channels) + extra))
    resolve = TemporalAccumulator(accumulation) if accumulation is not None else None
    W, H = plan.camera.width, plan.camera.height
    outs, masks, cams, acc, trusted, truths, edges, near = [], [], [], [], [], [], [], []
    for t in range(plan.frames):
        sc = plan.scene_at(t)
        cams.append(sc.camera)
        g = reference.gbuffer(sc, W, H, channels=channels, use_cache=use_cache, spp=spp, seed=seed)
        if plan.moving is not None:
            near.append(_near(g, plan.moving.index(plan.scene)).cpu())
        out = render(t, sc, g).detach().float().cpu()
        outs.append(out)
        masks.append((g.mask if valid is None else valid(g)).cpu())
        if resolve is not None:
            acc.append(resolve.step(out, g, plan.motion(t, g)))
            trusted.append(resolve.valid.cpu())
        if truth is not None:
            truths.append(truth(t, sc, g).detach().float().cpu())
            edges.append(edge_band(g.view_z, g.mask, EDGE_BAND, EDGE_JUMP, silhouettes=True).cpu())
    stack = lambda xs: torch.stack(xs) if xs else None                                # noqa: E731
    return Frames(torch.stack(outs), torch.stack(masks), tuple(plan.offset(t) for t in range(plan.frames)),
                  tuple(cams), stack(acc), stack(trusted), stack(truths), stack(edges), stack(near))
