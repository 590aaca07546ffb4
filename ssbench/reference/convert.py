"""Translate a :class:`~ssbench.scenes.Scene` into a Mitsuba scene dictionary (and load it). A scene read from a
Mitsuba file (``scene.mitsuba``) brings its own loaded shape and emitter objects
(:func:`ssbench.reference.mitsuba_file.objects`); only the sensor and the integrator are ours.

Mitsuba object ids encode the scene index: ``s0003__ball`` (and ``s0003__ball__cap1`` for a cylinder cap), so
G-buffer ``shape_id`` never depends on the order of ``scene.shapes()``, which is not stable across processes
(measured here: the order changed between fresh processes on the same scene).
"""
from __future__ import annotations

import math
import re
from collections import OrderedDict
from typing import Any

from ..camera import Camera
from ..scenes.model import Material, Scene, SceneError, Shape
from ..scenes.transforms import frame_z_to, matmul4, scale4, translate4
from ..scenes.schema import cylinder_caps
from . import backend

_ID = re.compile(r"^s(\d{4,})__")


def mitsuba_id(index: int, shape: Shape, part: str = "") -> str:
    return f"s{index:04d}__{shape.id}" + (f"__{part}" if part else "")


def scene_index(mitsuba_shape_id: str) -> int:
    """Scene index encoded in a Mitsuba shape id; −1 for shapes not made by ssbench."""
    m = _ID.match(mitsuba_shape_id)
    return int(m.group(1)) if m else -1


def _rgb(v) -> dict:
    return {"type": "rgb", "value": [float(x) for x in v]}


def bsdf(m: Material) -> dict:
    """Diffuse for rough dielectrics, a conductor for mirrors, ``principled`` otherwise (all two-sided)."""
    if m.metallic == 0.0 and m.roughness >= 1.0:
        inner = {"type": "diffuse", "reflectance": _rgb(m.albedo)}
    elif m.metallic >= 1.0 and m.roughness <= 1e-3:
        inner = {"type": "conductor", "material": "none", "specular_reflectance": _rgb(m.albedo)}
    else:
        return {"type": "principled", "base_color": _rgb(m.albedo), "roughness": max(m.roughness, 1e-3),
                "metallic": m.metallic}
    return {"type": "twosided", "material": inner}


def _uniform_scale(m) -> float:
    cols = [math.sqrt(sum(m[r][c] ** 2 for r in range(3))) for c in range(3)]
    if max(cols) - min(cols) > 1e-9 * max(cols):
        raise ValueError("non-uniform scale")
    return cols[0]


def shape_dicts(index: int, s: Shape, mi_transform) -> dict[str, dict]:
    """Mitsuba dicts for one scene shape (a capped cylinder gives three)."""
    M = [list(r) for r in s.to_world]
    out: dict[str, dict] = {}
    b = bsdf(s.material)
    T = lambda m: mi_transform(m)                                   # noqa: E731
    if s.type == "sphere":
        try:
            _uniform_scale(M)
        except ValueError:
            raise SceneError(f"{s.where}: shapes.{s.id}: spheres take only uniform scales") from None
        m = matmul4(M, matmul4(translate4(s.param("center")), scale4([s.param("radius")] * 3)))
        out[mitsuba_id(index, s)] = {"type": "sphere", "to_world": T(m), "bsdf": b}
    elif s.type == "box":
        out[mitsuba_id(index, s)] = {"type": "cube", "bsdf": b,
                                     "to_world": T(matmul4(M, scale4([v / 2 for v in s.param("size")])))}
    elif s.type == "rectangle":
        sx, sy = s.param("size")
        out[mitsuba_id(index, s)] = {"type": "rectangle", "bsdf": b,
                                     "to_world": T(matmul4(M, scale4([sx / 2, sy / 2, 1.0])))}
    elif s.type == "disk":
        r = s.param("radius")
        out[mitsuba_id(index, s)] = {"type": "disk", "bsdf": b, "to_world": T(matmul4(M, scale4([r, r, 1.0])))}
    elif s.type == "cylinder":
        p0, p1, r = s.param("p0"), s.param("p1"), s.param("radius")
        axis = [b1 - a for a, b1 in zip(p0, p1)]
        length = math.sqrt(sum(a * a for a in axis))
        local = matmul4(translate4(p0), matmul4(frame_z_to(axis), scale4([r, r, length])))
        out[mitsuba_id(index, s)] = {"type": "cylinder", "bsdf": b, "to_world": T(matmul4(M, local))}
        if s.param("caps"):
            for k, cap in enumerate(cylinder_caps(p0, p1, r)):
                out[mitsuba_id(index, s, f"cap{k}")] = {"type": "disk", "bsdf": b,
                                                        "to_world": T(matmul4(M, cap))}
    elif s.type == "mesh":
        kind = "obj" if s.param("file").lower().endswith(".obj") else "ply"
        out[mitsuba_id(index, s)] = {"type": kind, "filename": s.param("file"), "bsdf": b,
                                     "face_normals": bool(s.param("face_normals")), "to_world": T(M)}
    else:  # pragma: no cover - the schema rejects unknown types
        raise SceneError(f"{s.where}: unknown object type {s.type!r}")
    return out


