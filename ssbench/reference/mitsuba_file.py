"""Any Mitsuba 3 scene file, loaded by Mitsuba's own parser (``mitsuba.load_file``), as an ssbench :class:`Scene`.

The file is first checked by :func:`ssbench.scenes.mitsuba_guard.guard` (no entities, every file inside the
scene's folder, sizes bounded); then Mitsuba loads it with the ``-D`` overrides (``$name`` parameters),
``<include>``, ``<ref>`` and every plugin it knows. From the loaded scene:

* the **camera** comes from the first sensor (``perspective``; ``thinlens`` as a pinhole, with a note): its
  ``to_world`` however it was written (``lookat``, ``matrix``, ``rotate``/``translate`` chains) gives the eye and
  the view axes, ``x_fov`` and the film give the vertical fov, ``near_clip``/``far_clip`` the planes, the film
  size the default image size;
* each **shape** becomes a scene shape (its Mitsuba id, or ``shape<N>``) whose material is the BSDF mapped by
  :mod:`ssbench.reference.mitsuba_materials`; the G-buffer's ``shape_id`` indexes them in Mitsuba's order;
* the **emitters** (envmap, area, point, spot, directional, constant) stay Mitsuba's own objects: the colour
  and reflection references render with them.

Every reference (G-buffer, AO, colour, reflections) then rebuilds a Mitsuba scene from these very objects with
its own sensor and integrator (:func:`ssbench.reference.convert.scene_dict`), so a scene of hundreds of meshes
is one Mitsuba scene, loaded once per process. Mitsuba's own errors come back as one line.
"""
from __future__ import annotations

import math
import os
import warnings
from collections import OrderedDict
from typing import Any

import numpy as np

from ..camera import Camera
from ..scenes.mitsuba_guard import GuardedScene, guard, unchanged
from ..scenes.model import MitsubaSource, Scene, SceneError, Shape
from ..scenes.transforms import freeze4, identity4
from . import backend
from .mitsuba_materials import map_bsdf

__all__ = ["load_xml", "objects", "SceneNote"]

_LOADED: "OrderedDict[tuple, Any]" = OrderedDict()
_CHECKED: dict = {}                  # (path, defines, digest) -> the files the guard read, stamped (mtime, size)
_SENSORS = {"PerspectiveCamera": None, "ThinLensCamera": "thin-lens sensor used as a pinhole camera (no depth of "
                                                         "field)"}


class SceneNote(UserWarning):
    """Something in a scene file that the passes do not need and the loader ignored (or approximated)."""


def _one_line(e: Exception) -> str:
    return " ".join(str(e).split())


def _mitsuba_scene(g: GuardedScene):
    _CHECKED[(g.path, g.defines, g.digest)] = g.files
    key = (g.path, g.digest)
    if key in _LOADED:
        _LOADED.move_to_end(key)
        return _LOADED[key]
    mi = backend.mitsuba()
    try:
        obj = mi.load_file(g.path, optimize=False, **dict(g.defines))
    except Exception as e:                                     # Mitsuba's own message, in one line
        raise SceneError(f"{g.path}: Mitsuba could not load the scene: {_one_line(e)}") from None
    # the file's own shape ids, read now: every rebuilt scene renames these objects (convert.mitsuba_id)
    obj = (obj, tuple(sh.id() for sh in obj.shapes()))
    _LOADED[key] = obj
    while len(_LOADED) > 4:
        _LOADED.popitem(last=False)
    return obj


