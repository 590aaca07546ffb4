"""Validate a scene description (plain data from YAML, TOML, XML or a dict) into a :class:`Scene`.

Every error is a :class:`SceneError` whose message reads ``file:line: field.path: what is wrong``. The
format (YAML shown; TOML and Python dicts carry the same keys)::

    name: sphere_on_plane
    description: one line saying what the scene shows
    camera: {eye: [0, 2, 6], target: [0, 0.6, 0], up: [0, 1, 0], fovy: 45,
             width: 320, height: 240, near: 0.1, far: 100}
    materials:                       # optional named materials
      grey: {albedo: [0.7, 0.7, 0.7], roughness: 1.0, metallic: 0.0}
    shapes:
      - {type: sphere, id: ball, center: [0, 1, 0], radius: 1, material: grey}
      - {type: box, id: crate, size: [1, 1, 1], translate: [2, 0.5, 0], rotate: [0, 30, 0]}
      - {type: rectangle, id: floor, size: [10, 10], rotate: [-90, 0, 0], material: {albedo: 0.8}}
      - {type: disk, id: coin, radius: 0.5}
      - {type: cylinder, id: post, p0: [0, 0, 0], p1: [0, 2, 0], radius: 0.1, caps: true}
      - {type: mesh, id: bunny, file: bunny.obj, scale: 2}
    lights:
      - {type: point, position: [2, 5, 3], intensity: 40}
      - {type: directional, direction: [0, -1, 0], irradiance: 2}
      - {type: environment, radiance: 0.3}
    render: {max_depth: 6}
"""
from __future__ import annotations

import hashlib
import math
import os
from typing import Any, Callable, Sequence

from ..camera import Camera
from .model import LIGHT_TYPES, SHAPE_TYPES, Light, Material, Scene, SceneError, Shape
from .transforms import frame_z_to, freeze4, matmul4, rotate4, scale4, translate4

Path = tuple
Locator = Callable[[Path], str]

_SHAPE_KEYS = {
    "sphere": {"center", "radius"},
    "box": {"size"},
    "rectangle": {"size"},
    "disk": {"radius"},
    "cylinder": {"p0", "p1", "radius", "caps"},
    "mesh": {"file", "face_normals"},
}
_COMMON_SHAPE_KEYS = {"type", "id", "material", "translate", "rotate", "scale"}
_LIGHT_KEYS = {"point": {"position", "intensity"}, "directional": {"direction", "irradiance"},
               "environment": {"radiance"}}


def path_str(path: Path) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "<root>"



def kind_of(v: Any) -> str:
    """What a scene-file value is, in the file's words (a YAML list is "a list", whatever class holds it).

    Example:
        >>> kind_of([1, 2]), kind_of({"a": 1}), kind_of("x"), kind_of(None), kind_of(2.5)
        ('a list', 'a mapping', "a string ('x')", 'null', 'a number (2.5)')
    """
    if v is None:
        return "null"
    if isinstance(v, bool):
        return f"a boolean ({str(v).lower()})"
    if isinstance(v, dict):
        return "a mapping"
    if isinstance(v, (list, tuple)):
        return "a list"
    if isinstance(v, str):
        return f"a string ({v[:40]!r})"
    if isinstance(v, (int, float)):
        return f"a number ({v!r})"
    return type(v).__name__

class Ctx:
    def __init__(self, locate: Locator, base_dir: str | None):
        self.locate, self.base_dir = locate, base_dir

    def fail(self, path: Path, msg: str) -> SceneError:
        return SceneError(f"{self.locate(path)}: {path_str(path)}: {msg}")

    # ------------------------------------------------------------ typed getters
    def mapping(self, v: Any, path: Path) -> dict:
        if not isinstance(v, dict):
            raise self.fail(path, f"expected a mapping, got {kind_of(v)}")
        return v

    def keys(self, d: dict, allowed: set, path: Path) -> None:
        for k in d:
            if k not in allowed:
                raise self.fail(path + (k,), f"unknown field (allowed: {', '.join(sorted(allowed))})")

    def number(self, v: Any, path: Path, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(path, f"expected a number, got {v!r}")
        x = float(v)
        if not math.isfinite(x):
            raise self.fail(path, f"must be finite, got {v!r}")
        if lo is not None and (x < lo or (lo_open and x == lo)):
            raise self.fail(path, f"must be {'>' if lo_open else '>='} {lo:g}, got {v!r}")
        if hi is not None and x > hi:
            raise self.fail(path, f"must be <= {hi:g}, got {v!r}")
        return x

    def integer(self, v: Any, path: Path, lo: int) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise self.fail(path, f"expected an integer >= {lo}, got {v!r}")
        return v

    def vec(self, v: Any, path: Path, n: int = 3, lo: float | None = None, lo_open: bool = False,
            broadcast: bool = False) -> tuple[float, ...]:
        if broadcast and isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v] * n
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise self.fail(path, f"expected a list of {n} numbers, got {v!r}")
        return tuple(self.number(x, path + (i,), lo, lo_open=lo_open) for i, x in enumerate(v))

    def text(self, v: Any, path: Path) -> str:
        if not isinstance(v, str) or not v.strip():
            raise self.fail(path, f"expected a non-empty string, got {v!r}")
        return v

    def boolean(self, v: Any, path: Path) -> bool:
        if not isinstance(v, bool):
            raise self.fail(path, f"expected true or false, got {v!r}")
        return v


