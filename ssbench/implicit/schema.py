"""Validate an implicit-surface scene (plain data from YAML, TOML or a dict) into an :class:`ImplicitScene`.

The same reader (``ssbench.scenes.files``), the same ``file:line: field.path: what is wrong`` errors and the
same camera / material / light rules as ``ssbench.scenes.schema``. The format (YAML shown)::

    name: torus
    description: one line saying what the scene shows
    camera: {eye: [0, 2, 5], target: [0, 0, 0], up: [0, 1, 0], fovy: 45, width: 160, height: 120,
             near: 0.1, far: 12}
    materials: {gold: {albedo: [1, 0.8, 0.3], roughness: 0.3, metallic: 1}}
    params: {R: 1.0, r: 0.35}                       # scene-wide named parameters
    define: {ring: "length(vec3(length(vec3(x, 0, z)) - R, y, 0)) - r"}    # named sub-expressions
    implicit:                                       # the union of these objects is the surface
      - {id: torus, f: "ring", bounds: [[-1.4, -0.4, -1.4], [1.4, 0.4, 1.4]], lipschitz: 1.0,
         material: gold, translate: [0, 0, 0], rotate: [0, 0, 0], scale: 1}
    lights: [{type: point, position: [3, 5, 4], intensity: 40}]
    animation: {frames: 60, segments: [{frames: [20, 40], object: torus, translate_per_frame: [0.02, 0, 0]},
                                       {frames: [40, 60], camera: {eye_per_frame: [0.05, 0, 0]}}]}

``f`` is parsed by the whitelist parser of ``expression.py`` (nothing is ever executed); ``bounds`` is the
local box outside which f > 0 (required; f > 0 on its faces is proved at load by ``bounds.py``, a box the
surface reaches is refused naming the face); ``lipschitz`` an optional declared bound on |∇f|; ``scale`` is
uniform. Expression errors are reported as ``file:line: implicit[0].f: ...``.
"""
from __future__ import annotations

import os
import re
from typing import Any

from ..scenes.files import read_data_file, read_toml, read_yaml
from ..scenes.model import Material, SceneError
from ..scenes.schema import camera_from, Ctx, light_from, material_from, path_str
from .bounds import BoundsError
from .expression import parse
from .parser import ExpressionError
from .scene import Animation, ImplicitScene, Segment
from .surface import ImplicitObject
from .union import ImplicitSurface

_TOP_KEYS = {"name", "description", "camera", "materials", "params", "define", "implicit", "lights", "animation"}
_OBJECT_KEYS = {"id", "f", "bounds", "lipschitz", "material", "translate", "rotate", "scale"}
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_IN_DEF = re.compile(r": definition '([A-Za-z_][A-Za-z0-9_]*)'$")
MAX_FRAMES = 100_000


def _where(c: Ctx, path: tuple) -> str:
    return f"{c.locate(path)}: {path_str(path)}"


def _parse(c: Ctx, text: str, path: tuple, params: dict, defs: dict):
    """Parse with ``where = "file:line: field.path"``; an error inside a definition points at its line."""
    where = _where(c, path)
    try:
        return parse(text, params=params, defs=defs, where=where)
    except ExpressionError as e:
        msg, m = str(e), _IN_DEF.search(str(getattr(e, "where", "")))
        if m and m.group(1) in defs and msg.startswith(e.where):
            def_where = _where(c, ("define", m.group(1)))
            raise SceneError(def_where + msg[len(e.where):]) from None
        raise (SceneError(msg) if msg.startswith(where) else c.fail(path, msg)) from None


def _names(c: Ctx, v: Any, path: tuple) -> dict:
    d = c.mapping(v, path)
    for k in d:
        if not isinstance(k, str) or not _NAME.match(k):
            raise c.fail(path + (k,), f"names use letters, digits and '_' and do not start with a digit, got {k!r}")
    return d