def _camera(mscene, where: str) -> tuple[Camera, list[str]]:
    mi = backend.mitsuba()
    sensors = mscene.sensors()
    if not sensors:
        raise SceneError(f"{where}: the scene has no sensor (ssbench needs a perspective camera)")
    s, notes = sensors[0], []
    kind = str(s).split("[")[0].strip()
    if kind not in _SENSORS:
        raise SceneError(f"{where}: sensor: unsupported sensor {kind!r} (perspective or thinlens)")
    if _SENSORS[kind]:
        notes.append(f"{where}: {_SENSORS[kind]}")
    if len(sensors) > 1:
        notes.append(f"{where}: {len(sensors)} sensors: the first is used")
    p = mi.traverse(s)
    for k in ("principal_point_offset_x", "principal_point_offset_y"):
        if k in p.keys() and abs(float(np.asarray(p[k]).reshape(-1)[0])) > 1e-9:
            raise SceneError(f"{where}: sensor: {k} is not supported (the camera's axis must cross the centre)")
    m = np.asarray(s.world_transform().matrix, dtype=np.float64).reshape(4, 4)
    r = m[:3, :3]
    lengths = np.linalg.norm(r, axis=0)
    axes = r / np.maximum(lengths, 1e-300)
    if (not np.all(np.isfinite(m)) or np.abs(axes.T @ axes - np.eye(3)).max() > 1e-4
            or np.linalg.det(axes) <= 0):
        raise SceneError(f"{where}: sensor to_world must be a rotation and a translation (no shear, no mirror)")
    eye, up, forward = m[:3, 3], axes[:, 1], axes[:, 2]
    width, height = (int(v) for v in s.film().size())
    x_fov = math.radians(float(np.asarray(p["x_fov"]).reshape(-1)[0]))
    fovy = math.degrees(2.0 * math.atan(math.tan(x_fov / 2.0) * height / width))
    cam = Camera.from_look_at(eye.tolist(), (eye + forward).tolist(), up.tolist(), fovy, width, height,
                              float(s.near_clip()), float(s.far_clip()))
    return cam, notes


def _name(file_id: str, i: int, taken: set) -> str:
    base = file_id or f"shape{i}"
    name, k = base, 1
    while name in taken:
        name, k = f"{base}_{k}", k + 1
    taken.add(name)
    return name


def load_xml(path: "str | os.PathLike", defines=()) -> Scene:
    """Load a Mitsuba 3 scene file as a :class:`Scene` (see the module docstring); its notes (what was
    ignored or approximated) are in ``scene.extra`` as ``("notes", (...))`` and are issued as :class:`SceneNote`
    warnings.

    Args:
        path: the ``.xml`` file; every file it names must lie in its folder.
        defines: ``-D``-style overrides of its ``$name`` parameters, a dict or ``(name, value)`` pairs.

    Raises:
        SceneError: naming ``file:line`` where the guard refuses, else Mitsuba's own message in one line.
    """
    g = guard(path, defines)
    mscene, ids = _mitsuba_scene(g)
    cam, notes = _camera(mscene, g.path)
    notes = list(g.notes) + notes
    shapes, taken = [], set()
    for i, sh in enumerate(mscene.shapes()):
        mapped = map_bsdf(sh.bsdf())
        name = _name(ids[i], i, taken)
        notes += [f"{g.path}: shape {name!r}: {n}" for n in mapped.notes]
        shapes.append(Shape(name, "mitsuba", (("albedo_at_hit", mapped.albedo_at_hit),
                                              ("kind", str(sh).split("[")[0].strip())),
                            freeze4(identity4()), mapped.material, where=g.path))
    if not shapes:
        raise SceneError(f"{g.path}: the scene has no shapes")
    for n in notes:
        warnings.warn(n, SceneNote, stacklevel=2)
    return Scene(name=os.path.splitext(os.path.basename(g.path))[0], description=f"Mitsuba scene {g.path}",
                 shapes=tuple(shapes), lights=(), camera=cam, max_depth=g.max_depth, source=g.path,
                 extra=(("notes", tuple(notes)),), mitsuba=MitsubaSource(g.path, g.digest, g.defines))


def objects(source: MitsubaSource) -> tuple[list, list]:
    """The loaded scene's shapes (in the :class:`Scene`'s order) and its emitters that are not attached to a
    shape, as Mitsuba objects. The files must still hash to ``source.digest``: checked again in full (the guard)
    unless every file this process checked still has its modification time and size, as on every reference
    call after the first (each rebuilds the Mitsuba scene for its own camera)."""
    key = (source.path, source.defines, source.digest)
    if key in _CHECKED and (source.path, source.digest) in _LOADED and unchanged(_CHECKED[key]):
        _LOADED.move_to_end((source.path, source.digest))
        mscene = _LOADED[(source.path, source.digest)][0]
    else:
        g = guard(source.path, source.defines)
        if g.digest != source.digest:
            raise SceneError(f"{source.path}: the scene's files changed since it was loaded; load it again")
        mscene, _ = _mitsuba_scene(g)
    lone = [e for e in mscene.emitters() if not str(e).startswith("AreaLight")]
    return list(mscene.shapes()), lone
