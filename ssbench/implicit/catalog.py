"""Built-in implicit scenes: the hard cases of ray casting implicit surfaces (thin shells, grazing and tangent
rays, double roots, invalid Lipschitz bounds; Hart 1996, Mitchell 1990, Knoll et al. 2009 in ``ssbench/REFERENCES.md``).

Each entry is plain data run through the same validator as scene files (``schema.py``), so the catalog
doubles as format examples. Every camera is small (160×120) with near 0.1 and a *small* far (8–12): the
fixed-step and progressive methods step ``h = far / N``, and the thin cases are designed against
``N = 32`` (``h = 8/32 = 0.25``). Bounds are honest (f > 0 outside, tested); λ is declared only where it is
a true global bound on |∇f|, except in ``displaced_torus``, whose λ = 1 is wrong on purpose.
"""
from __future__ import annotations

from typing import Any, Callable

from .scene import ImplicitScene
from .schema import scene_from_dict

#: marching steps the thin cases are designed against (``h = far / DESIGN_STEPS``)
DESIGN_STEPS = 32
LIGHT = {"type": "point", "position": [3, 5, 4], "intensity": 40}
TORUS = "length(vec3(length(vec3(x, 0, z)) - R, y, 0)) - r"


def _cam(eye, target=(0, 0, 0), far=8.0, fovy=45.0) -> dict:
    return {"eye": list(eye), "target": list(target), "up": [0, 1, 0], "fovy": fovy, "width": 160,
            "height": 120, "near": 0.1, "far": far}


def _box(h: float) -> list:
    return [[-h, -h, -h], [h, h, h]]


def _scene(name: str, description: str, camera: dict, objects: list, albedo=(0.8, 0.6, 0.3), **extra) -> dict:
    d = {"name": name, "description": description, "camera": camera,
         "materials": {"main": {"albedo": list(albedo), "roughness": 0.5}},
         "implicit": [{"material": "main", **o} for o in objects], "lights": [LIGHT]}
    d.update(extra)
    return d


def sphere() -> dict:
    return _scene("sphere", "Unit sphere: the analytic reference (the article's ray-sphere quadratic gives t exactly).",
                  _cam([0, 1, 4]), [{"id": "ball", "f": "length(p) - 1", "bounds": _box(1.05), "lipschitz": 1.0}])


def torus() -> dict:
    return _scene("torus", "Torus R = 1, r = 0.35 about y: first hits have closed-form quartic roots.",
                  _cam([0, 2, 4], far=10.0),
                  [{"id": "torus", "f": "ring", "bounds": [[-1.4, -0.4, -1.4], [1.4, 0.4, 1.4]], "lipschitz": 1.0}],
                  params={"R": 1.0, "r": 0.35}, define={"ring": TORUS})


def thin_shell() -> dict:
    return _scene("thin_shell", "Shell |‖p‖−1| − w, w = 0.01 (wall 2w = 0.02) vs h = far/N = 8/32 = 0.25: fixed "
                  "steps punch through; a jittered step finds the wall w.p. ≈ 2w/h = 8% a frame.",
                  _cam([0, 0.8, 3.2]), [{"id": "shell", "f": "abs(length(p) - R) - w", "bounds": _box(1.05),
                                         "lipschitz": 1.0}], params={"R": 1.0, "w": 0.01})


def thin_plate() -> dict:
    return _scene("thin_plate", "Square plate |z| − w, w = 0.01, clipped to |x|, |y| <= 1 and turned 35° about y: "
                  "a slab ≈ 0.024 thick along the rays, far thinner than h = 0.25.",
                  _cam([0, 0.6, 3.5]), [{"id": "plate", "f": "max(abs(z) - w, max(abs(x), abs(y)) - 1)",
                                         "bounds": [[-1.05, -1.05, -0.05], [1.05, 1.05, 0.05]], "lipschitz": 1.0,
                                         "rotate": [0, 35, 0]}], params={"w": 0.01})


def gyroid_sheet() -> dict:
    return _scene("gyroid_sheet", "Gyroid sheet k = 8 (period 0.79), |g|/(2√3k) − w with w = 0.01, inside the unit "
                  "sphere: high frequency, thin walls, and interval arithmetic's dependency problem.",
                  _cam([0, 1, 3.2]), [{"id": "gyroid", "f": "max(abs(g) / (2*sqrt(3)*k) - w, length(p) - 1)",
                                       "bounds": _box(1.05), "lipschitz": 1.0}],
                  params={"k": 8.0, "w": 0.01},
                  define={"g": "sin(k*x)*cos(k*y) + sin(k*y)*cos(k*z) + sin(k*z)*cos(k*x)"})


