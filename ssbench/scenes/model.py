"""Scene data model: geometry + materials + lights + camera, as frozen, hashable data.

A scene models only what the comparisons need: analytic shapes (sphere, box, rectangle, disk, cylinder) and
meshes (OBJ/PLY) — or the shapes of a Mitsuba scene file, loaded by Mitsuba (type ``mitsuba``) — each with a
material of albedo / roughness / metallic; point, directional and constant
environment lights; one :class:`~ssbench.camera.Camera`. Nothing here imports Mitsuba; the reference backend
translates a :class:`Scene` into a Mitsuba scene (``ssbench.reference.convert``).

Transforms: every shape has a ``to_world`` 4×4 (row-major) built as ``T · R · S`` (``transforms.py``).
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from typing import Any

from ..camera import Camera
from .transforms import Mat4

Vec3 = tuple[float, float, float]

SHAPE_TYPES = ("sphere", "box", "rectangle", "disk", "cylinder", "mesh", "mitsuba")
LIGHT_TYPES = ("point", "directional", "environment")


class SceneError(ValueError):
    """A scene description is invalid. The message starts with ``file:line:`` (or ``<catalog:name>``)."""


@dataclass(frozen=True)
class Material:
    """Surface parameters shared by the G-buffer and the path tracer.

    ``albedo`` is linear RGB in [0, 1]; ``roughness`` in [0, 1] (1 = Lambertian); ``metallic`` in [0, 1].
    """

    albedo: Vec3 = (0.7, 0.7, 0.7)
    roughness: float = 1.0
    metallic: float = 0.0


@dataclass(frozen=True)
class Shape:
    """One object of the scene.

    ``params`` holds the type's own parameters as sorted ``(key, value)`` pairs:
    sphere ``center, radius``; box ``size`` (3 edge lengths); rectangle ``size`` (2 edge lengths, local xy
    plane, normal +z); disk ``radius`` (local xy plane, normal +z); cylinder ``p0, p1, radius, caps``;
    mesh ``file, sha256, face_normals``.
    """

    id: str
    type: str
    params: tuple[tuple[str, Any], ...]
    to_world: Mat4
    material: Material = Material()
    where: str = ""                 # "file:line" of the definition, for later error messages

    def param(self, key: str) -> Any:
        return dict(self.params)[key]


@dataclass(frozen=True)
class Light:
    """``point``: ``position``, ``intensity`` (RGB, W/sr); ``directional``: ``direction`` (the light travels
    along it), ``irradiance``; ``environment``: constant ``radiance``."""

    type: str
    params: tuple[tuple[str, Any], ...]

    def param(self, key: str) -> Any:
        return dict(self.params)[key]


@dataclass(frozen=True)
class MitsubaSource:
    """A scene loaded from a Mitsuba 3 file by Mitsuba itself (:mod:`ssbench.reference.mitsuba_file`): the file's
    real ``path``, the ``digest`` of every file it reads plus the overrides, and the ``defines`` (``-D``)."""

    path: str
    digest: str
    defines: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Scene:
    """A complete, validated scene. Build one with :func:`ssbench.scenes.load` or :func:`scene_from_dict`."""

    name: str
    description: str
    shapes: tuple[Shape, ...]
    lights: tuple[Light, ...]
    camera: Camera
    max_depth: int = 6
    source: str = "<dict>"
    extra: tuple[tuple[str, Any], ...] = field(default=())
    mitsuba: "MitsubaSource | None" = None   # set: the shapes and emitters are this file's Mitsuba objects

    def shape_index(self, shape_id: str) -> int:
        """Position of a shape in :attr:`shapes`; this index is the G-buffer ``shape_id``."""
        for i, s in enumerate(self.shapes):
            if s.id == shape_id:
                return i
        raise KeyError(f"shape_id: no shape named {shape_id!r} in scene {self.name!r}")

    def with_camera(self, camera: Camera) -> "Scene":
        from dataclasses import replace
        return replace(self, camera=camera)

    def content_hash(self) -> str:
        """SHA-256 of everything that affects a rendering (not the description or source path)."""
        d = asdict(self)
        d.pop("description"), d.pop("source")
        if d["mitsuba"] is None:
            d.pop("mitsuba")                     # scenes without a file hash as they always did
        else:
            d["mitsuba"].pop("path"), d.pop("extra")
        for s in d["shapes"]:
            s.pop("where")
        blob = json.dumps(d, sort_keys=True, default=str).encode()
        return hashlib.sha256(blob).hexdigest()