def scene_dict(scene: Scene, camera: Camera | None = None) -> dict[str, Any]:
    """The Mitsuba ``load_dict`` dictionary of ``scene`` seen through ``camera`` (default: the scene's)."""
    mi = backend.mitsuba()
    cam = camera or scene.camera
    T = lambda m: mi.ScalarTransform4f([[float(v) for v in row] for row in m])   # noqa: E731
    sens = cam.mitsuba_sensor()
    d: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(scene.max_depth)},
        "sensor": {"type": "perspective", "fov": sens["fov"], "fov_axis": sens["fov_axis"],
                   "near_clip": sens["near_clip"], "far_clip": sens["far_clip"], "to_world": T(sens["to_world"]),
                   "sampler": {"type": "independent", "sample_count": 1},
                   "film": {"type": "hdrfilm", "width": cam.width, "height": cam.height,
                            "rfilter": {"type": "box"}, "pixel_format": "rgb"}},
    }
    if scene.mitsuba is not None:               # a Mitsuba file: its own shape and emitter objects
        from .mitsuba_file import objects
        shapes, emitters = objects(scene.mitsuba)
        d.update({mitsuba_id(i, s): obj for i, (s, obj) in enumerate(zip(scene.shapes, shapes))})
        d.update({f"light{k}": e for k, e in enumerate(emitters)})
    else:
        for i, s in enumerate(scene.shapes):
            d.update(shape_dicts(i, s, T))
    for k, light in enumerate(scene.lights):
        if light.type == "point":
            d[f"light{k}"] = {"type": "point", "position": list(light.param("position")),
                              "intensity": _rgb(light.param("intensity"))}
        elif light.type == "directional":
            d[f"light{k}"] = {"type": "directional", "direction": list(light.param("direction")),
                              "irradiance": _rgb(light.param("irradiance"))}
        else:
            d[f"light{k}"] = {"type": "constant", "radiance": _rgb(light.param("radiance"))}
    return d


_LOADED: "OrderedDict[tuple, Any]" = OrderedDict()


def load(scene: Scene, camera: Camera | None = None):
    """``mi.load_dict`` of :func:`scene_dict`, memoised for the last few (scene, camera) pairs."""
    mi = backend.mitsuba()
    key = (scene.content_hash(), camera or scene.camera)
    if key in _LOADED:
        _LOADED.move_to_end(key)
        return _LOADED[key]
    try:
        # optimize=False: the default merges shapes that share a BSDF into one shape with an empty id
        obj = mi.load_dict(scene_dict(scene, camera), optimize=False)
    except SceneError:
        raise
    except Exception as e:  # Mitsuba's own errors (e.g. an unreadable mesh) get the scene's name
        raise SceneError(f"{scene.source}: Mitsuba could not load scene {scene.name!r}: {e}") from e
    _LOADED[key] = obj
    while len(_LOADED) > 4:
        _LOADED.popitem(last=False)
    return obj