def tangent_sphere() -> dict:
    return _scene("tangent_sphere", "Telephoto (fovy 6°) from the plane tangent to the top of a unit sphere: the "
                  "horizon arc spans the image; ~1000 rays cut chords < 0.4 (chord 2√(2δ) → 0).",
                  _cam([0, 1, 3.5], [0, 1, 0], fovy=6.0),
                  [{"id": "ball", "f": "length(p) - 1", "bounds": _box(1.05), "lipschitz": 1.0}])


def double_root() -> dict:
    return _scene("double_root", "(‖p‖−1)²: f >= 0 everywhere, a double root with no sign change, so sign-change "
                  "methods (fixed step, progressive, bisection) cannot see it; no λ (|∇f| = 2|‖p‖−1|).",
                  _cam([0, 1, 4]), [{"id": "ball", "f": "(length(p) - 1)^2", "bounds": _box(1.05)}])


def badly_scaled() -> dict:
    return _scene("badly_scaled", "1000(x²+y²+z²−1): the unit sphere with |∇f| = 2000‖p‖, no usable distance "
                  "bound (no λ); sphere tracing with λ = 1 overshoots wildly.",
                  _cam([0, 1, 4]), [{"id": "ball", "f": "1000*(x^2 + y^2 + z^2 - 1)", "bounds": _box(1.05)}])


def barth_sextic() -> dict:
    return _scene("barth_sextic", "Barth sextic (φ the golden ratio) clipped to ‖p‖ <= 1.8: degree 6, nodes where "
                  "∇f = 0, no λ.", _cam([2.2, 2.6, 4.4], far=12.0),
                  [{"id": "barth", "bounds": _box(1.85),
                    "f": "max(4*(phi^2*x^2 - y^2)*(phi^2*y^2 - z^2)*(phi^2*z^2 - x^2) "
                         "- (1 + 2*phi)*(x^2 + y^2 + z^2 - 1)^2, length(p) - 1.8)"}],
                  params={"phi": (1 + 5 ** 0.5) / 2})


def displaced_torus() -> dict:
    return _scene("displaced_torus", "Torus + 0.045·sin20x·sin20y·sin20z with a WRONG declared λ = 1 (the bumps "
                  "add up to 0.9: max |∇f| ≈ 1.9): sphere tracing overshoots into holes; for the λ-vs-observed check.",
                  _cam([0, 2, 4], far=10.0),
                  [{"id": "torus", "f": "ring + a*sin(k*x)*sin(k*y)*sin(k*z)", "lipschitz": 1.0,
                    "bounds": [[-1.45, -0.45, -1.45], [1.45, 0.45, 1.45]]}],
                  params={"R": 1.0, "r": 0.35, "a": 0.045, "k": 20.0}, define={"ring": TORUS})


def animated() -> dict:
    return _scene("animated", "A ball crosses the frame over a slab (frames [10, 30)), then the camera moves "
                  "(frames [40, 60)): stale t' must be invalidated by the (1+ε)t' probe.",
                  _cam([0, 0.8, 5], far=10.0),
                  [{"id": "ball", "f": "length(p) - 0.5", "bounds": _box(0.55), "lipschitz": 1.0,
                    "translate": [-1.5, 0, 0]},
                   {"id": "slab", "f": "max(abs(y) - 0.05, max(abs(x), abs(z)) - 3)", "lipschitz": 1.0,
                    "bounds": [[-3.05, -0.1, -3.05], [3.05, 0.1, 3.05]], "translate": [0, -0.6, 0]}],
                  animation={"frames": 60, "segments": [
                      {"frames": [10, 30], "object": "ball", "translate_per_frame": [0.15, 0, 0]},
                      {"frames": [40, 60], "camera": {"eye_per_frame": [0.05, 0, -0.02]}}]})


CATALOG: dict[str, Callable[[], dict]] = {f.__name__: f for f in (
    sphere, torus, thin_shell, thin_plate, gyroid_sheet, tangent_sphere, double_root, badly_scaled,
    barth_sextic, displaced_torus, animated)}


def names() -> list[str]:
    """Names of the built-in implicit scenes, in catalog order."""
    return list(CATALOG)


def describe() -> dict[str, str]:
    """``{name: one-line description}``.

    Example:
        >>> describe()["double_root"].startswith("(‖p‖−1)²")
        True
    """
    return {n: CATALOG[n]()["description"] for n in CATALOG}


def get(name: str) -> ImplicitScene:
    """Build a catalog scene by name (validated like a scene file)."""
    if name not in CATALOG:
        raise KeyError(f"name_or_path: unknown implicit scene {name!r}; built-in: {', '.join(CATALOG)}")
    return scene_from_dict(CATALOG[name](), source=f"<catalog:{name}>")


def as_dict(name: str) -> dict[str, Any]:
    """The raw description of a catalog scene (a template for your own scene files)."""
    if name not in CATALOG:
        raise KeyError(f"name: unknown implicit scene {name!r}; built-in: {', '.join(CATALOG)}")
    return CATALOG[name]()
