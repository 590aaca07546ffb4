"""Built-in scenes, each chosen for an artifact the source articles discuss.

Scenes are plain data run through the same validator as scene files, so the catalog doubles as a set of
format examples (``ssbench scenes`` lists them). Boxes that rest on the floor float 1e-3 above it: coplanar
faces would hide their bottom face from the back-face (exit depth) search and z-fight in the path tracer.
"""
from __future__ import annotations

import copy
import math
from typing import Any, Callable

from .model import Scene
from .schema import scene_from_dict

_LIFT = 1e-3
GREY = {"albedo": [0.7, 0.7, 0.7]}
WHITE = {"albedo": [0.8, 0.8, 0.8]}
RED = {"albedo": [0.8, 0.1, 0.1]}
GREEN = {"albedo": [0.1, 0.7, 0.1]}
BLUE = {"albedo": [0.2, 0.3, 0.8]}
MIRROR = {"albedo": [0.9, 0.9, 0.9], "roughness": 0.0, "metallic": 1.0}
LIGHTS = [{"type": "point", "position": [2, 5, 3], "intensity": 40}, {"type": "environment", "radiance": 0.3}]


def _cam(eye, target, fovy=45.0, near=0.1, far=100.0) -> dict:
    return {"eye": eye, "target": target, "up": [0, 1, 0], "fovy": fovy, "width": 320, "height": 240,
            "near": near, "far": far}


def _floor(size=20.0, mat=None, sid="floor") -> dict:
    return {"type": "rectangle", "id": sid, "size": [size, size], "rotate": [-90, 0, 0],
            "material": mat or GREY}


def _box(sid, size, at, mat=None, rotate=(0, 0, 0)) -> dict:
    """A box standing on the floor (y = 0) with its base centre at ``at = (x, z)``."""
    return {"type": "box", "id": sid, "size": list(size), "rotate": list(rotate),
            "translate": [at[0], size[1] / 2 + _LIFT, at[1]], "material": mat or GREY}


def sphere_on_plane() -> dict:
    return {"name": "sphere_on_plane",
            "description": "A sphere touching a floor: contact occlusion, and SSAO's grey bias on open floor.",
            "camera": _cam([0, 2, 6], [0, 0.6, 0]),
            "shapes": [_floor(), {"type": "sphere", "id": "ball", "center": [0, 1, 0], "radius": 1,
                                  "material": BLUE}],
            "lights": LIGHTS}


def crease() -> dict:
    return {"name": "crease",
            "description": "A wall meets the floor: AO along a crease has the closed form 1-(acos a - a*sqrt(1-a^2))/pi.",
            "camera": _cam([1.5, 2.5, 5], [0, 0.5, -1.5]),
            "shapes": [_floor(), {"type": "rectangle", "id": "wall", "size": [20, 10], "translate": [0, 5, -3],
                                  "material": WHITE}],
            "lights": LIGHTS}


def cornell_box() -> dict:
    wall = lambda sid, t, r, m: {"type": "rectangle", "id": sid, "size": [2, 2], "translate": t, "rotate": r,
                                 "material": m}
    return {"name": "cornell_box",
            "description": "A Cornell-style box: corners, colour bleeding and occlusion between two blocks.",
            "camera": _cam([0, 1, 3.4], [0, 1, 0], fovy=40),
            "shapes": [wall("floor", [0, 0, 0], [-90, 0, 0], WHITE), wall("ceiling", [0, 2, 0], [90, 0, 0], WHITE),
                       wall("back", [0, 1, -1], [0, 0, 0], WHITE), wall("left", [-1, 1, 0], [0, 90, 0], RED),
                       wall("right", [1, 1, 0], [0, -90, 0], GREEN),
                       _box("tall_block", [0.6, 1.2, 0.6], (-0.35, -0.3), WHITE, (0, 20, 0)),
                       _box("short_block", [0.6, 0.6, 0.6], (0.35, 0.3), WHITE, (0, -18, 0))],
            "lights": [{"type": "point", "position": [0, 1.8, 0.2], "intensity": 3},
                       {"type": "environment", "radiance": 0.1}]}


