"""A moving object: one shape of a scene translated by a constant velocity, frame by frame.

The only animation the comparisons need is an object whose screen position changes while the rest of the scene
stays put: its silhouette uncovers the background behind it (disocclusion) and its contact shadow moves over a
static floor, which is what temporal accumulation gets wrong (ghosting). :class:`Motion` says which shape moves
and how fast; :meth:`Motion.at` gives the scene of frame ``t`` and :meth:`Motion.offset` the shape's world
translation, from which a pass's motion vectors follow (:func:`ssbench.passes.temporal.previous_world`).

Example:
    >>> from ssbench.scenes import load
    >>> m = Motion("ball", (0.25, 0.0, 0.0))
    >>> m.at(load("sphere_on_plane"), 3).shapes[1].to_world[0][3]
    0.75
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .model import Scene
from .transforms import freeze4, matmul4, translate4

__all__ = ["Motion"]


@dataclass(frozen=True)
class Motion:
    """Shape ``shape`` (its id) moves by ``velocity`` world units per frame (frame 0: where the scene puts it)."""

    shape: str
    velocity: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not isinstance(self.shape, str) or not self.shape:
            raise ValueError(f"shape: expected a shape id, got {self.shape!r}")
        v = self.velocity
        if (not isinstance(v, (tuple, list)) or len(v) != 3
                or any(isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c) for c in v)):
            raise ValueError(f"velocity: expected three finite numbers, got {v!r}")
        object.__setattr__(self, "velocity", tuple(float(c) for c in v))

    def offset(self, t: float) -> tuple[float, float, float]:
        """The shape's world translation at frame ``t`` relative to frame 0."""
        return tuple(c * t for c in self.velocity)

    def index(self, scene: Scene) -> int:
        """The moving shape's index in ``scene.shapes`` (its G-buffer ``shape_id``)."""
        if scene.mitsuba is not None:
            raise ValueError(f"shape: scene {scene.name!r} is a Mitsuba file; its shapes cannot be moved here")
        try:
            return scene.shape_index(self.shape)
        except KeyError:
            ids = ", ".join(s.id for s in scene.shapes)
            raise ValueError(f"shape: no shape {self.shape!r} in scene {scene.name!r} (shapes: {ids})") from None

    def at(self, scene: Scene, t: int) -> Scene:
        """``scene`` at frame ``t``: the moving shape's ``to_world`` preceded by the translation ``offset(t)``."""
        i = self.index(scene)
        s = scene.shapes[i]
        moved = dataclasses.replace(s, to_world=freeze4(matmul4(translate4(self.offset(t)), s.to_world)))
        return dataclasses.replace(scene, shapes=scene.shapes[:i] + (moved,) + scene.shapes[i + 1:])
