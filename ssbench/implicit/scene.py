"""Implicit-surface scenes: a surface (union of objects), lights, a camera and an optional animation.

Animation is piecewise linear: each segment ``[a, b)`` adds a per-frame velocity to one object's
translation or to the camera's eye / target. The pose at frame ``k`` is the rest pose plus, for every
segment, ``velocity · clamp(k − a, 0, b − a)`` (the frames of the segment already elapsed), so frame ``a``
is the last frame before the motion and the pose holds after the last segment.

Example:
    >>> s = load("animated")
    >>> s.frames, s.surface(0).objects[0].translate, s.surface(30).objects[0].translate
    (60, (-1.5, 0.0, 0.0), (1.5, 0.0, 0.0))
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict, dataclass
from typing import Any, Optional

from ..camera import Camera
from ..scenes.model import Light, Material
from ..vec3 import Vec3
from .union import ImplicitSurface

_ZERO: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Segment:
    """Frames ``[start, stop)`` of motion: ``object`` moves by ``translate_per_frame`` per frame, or (when
    ``object`` is None) the camera's eye and target move by ``eye_per_frame`` / ``target_per_frame``."""

    start: int
    stop: int
    object: Optional[str] = None
    translate_per_frame: Vec3 = _ZERO
    eye_per_frame: Vec3 = _ZERO
    target_per_frame: Vec3 = _ZERO

    def elapsed(self, frame: int) -> int:
        """Frames of this segment already elapsed at ``frame``: ``clamp(frame − start, 0, stop − start)``."""
        return min(max(frame - self.start, 0), self.stop - self.start)


@dataclass(frozen=True)
class Animation:
    """``frames`` frames of piecewise-linear motion (see the module docstring)."""

    frames: int
    segments: tuple[Segment, ...] = ()

    def offset(self, obj_id: str, frame: int) -> Vec3:
        """Total translation of object ``obj_id`` at ``frame`` relative to its rest pose."""
        return self._sum(frame, lambda s: s.translate_per_frame if s.object == obj_id else None)

    def camera_offsets(self, frame: int) -> tuple[Vec3, Vec3]:
        """``(eye offset, target offset)`` at ``frame``."""
        return (self._sum(frame, lambda s: s.eye_per_frame if s.object is None else None),
                self._sum(frame, lambda s: s.target_per_frame if s.object is None else None))

    def _sum(self, frame: int, pick) -> Vec3:
        out = [0.0, 0.0, 0.0]
        for s in self.segments:
            v = pick(s)
            if v is not None:
                n = s.elapsed(frame)
                out = [a + n * b for a, b in zip(out, v)]
        return tuple(out)  # type: ignore[return-value]


def _check_frame(frame: int) -> int:
    if isinstance(frame, bool) or not isinstance(frame, int) or frame < 0:
        raise ValueError(f"frame: expected an integer >= 0, got {frame!r}")
    return frame


@dataclass(frozen=True)
class ImplicitScene:
    """A validated implicit scene; build one with :func:`load` (catalog name, file or dict).

    ``objects`` is the rest pose; :meth:`surface` and :meth:`camera_at` give the pose at a frame (frames past
    the end hold the last pose; a static scene is the same at every frame).
    """

    name: str
    description: str
    objects: ImplicitSurface
    lights: tuple[Light, ...]
    camera: Camera
    animation: Optional[Animation] = None
    source: str = "<dict>"

    @property
    def frames(self) -> int:
        """Length of the animation (1 for a static scene)."""
        return self.animation.frames if self.animation is not None else 1

    @property
    def materials(self) -> tuple[Material, ...]:
        """Materials in object order (index = ``surface.object_index``)."""
        return self.objects.materials

    def surface(self, frame: int = 0) -> ImplicitSurface:
        """The surface at ``frame`` (objects translated by the animation)."""
        _check_frame(frame)
        surf = self.objects
        if self.animation is not None:
            for o in self.objects.objects:
                off = self.animation.offset(o.id, frame)
                if any(off):
                    surf = surf.translated(o.id, off)
        return surf

    def camera_at(self, frame: int = 0) -> Camera:
        """The camera at ``frame`` (eye and target moved by the animation; up, fov, size, near, far kept)."""
        _check_frame(frame)
        if self.animation is None:
            return self.camera
        de, dt = self.animation.camera_offsets(frame)
        if not any(de) and not any(dt):
            return self.camera
        c = self.camera
        return Camera.from_look_at([a + b for a, b in zip(c.eye, de)], [a + b for a, b in zip(c.target, dt)],
                                   c.up, c.fovy_deg, c.width, c.height, c.near, c.far)

    def content_hash(self) -> str:
        """SHA-256 of everything that affects a rendering (not the name's source, description or ``where``)."""
        objs = [{**o.key_data(), "material": asdict(o.material)} for o in self.objects.objects]
        d = {"name": self.name, "objects": objs, "lights": [asdict(light) for light in self.lights],
             "camera": asdict(self.camera), "animation": asdict(self.animation) if self.animation else None}
        return hashlib.sha256(json.dumps(d, sort_keys=True, default=repr).encode()).hexdigest()


def load(name_or_path: "str | os.PathLike | dict[str, Any] | ImplicitScene") -> ImplicitScene:
    """An implicit scene from the built-in catalog (by name), a ``.yaml``/``.yml``/``.toml`` file, or a dict.

    Example:
        >>> load("torus").objects.lipschitz
        1.0
    """
    from . import catalog
    from .schema import scene_from_dict, scene_from_file
    if isinstance(name_or_path, ImplicitScene):
        return name_or_path
    if isinstance(name_or_path, dict):
        return scene_from_dict(name_or_path)
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise TypeError(f"name_or_path: expected an implicit scene name, a file path or a dict, "
                        f"got {type(name_or_path).__name__}")
    s = os.fspath(name_or_path)
    if s in catalog.CATALOG:
        return catalog.get(s)
    if os.path.splitext(s)[1].lower() in (".yaml", ".yml", ".toml") or os.path.exists(s):
        return scene_from_file(s)
    raise KeyError(f"name_or_path: {s!r} is neither a built-in implicit scene ({', '.join(catalog.CATALOG)}) "
                   f"nor a .yaml/.yml/.toml file")