def fence() -> dict:
    slats = [_box(f"slat_{k}", [0.04, 1.6, 0.02], (-1.2 + 0.3 * k, 0.0), WHITE) for k in range(9)]
    return {"name": "fence",
            "description": "Thin slats (2 cm) before a sphere and a wall: thin-object punch-through in marchers.",
            "camera": _cam([0.3, 1.4, 4], [0, 0.7, -1]),
            "shapes": [_floor(mat=MIRROR), {"type": "rectangle", "id": "wall", "size": [20, 10],
                                            "translate": [0, 5, -3], "material": GREY},
                       {"type": "sphere", "id": "ball", "center": [0.2, 0.6, -1.4], "radius": 0.6,
                        "material": RED}] + slats,
            "lights": LIGHTS}


def stairs() -> dict:
    steps = [_box(f"step_{k}", [3, 0.2 * (k + 1), 0.4], (0, -0.4 * k), GREY) for k in range(8)]
    return {"name": "stairs",
            "description": "A staircase: many parallel creases that show banding as sample counts drop.",
            "camera": _cam([3, 2.5, 3.5], [0, 0.6, -1.2]),
            "shapes": [_floor(mat=WHITE)] + steps,
            "lights": LIGHTS}


def reflective_floor() -> dict:
    return {"name": "reflective_floor",
            "description": "A mirror floor with objects cut by the frame and one hidden behind another (SSR fails).",
            "camera": _cam([0, 1.2, 5], [0, 0.6, 0]),
            "shapes": [_floor(mat=MIRROR),
                       {"type": "sphere", "id": "front_ball", "center": [0, 0.5, 0.5], "radius": 0.5,
                        "material": BLUE},
                       _box("hidden_box", [0.5, 0.5, 0.5], (0.1, -0.8), RED),
                       {"type": "sphere", "id": "edge_ball", "center": [-2.3, 0.7, 0], "radius": 0.7,
                        "material": GREEN},
                       _box("tall_pillar", [0.4, 4.0, 0.4], (1.6, -0.5), WHITE),
                       {"type": "rectangle", "id": "wall", "size": [20, 10], "translate": [0, 5, -4],
                        "material": GREY}],
            "lights": LIGHTS}


def grazing_floor() -> dict:
    return {"name": "grazing_floor",
            "description": "A long floor seen at a grazing angle: stretched samples, tangent bias, depth precision.",
            "camera": _cam([0, 0.25, 6], [0, 0.1, -4], fovy=50),
            "shapes": [_floor(size=60), _box("block", [0.6, 0.6, 0.6], (0.8, -2), RED),
                       {"type": "sphere", "id": "ball", "center": [-0.7, 0.3, 0], "radius": 0.3,
                        "material": BLUE}],
            "lights": LIGHTS}


#: the roughness ramp of ``glossy_ramp``'s floor strips (left to right) and of its metal spheres
FLOOR_ROUGHNESS = (0.0, 0.05, 0.1, 0.2, 0.35, 0.5)
SPHERE_ROUGHNESS = (0.0, 0.1, 0.2, 0.35, 0.5)


def glossy_ramp() -> dict:
    strips = [{"type": "rectangle", "id": f"strip_{k}", "size": [1.0, 20.0], "rotate": [-90, 0, 0],
               "translate": [-3.0 + 1.0 * k + 0.5, 0.0, 0.0],
               "material": {"albedo": [0.85, 0.85, 0.85], "roughness": r, "metallic": 1.0}}
              for k, r in enumerate(FLOOR_ROUGHNESS)]
    balls = [{"type": "sphere", "id": f"metal_{k}", "center": [-2.0 + 1.0 * k, 0.35 + _LIFT, -0.6], "radius": 0.35,
              "material": {"albedo": [0.95, 0.75, 0.35], "roughness": r, "metallic": 1.0}}
             for k, r in enumerate(SPHERE_ROUGHNESS)]
    posts = [_box("red_post", [0.4, 1.6, 0.4], (-1.5, -2.2), RED), _box("green_post", [0.4, 1.0, 0.4], (0.0, -2.6), GREEN),
             _box("blue_post", [0.4, 2.0, 0.4], (1.5, -2.2), BLUE)]
    return {"name": "glossy_ramp",
            "description": "A metal floor in strips of rising roughness (0 to 0.5) and metal spheres likewise: "
                           "mirror vs glossy reflections, and where screen-space rays miss.",
            "camera": _cam([0.0, 1.3, 4.5], [0.0, 0.4, -1.0]),
            "shapes": strips + balls + posts + [{"type": "rectangle", "id": "wall", "size": [20, 10],
                                                   "translate": [0, 5, -4], "material": WHITE}],
            "lights": LIGHTS}