def camera_from(c: Ctx, v: Any) -> Camera:
    path = ("camera",)
    d = c.mapping(v, path)
    c.keys(d, {"eye", "target", "up", "fovy", "width", "height", "near", "far"}, path)
    for k in ("eye", "target", "fovy"):
        if k not in d:
            raise c.fail(path + (k,), "missing required field")
    eye = c.vec(d["eye"], path + ("eye",))
    target = c.vec(d["target"], path + ("target",))
    up = c.vec(d.get("up", [0, 1, 0]), path + ("up",))
    fovy = c.number(d["fovy"], path + ("fovy",), 0.0, 180.0, lo_open=True)
    width = c.integer(d.get("width", 320), path + ("width",), 1)
    height = c.integer(d.get("height", 240), path + ("height",), 1)
    near = c.number(d.get("near", 0.1), path + ("near",), 0.0, lo_open=True)
    far = c.number(d.get("far", 100.0), path + ("far",), 0.0, lo_open=True)
    if far <= near:
        raise c.fail(path + ("far",), f"must be greater than near={near:g}, got {far:g}")
    try:
        return Camera.from_look_at(eye, target, up, fovy, width, height, near, far)
    except ValueError as e:
        field = str(e).split(":", 1)[0]
        field = {"fovy_deg": "fovy"}.get(field, field)      # Camera's field name -> the scene file's key
        raise c.fail(path + (field,), str(e).split(":", 1)[-1].strip()) from None


def material_from(c: Ctx, v: Any, path: Path, named: dict[str, Material]) -> Material:
    if isinstance(v, str):
        if v not in named:
            raise c.fail(path, f"unknown material {v!r} (defined: {', '.join(sorted(named)) or 'none'})")
        return named[v]
    d = c.mapping(v, path)
    c.keys(d, {"albedo", "roughness", "metallic"}, path)
    albedo = c.vec(d.get("albedo", 0.7), path + ("albedo",), lo=0.0, broadcast=True)
    if max(albedo) > 1.0:
        raise c.fail(path + ("albedo",), f"components must lie in [0, 1], got {list(albedo)}")
    return Material(albedo=albedo,  # type: ignore[arg-type]
                    roughness=c.number(d.get("roughness", 1.0), path + ("roughness",), 0.0, 1.0),
                    metallic=c.number(d.get("metallic", 0.0), path + ("metallic",), 0.0, 1.0))


def _transform(c: Ctx, d: dict, path: Path) -> list[list[float]]:
    t = c.vec(d.get("translate", [0, 0, 0]), path + ("translate",))
    r = c.vec(d.get("rotate", [0, 0, 0]), path + ("rotate",))
    s = c.vec(d.get("scale", 1.0), path + ("scale",), lo=0.0, lo_open=True, broadcast=True)
    return matmul4(translate4(t), matmul4(rotate4(r), scale4(s)))


