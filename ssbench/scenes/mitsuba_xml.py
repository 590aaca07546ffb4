"""Mitsuba 3 scene XML → :class:`Scene`: a documented subset, read as data (nothing is ever executed).

The file is parsed with ``xml.parsers.expat``; DOCTYPE/ENTITY declarations and ``<include>`` are refused, so no
external entity is resolved and no entity expansion happens. Every error reads ``file:line: what is wrong``.

Supported subset (anything else, unknown properties included, is an error naming ``file:line``, so nothing that
changes the picture is silently dropped):

* ``<scene version="x.y.z">`` root (version >= 2), ``<default name=.. value=..>`` and ``$name`` substitution.
* The first ``perspective`` sensor: ``fov`` + ``fov_axis`` (``x`` is Mitsuba's default; ``y``, ``diagonal``,
  ``smaller``, ``larger``) or ``focal_length``, converted to our vertical ``fovy`` with the film aspect;
  ``near_clip`` (0.01), ``far_clip`` (10000); ``to_world`` must be one ``<lookat>``; film ``width``/``height``
  (768×576).
* Shapes ``sphere``, ``cube`` (→ box, [-1, 1]³), ``rectangle`` and ``disk`` (unit, xy plane), ``cylinder``
  (open: ``caps: false``), ``obj``/``ply`` (→ mesh). ``to_world`` chains translate / rotate (unit axis: Mitsuba
  does not normalise it) / scale / matrix / lookat; the product must be ``T · R · S`` with positive scales (no
  shear, no mirroring) and is stored as translate / Euler rotate / scale. Area emitters on shapes are ignored.
* BSDFs, inline or ``<ref id>`` to a top-level ``<bsdf id>``: ``diffuse``, ``twosided`` (unwrapped),
  ``conductor`` (albedo 0.9 or ``specular_reflectance``), ``roughconductor`` (roughness = sqrt(alpha): our
  roughness r means GGX alpha r², as in Mitsuba's ``principled``), ``principled`` (base_color, roughness,
  metallic). Colours are ``rgb``, ``float`` or a constant ``spectrum``; textures are not supported.
* Emitters ``point``, ``constant`` (→ environment), ``directional``; ``<integrator type="path">``
  ``max_depth`` (−1, unlimited, is Mitsuba's default and also applies without an integrator: → 64). Other
  integrators, samplers and filters are ignored.
"""
from __future__ import annotations

import math
import re
from typing import Any

from .model import Scene
from .transforms import clean, decompose, identity4
from .mitsuba_xml_props import Node, Props, parse_tree
from .schema import path_str, scene_from_dict

_SHAPES = {"sphere": {"center", "radius"}, "cube": set(), "rectangle": set(), "disk": set(),
           "cylinder": {"p0", "p1", "radius"}, "obj": {"filename", "face_normals", "flip_tex_coords"},
           "ply": {"filename", "face_normals", "flip_tex_coords"}}
_IGNORED_TOP = {"bsdf", "default", "sampler", "film", "rfilter", "texture"}
_UNLIMITED_DEPTH = 64