WOOD = {"albedo": [0.42, 0.27, 0.15]}
VARNISH = {"albedo": [0.35, 0.2, 0.1], "roughness": 0.25}
PAPER = [{"albedo": [0.6, 0.15, 0.1]}, {"albedo": [0.15, 0.3, 0.55]}, {"albedo": [0.75, 0.7, 0.55]},
         {"albedo": [0.2, 0.45, 0.25]}, {"albedo": [0.5, 0.5, 0.5]}]


def _block(sid, size, centre, mat, rotate=(0, 0, 0)) -> dict:
    """A box by its centre (furniture parts off the floor)."""
    return {"type": "box", "id": sid, "size": list(size), "rotate": list(rotate), "translate": list(centre),
            "material": mat}


def _table(x, z, top_y=0.74) -> list:
    legs = [_block(f"table_leg_{i}", [0.05, top_y - 0.03, 0.05], [x + dx, (top_y - 0.03) / 2 + _LIFT, z + dz], WOOD)
            for i, (dx, dz) in enumerate([(-0.55, -0.3), (0.55, -0.3), (-0.55, 0.3), (0.55, 0.3)])]
    return legs + [_block("table_top", [1.25, 0.04, 0.72], [x, top_y - 0.01, z], VARNISH)]


def _chair(x, z, turn) -> list:
    c, s = math.cos(math.radians(turn)), math.sin(math.radians(turn))
    at = lambda dx, dz: (x + c * dx + s * dz, z - s * dx + c * dz)                      # noqa: E731
    parts = [_block(f"chair_leg_{i}", [0.035, 0.44, 0.035], [*at(dx, dz)[:1], 0.22 + _LIFT, at(dx, dz)[1]],
                    WOOD, (0, turn, 0)) for i, (dx, dz) in enumerate([(-0.18, -0.18), (0.18, -0.18),
                                                                      (-0.18, 0.18), (0.18, 0.18)])]
    sx, sz = at(0, 0)
    bx, bz = at(0, 0.185)
    return parts + [_block("chair_seat", [0.42, 0.035, 0.42], [sx, 0.46, sz], WOOD, (0, turn, 0)),
                    _block("chair_back", [0.42, 0.42, 0.03], [bx, 0.69, bz], WOOD, (0, turn, 0))]


def _shelf(x, z) -> list:
    parts = [_block(f"shelf_side_{i}", [0.03, 1.7, 0.3], [x + dx, 0.85 + _LIFT, z], WOOD)
             for i, dx in enumerate((-0.48, 0.48))]
    books, k = [], 0
    for j, y in enumerate((0.05, 0.45, 0.85, 1.25, 1.65)):
        parts.append(_block(f"shelf_{j}", [0.93, 0.025, 0.3], [x, y, z], WOOD))
        if j == 4:
            continue
        u = x - 0.44
        while u < x + 0.36 - 0.05 * (j % 2):
            w, h = 0.03 + 0.012 * ((k * 7) % 3), 0.22 + 0.03 * ((k * 5) % 4)
            books.append(_block(f"book_{k}", [w, h, 0.2], [u + w / 2, y + 0.0125 + h / 2 + _LIFT, z + 0.02],
                                PAPER[k % len(PAPER)]))
            u, k = u + w + 0.004 * (1 + k % 3), k + 1                                  # thin gaps between books
    return parts + books