def file_sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _shape(c: Ctx, v: Any, i: int, named: dict[str, Material], seen: set[str]) -> Shape:
    path = ("shapes", i)
    d = c.mapping(v, path)
    if "type" not in d:
        raise c.fail(path + ("type",), f"missing required field (one of: {', '.join(SHAPE_TYPES)})")
    kind = d["type"]
    if kind not in SHAPE_TYPES:
        raise c.fail(path + ("type",), f"unknown object type {kind!r} (known: {', '.join(SHAPE_TYPES)})")
    c.keys(d, _SHAPE_KEYS[kind] | _COMMON_SHAPE_KEYS, path)
    sid = c.text(d.get("id", f"{kind}_{i}"), path + ("id",))
    if sid in seen:
        raise c.fail(path + ("id",), f"duplicate shape id {sid!r}")
    if "__" in sid or not all(ch.isalnum() or ch in "_-." for ch in sid):
        raise c.fail(path + ("id",), f"ids use letters, digits, '_', '-', '.' (no '__'), got {sid!r}")
    seen.add(sid)
    mat = material_from(c, d.get("material", {}), path + ("material",), named)
    to_world = _transform(c, d, path)

    def need(key: str) -> Any:
        if key not in d:
            raise c.fail(path + (key,), "missing required field")
        return d[key]

    p: dict[str, Any] = {}
    if kind == "sphere":
        p["center"] = c.vec(d.get("center", [0, 0, 0]), path + ("center",))
        p["radius"] = c.number(need("radius"), path + ("radius",), 0.0, lo_open=True)
    elif kind == "box":
        p["size"] = c.vec(need("size"), path + ("size",), lo=0.0, lo_open=True, broadcast=True)
    elif kind == "rectangle":
        p["size"] = c.vec(need("size"), path + ("size",), n=2, lo=0.0, lo_open=True, broadcast=True)
    elif kind == "disk":
        p["radius"] = c.number(need("radius"), path + ("radius",), 0.0, lo_open=True)
    elif kind == "cylinder":
        p["p0"] = c.vec(need("p0"), path + ("p0",))
        p["p1"] = c.vec(need("p1"), path + ("p1",))
        if p["p0"] == p["p1"]:
            raise c.fail(path + ("p1",), "must differ from p0")
        p["radius"] = c.number(need("radius"), path + ("radius",), 0.0, lo_open=True)
        p["caps"] = c.boolean(d.get("caps", True), path + ("caps",))
    elif kind == "mesh":
        name = c.text(need("file"), path + ("file",))
        ext = os.path.splitext(name)[1].lower()
        if ext not in (".obj", ".ply"):
            raise c.fail(path + ("file",), f"mesh files must be .obj or .ply, got {name!r}")
        full = name if os.path.isabs(name) else os.path.join(c.base_dir or os.getcwd(), name)
        if not os.path.isfile(full):
            raise c.fail(path + ("file",), f"mesh file not found: {full}")
        p["file"] = os.path.abspath(full)
        p["sha256"] = file_sha256(full)
        p["face_normals"] = c.boolean(d.get("face_normals", False), path + ("face_normals",))
    return Shape(id=sid, type=kind, params=tuple(sorted(p.items())), to_world=freeze4(to_world),
                 material=mat, where=c.locate(path))


def light_from(c: Ctx, v: Any, i: int) -> Light:
    path = ("lights", i)
    d = c.mapping(v, path)
    kind = d.get("type")
    if kind not in LIGHT_TYPES:
        raise c.fail(path + ("type",), f"unknown light type {kind!r} (known: {', '.join(LIGHT_TYPES)})")
    c.keys(d, _LIGHT_KEYS[kind] | {"type"}, path)
    p: dict[str, Any] = {}
    if kind == "point":
        p["position"] = c.vec(d.get("position"), path + ("position",))
        p["intensity"] = c.vec(d.get("intensity", 1.0), path + ("intensity",), lo=0.0, broadcast=True)
    elif kind == "directional":
        p["direction"] = c.vec(d.get("direction"), path + ("direction",))
        if max(abs(x) for x in p["direction"]) == 0:
            raise c.fail(path + ("direction",), "must be non-zero")
        p["irradiance"] = c.vec(d.get("irradiance", 1.0), path + ("irradiance",), lo=0.0, broadcast=True)
    else:
        p["radiance"] = c.vec(d.get("radiance", 1.0), path + ("radiance",), lo=0.0, broadcast=True)
    return Light(type=kind, params=tuple(sorted(p.items())))


def scene_from_dict(data: Any, locate: Locator | None = None, source: str = "<dict>",
                    base_dir: str | None = None) -> Scene:
    """Validate plain data into a :class:`Scene`; errors name ``file:line`` (via ``locate``) and the field."""
    c = Ctx(locate or (lambda path: source), base_dir)
    d = c.mapping(data, ())
    c.keys(d, {"name", "description", "camera", "materials", "shapes", "lights", "render"}, ())
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
    shapes_v = d.get("shapes")
    if not isinstance(shapes_v, list) or not shapes_v:
        raise c.fail(("shapes",), "expected a non-empty list of shapes")
    seen: set[str] = set()
    shapes = tuple(_shape(c, s, i, named, seen) for i, s in enumerate(shapes_v))
    lights_v = d.get("lights", [])
    if not isinstance(lights_v, list):
        raise c.fail(("lights",), "expected a list of lights")
    lights = tuple(light_from(c, lv, i) for i, lv in enumerate(lights_v))
    render = c.mapping(d.get("render", {}), ("render",))
    c.keys(render, {"max_depth"}, ("render",))
    max_depth = c.integer(render.get("max_depth", 6), ("render", "max_depth"), 1)
    return Scene(name=name, description=description, shapes=shapes, lights=lights, camera=camera,
                 max_depth=max_depth, source=source)


def cylinder_caps(p0: Sequence[float], p1: Sequence[float], radius: float) -> list[list[list[float]]]:
    """``to_world`` matrices (local frame) of the two cap disks of a cylinder, normals pointing outward."""
    axis = [b - a for a, b in zip(p0, p1)]
    top = matmul4(translate4(p1), matmul4(frame_z_to(axis), scale4([radius] * 3)))
    bottom = matmul4(translate4(p0), matmul4(frame_z_to([-a for a in axis]), scale4([radius] * 3)))
    return [bottom, top]