class _Conv(Props):
    # ------------------------------------------------------------ objects
    def sensor(self, node: Node) -> dict:
        if node.get("type") != "perspective":
            raise self.err(node, f"camera: unsupported sensor type {node.get('type')!r} (only 'perspective')")
        props, kids = self.split(node, {"fov", "fov_axis", "focal_length", "near_clip", "far_clip", "to_world"},
                                 ("film", "sampler"), {"shutter_open", "shutter_close"})
        self.at(("camera",), node)
        eye, target, up = [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]
        if "to_world" in props:
            t = props["to_world"]
            bad = [op for op in t.kids if op.tag != "lookat"] + t.kids[1:]
            if bad or not t.kids:
                raise self.err(bad[0] if bad else t, "camera: sensor to_world: only a single <lookat> is supported "
                                                     "for sensors")
            eye, target, up = self.lookat(t.kids[0])
            for k in ("eye", "target", "up"):
                self.at(("camera", k), t.kids[0])
        width, height = 768, 576
        for film in (k for k in kids if k.tag == "film"):
            fp, _ = self.split(film, {"width", "height"}, ("rfilter",),
                               {"pixel_format", "component_format", "file_format", "sample_border", "compensate"})
            width = self.scalar(fp, "width", width, ("camera", "width"), integer=True)
            height = self.scalar(fp, "height", height, ("camera", "height"), integer=True)
        aspect = width / height if width > 0 and height > 0 else 1.0
        if "fov" in props:
            fov = self.scalar(props, "fov", 0.0, ("camera", "fovy"))
            axis = self.text(props, "fov_axis", "x").lower()
            axis = {"smaller": "y" if aspect > 1 else "x", "larger": "x" if aspect > 1 else "y"}.get(axis, axis)
        else:
            f = self.text(props, "focal_length", "50mm").removesuffix("mm")
            try:
                fov, axis = math.degrees(2 * math.atan(math.hypot(36, 24) / (2 * float(f)))), "diagonal"
            except (ValueError, ZeroDivisionError):
                raise self.err(props["focal_length"], f"focal_length: expected '<x>mm', got {f!r}") from None
        h = math.tan(math.radians(fov) / 2)
        if axis == "x":
            h /= aspect
        elif axis == "diagonal":
            h /= math.sqrt(1 + aspect * aspect)
        elif axis != "y":
            raise self.err(props["fov_axis"], f"camera.fov_axis: expected x, y, diagonal, smaller or larger, "
                                              f"got {axis!r}")
        return {"eye": eye, "target": target, "up": up, "fovy": math.degrees(2 * math.atan(h)), "width": width,
                "height": height, "near": self.scalar(props, "near_clip", 0.01, ("camera", "near")),
                "far": self.scalar(props, "far_clip", 10000.0, ("camera", "far"))}

    def bsdf(self, node: Node, path: tuple) -> dict:
        if node.tag == "ref":
            if node.get("id") not in self.named:
                raise self.err(node, f"{path_str(path)}: reference to unknown bsdf id {node.get('id')!r}")
            node = self.named[node.get("id")]
        kind = node.get("type")
        self.at(path, node)
        if kind == "twosided":
            _, kids = self.split(node, set(), ("bsdf", "ref"))
            if len(kids) != 1:
                raise self.err(node, f"{path_str(path)}: twosided must wrap exactly one bsdf")
            return self.bsdf(kids[0], path)
        a = path + ("albedo",)
        if kind == "diffuse":
            props, _ = self.split(node, {"reflectance"})
            return {"albedo": self.color(props, "reflectance", 0.5, a), "roughness": 1.0, "metallic": 0.0}
        if kind in ("conductor", "roughconductor"):
            rough = {"alpha", "distribution", "sample_visible"} if kind == "roughconductor" else set()
            props, _ = self.split(node, {"specular_reflectance", "material", "eta", "k"} | rough)
            alpha = self.scalar(props, "alpha", 0.1 if kind == "roughconductor" else 0.0, path + ("roughness",))
            return {"albedo": self.color(props, "specular_reflectance", 0.9, a),
                    "roughness": math.sqrt(alpha) if alpha > 0 else alpha, "metallic": 1.0}
        if kind == "principled":
            props, _ = self.split(node, {"base_color", "roughness", "metallic"})
            return {"albedo": self.color(props, "base_color", 0.5, a),
                    "roughness": self.scalar(props, "roughness", 0.5, path + ("roughness",)),
                    "metallic": self.scalar(props, "metallic", 0.0, path + ("metallic",))}
        raise self.err(node, f"{path_str(path)}: unknown bsdf type {kind!r} "
                             f"(supported: diffuse, twosided, conductor, roughconductor, principled)")

    def shape(self, node: Node, k: int) -> dict:
        kind, path = node.get("type"), ("shapes", k)
        if kind not in _SHAPES:
            raise self.err(node, f"{path_str(path + ('type',))}: unknown object type {kind!r} "
                                 f"(supported: {', '.join(_SHAPES)})")
        props, kids = self.split(node, _SHAPES[kind] | {"to_world", "flip_normals"}, ("bsdf", "ref", "emitter"))
        self.at(path, node)
        if self.flag(props, "flip_normals"):
            raise self.err(props["flip_normals"], f"{path_str(path)}: flip_normals is not supported")
        tw = props.get("to_world")
        m = self.transform(tw) if tw is not None else identity4()
        try:
            t, r, s = decompose(m)
        except ValueError as e:
            raise self.err(tw or node, f"{path_str(path)}.to_world: {e}") from None
        for key in ("translate", "rotate", "scale", "size"):
            self.at(path + (key,), tw)
        d: dict[str, Any] = {"type": kind, "id": node.get("id", f"{kind}_{k}")}
        one = lambda v: all(abs(x - 1.0) < 1e-12 for x in v)        # noqa: E731
        if kind == "sphere":
            if max(s) - min(s) > 1e-9 * max(s):
                raise self.err(tw, f"{path_str(path)}.to_world: spheres take only uniform scales, got {s}")
            c = self.xyz(props["center"], 0.0) if "center" in props else [0.0, 0.0, 0.0]
            self.at(path + ("center",), props.get("center", tw))
            d["center"] = [clean(sum(m[i][j] * c[j] for j in range(3)) + m[i][3]) for i in range(3)]
            d["radius"] = self.scalar(props, "radius", 1.0, path + ("radius",)) * s[0]
        elif kind in ("cube", "rectangle", "disk"):
            d.update(type={"cube": "box"}.get(kind, kind), translate=t, rotate=r)
            if kind == "cube":
                d["size"] = [2 * v for v in s]
            elif kind == "rectangle":
                d["size"], rest = [2 * s[0], 2 * s[1]], [1.0, 1.0, s[2]]
            else:
                d["radius"], rest = s[0], [1.0, clean(s[1] / s[0]), s[2]]
            if kind != "cube" and not one(rest):
                d["scale"] = rest
        else:
            d.update(translate=t, rotate=r)
            if not one(s):
                d["scale"] = s
            if kind == "cylinder":
                for key, default in (("p0", [0.0, 0.0, 0.0]), ("p1", [0.0, 0.0, 1.0])):
                    d[key] = self.xyz(props[key], 0.0) if key in props else default
                    self.at(path + (key,), props.get(key))
                d.update(radius=self.scalar(props, "radius", 1.0, path + ("radius",)), caps=False)
            else:
                if "filename" not in props:
                    raise self.err(node, f"{path_str(path)}.filename: missing required property")
                self.at(path + ("file",), props["filename"])
                d.update(type="mesh", file=self.text(props, "filename", ""),
                         face_normals=self.flag(props, "face_normals"))
        mats = [c for c in kids if c.tag in ("bsdf", "ref")]
        if len(mats) > 1:
            raise self.err(mats[1], f"{path_str(path)}: a shape takes at most one bsdf")
        d["material"] = (self.bsdf(mats[0], path + ("material",)) if mats else
                         {"albedo": [0.5] * 3, "roughness": 1.0, "metallic": 0.0})   # Mitsuba's default bsdf
        bad = [c for c in kids if c.tag == "emitter" and c.get("type") != "area"]
        if bad:
            raise self.err(bad[0], f"{path_str(path)}: only area emitters may be nested in a shape")
        return d

    def emitter(self, node: Node, j: int) -> dict:
        kind, path = node.get("type"), ("lights", j)
        self.at(path, node)
        if kind == "point":
            props, _ = self.split(node, {"position", "intensity", "to_world"})
            pos = (self.xyz(props["position"], 0.0) if "position" in props else
                   [row[3] for row in self.transform(props["to_world"])] if "to_world" in props else [0.0] * 3)
            self.at(path + ("position",), props.get("position", props.get("to_world")))
            return {"type": "point", "position": pos, "intensity": self.color(props, "intensity", 1.0,
                                                                               path + ("intensity",))}
        if kind == "constant":
            props, _ = self.split(node, {"radiance"})
            return {"type": "environment", "radiance": self.color(props, "radiance", 1.0, path + ("radiance",))}
        if kind == "directional":
            props, _ = self.split(node, {"direction", "irradiance", "to_world"})
            self.at(path + ("direction",), props.get("direction", props.get("to_world")))
            dv = (self.xyz(props["direction"], 0.0) if "direction" in props else
                  [row[2] for row in self.transform(props["to_world"])[:3]] if "to_world" in props else [0, 0, 1.0])
            return {"type": "directional", "direction": dv,
                    "irradiance": self.color(props, "irradiance", 1.0, path + ("irradiance",))}
        raise self.err(node, f"{path_str(path + ('type',))}: unsupported emitter type {kind!r} (supported: "
                             f"point, constant, directional; area emitters only inside shapes)")

    def scene(self, root: Node) -> dict:
        if root.tag != "scene":
            raise self.err(root, f"the root element must be <scene version=...>, got <{root.tag}>")
        self.at((), root)
        version = root.get("version", "")
        if not re.fullmatch(r"\d+\.\d+\.\d+", version) or int(version.split(".")[0]) < 2:
            raise self.err(root, f"scene version: expected 'x.y.z' with x >= 2 (Mitsuba 2/3), got {version!r}")
        params = {}
        for k in (k for k in root.kids if k.tag == "default"):
            if not re.fullmatch(r"\w+", k.get("name", "")) or "value" not in k.attrs or k.kids:
                raise self.err(k, "<default> takes a name (letters, digits, _) and a value, and no children")
            params[k.get("name")] = k.get("value")
        self.substitute(root, params)
        self.named = {k.get("id"): k for k in root.kids if k.tag == "bsdf" and k.get("id")}
        data: dict[str, Any] = {"description": "converted from Mitsuba XML", "shapes": [], "lights": [],
                                "render": {"max_depth": _UNLIMITED_DEPTH}}   # Mitsuba's default: path, -1
        for k in root.kids:
            if k.tag == "sensor":
                if "camera" not in data:           # Mitsuba renders with the first sensor
                    data["camera"] = self.sensor(k)
            elif k.tag == "shape":
                data["shapes"].append(self.shape(k, len(data["shapes"])))
            elif k.tag == "emitter":
                data["lights"].append(self.emitter(k, len(data["lights"])))
            elif k.tag == "integrator" and k.get("type") == "path":
                props, _ = self.split(k, {"max_depth"}, ignore={"rr_depth", "hide_emitters"})
                depth = self.scalar(props, "max_depth", -1, ("render", "max_depth"), integer=True)
                data["render"] = {"max_depth": _UNLIMITED_DEPTH if depth == -1 else depth}
            elif k.tag not in _IGNORED_TOP and k.tag != "integrator":
                raise self.err(k, f"unsupported top-level element <{k.tag}>")
        if "camera" not in data:
            raise self.err(root, "camera: the scene has no <sensor>")
        return data

    def substitute(self, node: Node, params: dict) -> None:
        for key, v in node.attrs.items():
            if "$" in v and node.tag != "default":
                for name in sorted(params, key=len, reverse=True):
                    v = v.replace("$" + name, params[name])
                if "$" in v:
                    raise self.err(node, f"undefined parameter in {key}={v!r} (declare it with <default>)")
                node.attrs[key] = v
        for kid in node.kids:
            self.substitute(kid, params)


def parse_mitsuba_xml(text: str, filename: str = "<xml>", base_dir: str | None = None) -> Scene:
    """Parse Mitsuba 3 scene XML (the subset in the module docstring). Errors name ``filename:line``."""
    conv = _Conv(filename)
    data = conv.scene(parse_tree(text, filename))
    return scene_from_dict(data, conv.locate, filename, base_dir)