def furnished_room() -> dict:
    return {"name": "furnished_room",
            "description": "A furnished room: table, chair, a shelf of books with thin gaps, small objects.",
            "camera": _cam([1.1, 1.3, 2.3], [-0.45, 0.7, -0.7], fovy=55),
            "shapes": [_floor(size=8, mat=WOOD),
                       {"type": "rectangle", "id": "back_wall", "size": [8, 4], "translate": [0, 2, -1.5],
                        "material": WHITE},
                       {"type": "rectangle", "id": "side_wall", "size": [8, 4], "translate": [-2, 2, 0],
                        "rotate": [0, 90, 0], "material": WHITE}]
                      + _table(0.2, 0.3) + _chair(0.2, 1.0, 180) + _shelf(-1.2, -1.33)
                      + [{"type": "sphere", "id": "apple", "center": [0.45, 0.78, 0.35], "radius": 0.045,
                          "material": RED},
                         {"type": "cylinder", "id": "cup", "p0": [0.0, 0.741, 0.2], "p1": [0.0, 0.84, 0.2],
                          "radius": 0.04, "caps": True, "material": WHITE},
                         _block("book_on_table", [0.22, 0.04, 0.3], [-0.2, 0.761, 0.45], PAPER[1], (0, 25, 0))],
            "lights": [{"type": "point", "position": [0.5, 2.6, 1.0], "intensity": 8},
                       {"type": "environment", "radiance": 0.25}]}


def _scaled(build: Callable[[], dict], s: float, name: str, what: str) -> Callable[[], dict]:
    """A copy of a scene with every length multiplied by ``s`` (camera, near/far and lights included)."""
    def scaled() -> dict:
        d = copy.deepcopy(build())
        d["name"], d["description"] = name, what
        cam = d["camera"]
        for k in ("eye", "target"):
            cam[k] = [v * s for v in cam[k]]
        cam["near"], cam["far"] = cam["near"] * s, cam["far"] * s
        for sh in d["shapes"]:
            for k in ("center", "translate", "p0", "p1"):
                if k in sh:
                    sh[k] = [v * s for v in sh[k]]
            for k in ("radius",):
                if k in sh:
                    sh[k] = sh[k] * s
            if "size" in sh:
                sh["size"] = [v * s for v in sh["size"]]
        for light in d["lights"]:
            if light["type"] == "point":
                light["position"] = [v * s for v in light["position"]]
                light["intensity"] = light["intensity"] * s * s      # same irradiance at scaled distances
        return d
    return scaled


CATALOG: dict[str, Callable[[], dict]] = {
    "sphere_on_plane": sphere_on_plane,
    "crease": crease,
    "cornell_box": cornell_box,
    "fence": fence,
    "stairs": stairs,
    "reflective_floor": reflective_floor,
    "grazing_floor": grazing_floor,
    "glossy_ramp": glossy_ramp,
    "furnished_room": furnished_room,
    "sphere_on_plane_small": _scaled(sphere_on_plane, 0.01, "sphere_on_plane_small",
                                     "sphere_on_plane scaled by 0.01: a scale-invariant pass gives the same image."),
    "sphere_on_plane_large": _scaled(sphere_on_plane, 100.0, "sphere_on_plane_large",
                                     "sphere_on_plane scaled by 100: a scale-invariant pass gives the same image."),
}


def names() -> list[str]:
    """Names of the built-in scenes, in catalog order."""
    return list(CATALOG)


def describe() -> dict[str, str]:
    """``{name: one-line description}`` of the built-in scenes."""
    return {n: CATALOG[n]()["description"] for n in CATALOG}


def get(name: str) -> Scene:
    """Build a catalog scene by name."""
    if name not in CATALOG:
        raise KeyError(f"name_or_path: unknown scene {name!r}; built-in scenes: {', '.join(CATALOG)}")
    return scene_from_dict(CATALOG[name](), source=f"<catalog:{name}>")


def as_dict(name: str) -> dict[str, Any]:
    """The raw description of a catalog scene (a template for your own scene files)."""
    if name not in CATALOG:
        raise KeyError(f"name: unknown scene {name!r}; built-in scenes: {', '.join(CATALOG)}")
    return CATALOG[name]()