def _object(c: Ctx, v: Any, i: int, named: dict, params: dict, defs: dict, seen: set) -> ImplicitObject:
    path = ("implicit", i)
    d = c.mapping(v, path)
    c.keys(d, _OBJECT_KEYS, path)
    oid = c.text(d.get("id", f"implicit_{i}"), path + ("id",))
    if oid in seen:
        raise c.fail(path + ("id",), f"duplicate object id {oid!r}")
    if "__" in oid or not all(ch.isalnum() or ch in "_-." for ch in oid):
        raise c.fail(path + ("id",), f"ids use letters, digits, '_', '-', '.' (no '__'), got {oid!r}")
    seen.add(oid)
    for key in ("f", "bounds"):
        if key not in d:
            raise c.fail(path + (key,), "missing required field")
    expr = _parse(c, c.text(d["f"], path + ("f",)), path + ("f",), params, defs)
    bp = path + ("bounds",)
    b = d["bounds"]
    if not isinstance(b, list) or len(b) != 2:
        raise c.fail(bp, f"expected [[x0, y0, z0], [x1, y1, z1]], got {b!r}")
    lo, hi = c.vec(b[0], bp + (0,)), c.vec(b[1], bp + (1,))
    for k, axis in enumerate("xyz"):
        if not lo[k] < hi[k]:
            raise c.fail(bp, f"lower corner must be < upper corner on every axis, got {axis}: {lo[k]:g} >= {hi[k]:g}")
    lam = d.get("lipschitz")
    lam = None if lam is None else c.number(lam, path + ("lipschitz",), 0.0, lo_open=True)
    mat = material_from(c, d.get("material", {}), path + ("material",), named)
    if isinstance(d.get("scale"), list):
        raise c.fail(path + ("scale",), "only a uniform scale (one number > 0) keeps f a distance bound")
    translate = c.vec(d.get("translate", [0, 0, 0]), path + ("translate",))
    rotate = c.vec(d.get("rotate", [0, 0, 0]), path + ("rotate",))
    scale = c.number(d.get("scale", 1.0), path + ("scale",), 0.0, lo_open=True)
    try:
        return ImplicitObject(id=oid, expression=expr, material=mat, bounds=(lo, hi), lipschitz=lam,
                              translate=translate, rotate=rotate, scale=scale, where=c.locate(path))
    except BoundsError as e:                               # the surface reaches a face of the box
        raise c.fail(bp, str(e)) from None


def _segment(c: Ctx, v: Any, j: int, frames: int, ids: set) -> Segment:
    path = ("animation", "segments", j)
    d = c.mapping(v, path)
    c.keys(d, {"frames", "object", "translate_per_frame", "camera"}, path)
    fr = d.get("frames")
    if not isinstance(fr, list) or len(fr) != 2:
        raise c.fail(path + ("frames",), f"expected [first, stop) as two integers, got {fr!r}")
    a, b = (c.integer(x, path + ("frames", k), 0) for k, x in enumerate(fr))
    if not a < b <= frames:
        raise c.fail(path + ("frames",), f"need 0 <= first < stop <= animation.frames={frames}, got [{a}, {b}]")
    if ("object" in d) == ("camera" in d):
        raise c.fail(path, "a segment moves exactly one thing: give either 'object' or 'camera'")
    if "object" in d:
        if d["object"] not in ids:
            raise c.fail(path + ("object",), f"unknown object {d['object']!r} (objects: {', '.join(sorted(ids))})")
        if "translate_per_frame" not in d:
            raise c.fail(path + ("translate_per_frame",), "missing required field")
        return Segment(a, b, object=d["object"],
                       translate_per_frame=c.vec(d["translate_per_frame"], path + ("translate_per_frame",)))
    if "translate_per_frame" in d:
        raise c.fail(path + ("translate_per_frame",), "only for object segments (camera: eye/target_per_frame)")
    cp = path + ("camera",)
    cam = c.mapping(d["camera"], cp)
    c.keys(cam, {"eye_per_frame", "target_per_frame"}, cp)
    return Segment(a, b, eye_per_frame=c.vec(cam.get("eye_per_frame", [0, 0, 0]), cp + ("eye_per_frame",)),
                   target_per_frame=c.vec(cam.get("target_per_frame", [0, 0, 0]), cp + ("target_per_frame",)))


def _animation(c: Ctx, v: Any, ids: set) -> Animation:
    path = ("animation",)
    d = c.mapping(v, path)
    c.keys(d, {"frames", "segments"}, path)
    if "frames" not in d:
        raise c.fail(path + ("frames",), "missing required field")
    frames = c.integer(d["frames"], path + ("frames",), 1)
    if frames > MAX_FRAMES:
        raise c.fail(path + ("frames",), f"must be <= {MAX_FRAMES}, got {frames}")
    segs = d.get("segments", [])
    if not isinstance(segs, list):
        raise c.fail(path + ("segments",), "expected a list of segments")
    return Animation(frames, tuple(_segment(c, s, j, frames, ids) for j, s in enumerate(segs)))


def scene_from_dict(data: Any, locate=None, source: str = "<dict>") -> ImplicitScene:
    """Validate plain data into an :class:`ImplicitScene`; errors name ``file:line`` and the field."""
    c = Ctx(locate or (lambda path: source), None)
    d = c.mapping(data, ())
    if "implicit" not in d and "shapes" in d:
        raise c.fail(("shapes",), "a mesh/analytic-shape scene; load it with ssbench.scenes.load")
    c.keys(d, _TOP_KEYS, ())
    name = c.text(d.get("name", os.path.splitext(os.path.basename(source))[0] or "scene"), ("name",))
    description = d.get("description", "")
    if not isinstance(description, str):
        raise c.fail(("description",), "expected a string")
    if "camera" not in d:
        raise c.fail(("camera",), "missing required field")
    camera = camera_from(c, d["camera"])
    named: dict[str, Material] = {}
    for k, mv in c.mapping(d.get("materials", {}), ("materials",)).items():
        named[k] = material_from(c, mv, ("materials", k), {})
    params = {k: c.number(x, ("params", k)) for k, x in _names(c, d.get("params", {}), ("params",)).items()}
    defs = {k: c.text(x, ("define", k)) for k, x in _names(c, d.get("define", {}), ("define",)).items()}
    for k in defs:
        if k in params:
            raise c.fail(("define", k), f"{k!r} is already a parameter")
    for k, x in params.items():                       # names that shadow x, y, z, p, pi or a function
        _parse(c, "0", ("params", k), {k: x}, {})
    _parse(c, "0", ("define",), params, defs)        # every definition is parsed and checked, used or not
    objs_v = d.get("implicit")
    if not isinstance(objs_v, list) or not objs_v:
        raise c.fail(("implicit",), "expected a non-empty list of implicit objects")
    seen: set[str] = set()
    objects = ImplicitSurface(tuple(_object(c, o, i, named, params, defs, seen) for i, o in enumerate(objs_v)))
    lights_v = d.get("lights", [])
    if not isinstance(lights_v, list):
        raise c.fail(("lights",), "expected a list of lights")
    lights = tuple(light_from(c, lv, i) for i, lv in enumerate(lights_v))
    animation = _animation(c, d["animation"], seen) if d.get("animation") is not None else None
    scene = ImplicitScene(name=name, description=description, objects=objects, lights=lights, camera=camera,
                          animation=animation, source=source)
    if animation is not None and any(s.object is None for s in animation.segments):
        for k in range(animation.frames + 1):       # the moving camera must stay a valid camera
            try:
                scene.camera_at(k)
            except ValueError as e:
                raise c.fail(("animation", "segments"), f"camera invalid at frame {k}: {e}") from None
    return scene


def scene_from_yaml(text: str, filename: str = "<yaml>") -> ImplicitScene:
    """Parse YAML implicit-scene text; errors name ``filename:line``."""
    return scene_from_dict(*read_yaml(text, filename), source=filename)


def scene_from_toml(text: str, filename: str = "<toml>") -> ImplicitScene:
    """Parse TOML implicit-scene text; errors name ``filename:line``."""
    return scene_from_dict(*read_toml(text, filename), source=filename)


def scene_from_file(path: "str | os.PathLike") -> ImplicitScene:
    """Load a ``.yaml``/``.yml``/``.toml`` implicit-scene file."""
    return scene_from_dict(*read_data_file(path), source=os.fspath(path))
