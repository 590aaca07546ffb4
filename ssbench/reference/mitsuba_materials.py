"""A loaded Mitsuba BSDF → the G-buffer's material (albedo, roughness, metallic): the documented mapping.

Read from the BSDF's own parameters (``mi.traverse``), so a material is mapped whatever XML wrote it:

==================================  =====================================  ============  ========
BSDF (Mitsuba plugin)               albedo                                 roughness     metallic
==================================  =====================================  ============  ========
``diffuse``                         ``reflectance``                        1             0
``principled``                      ``base_color``                         ``roughness`` ``metallic``
``conductor``                       ``specular_reflectance`` (default 1)   0             1
``roughconductor``                  ``specular_reflectance`` (default 1)   √``alpha``    1
``plastic`` / ``roughplastic``      ``diffuse_reflectance``                0 / √``alpha`` 0
``dielectric``, ``thindielectric``  1                                      0             0
``roughdielectric``                 1                                      √``alpha``    0
``twosided``, ``mask``, bump/normal the material inside
``blendbsdf``                       both, mixed by ``weight``
==================================  =====================================  ============  ========

Our roughness ``r`` means GGX ``alpha = r²`` (as Mitsuba's ``principled``), hence √``alpha``. A BSDF matching none
of these gets :data:`DEFAULT` and a note. A textured albedo of a diffuse-like BSDF (``diffuse``, ``plastic``,
``roughplastic``, nested or not) is looked up at each hit by the G-buffer (``albedo_at_hit``); any other textured
parameter is replaced by its texture's mean, with a note.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scenes.model import Material

__all__ = ["MappedMaterial", "map_bsdf", "DEFAULT"]

#: what an unknown BSDF maps to
DEFAULT = Material()
_DIFFUSE_LIKE = ("reflectance", "diffuse_reflectance")


@dataclass(frozen=True)
class MappedMaterial:
    """``material`` for the G-buffer tables; ``albedo_at_hit``: the albedo is a texture to evaluate per hit;
    ``notes``: what was approximated."""

    material: Material
    albedo_at_hit: bool = False
    notes: tuple[str, ...] = ()


def _value(params, key: str):
    """A parameter as floats: ``key.value`` (constant), ``key`` (plain float) or ``key.data`` (texture mean)."""
    for k in (key + ".value", key):
        if k in params:
            v = np.atleast_1d(np.asarray(params[k], dtype=np.float64)).reshape(-1)
            return [float(x) for x in v], False
    if key + ".data" in params:
        data = np.asarray(params[key + ".data"])
        x = data.astype(np.float64) / (255.0 if data.dtype == np.uint8 else 1.0)
        if data.dtype == np.uint8:                                             # sRGB-encoded 8-bit texels
            x = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)
        mean = x.reshape(-1, x.shape[-1] if x.ndim == 3 else 1).mean(0)
        return [float(v) for v in mean], True
    return None, False


def _rgb(v) -> tuple:
    if v is None:
        return (1.0, 1.0, 1.0)
    return tuple(float(min(1.0, max(0.0, x))) for x in (v * 3 if len(v) == 1 else v[:3]))


def _scalar(v, default: float) -> float:
    return default if v is None else float(v[0])


def _strip(params, prefix: str) -> dict:
    return {k[len(prefix):]: params[k] for k in params.keys() if k.startswith(prefix)}


def _map(p: dict, kind: str) -> MappedMaterial:
    keys = {k.split(".")[0] for k in p}
    if "weight" in keys and any(k.startswith("bsdf_0") for k in keys):                    # blendbsdf
        w = _scalar(_value(p, "weight")[0], 0.5)
        a, b = _map(_strip(p, "bsdf_0."), kind), _map(_strip(p, "bsdf_1."), kind)
        mix = lambda x, y: (1.0 - w) * x + w * y                                          # noqa: E731
        m = Material(tuple(mix(x, y) for x, y in zip(a.material.albedo, b.material.albedo)),
                     mix(a.material.roughness, b.material.roughness), mix(a.material.metallic, b.material.metallic))
        notes = a.notes + b.notes
        if a.albedo_at_hit or b.albedo_at_hit:
            notes += (f"{kind}: a textured albedo inside a blend is replaced by its mean",)
        return MappedMaterial(m, False, notes)
    for prefix in ("brdf_0.", "nested_bsdf."):                                          # twosided, mask, bump
        if any(k.startswith(prefix) for k in p):
            return _map(_strip(p, prefix), kind)
    notes: list[str] = []

    def colour(key: str):
        v, textured = _value(p, key)
        if textured and key not in _DIFFUSE_LIKE:
            notes.append(f"{kind}: textured {key} replaced by its mean {_rgb(v)}")
        return _rgb(v), textured and key in _DIFFUSE_LIKE

    def rough(key: str = "alpha") -> float:
        v, textured = _value(p, key)
        if textured:
            notes.append(f"{kind}: textured {key} replaced by its mean")
        return 0.0 if v is None else min(1.0, math.sqrt(max(0.0, v[0])))

    if "base_color" in keys:                                                             # principled
        albedo, _ = colour("base_color")
        return MappedMaterial(Material(albedo, min(1.0, max(0.0, _scalar(_value(p, "roughness")[0], 0.5))),
                                       min(1.0, max(0.0, _scalar(_value(p, "metallic")[0], 0.0)))), False,
                              tuple(notes))
    if "reflectance" in keys:                                                            # diffuse
        albedo, at_hit = colour("reflectance")
        return MappedMaterial(Material(albedo, 1.0, 0.0), at_hit, tuple(notes))
    if "k" in keys or "specular_reflectance" in keys:                                    # (rough)conductor
        albedo, _ = colour("specular_reflectance")
        return MappedMaterial(Material(albedo, rough() if "alpha" in keys else 0.0, 1.0), False, tuple(notes))
    if "diffuse_reflectance" in keys:                                                    # (rough)plastic
        albedo, at_hit = colour("diffuse_reflectance")
        return MappedMaterial(Material(albedo, rough() if "alpha" in keys else 0.0, 0.0), at_hit, tuple(notes))
    if keys <= {"eta", "alpha", "specular_reflectance", "specular_transmittance"} and "eta" in keys:  # dielectrics
        return MappedMaterial(Material((1.0, 1.0, 1.0), rough() if "alpha" in keys else 0.0, 0.0), False,
                              tuple(notes))
    return MappedMaterial(DEFAULT, False, (f"{kind}: no mapping for this BSDF; using albedo {DEFAULT.albedo}, "
                                           f"roughness {DEFAULT.roughness}, metallic {DEFAULT.metallic}",))


def map_bsdf(bsdf) -> MappedMaterial:
    """The :class:`MappedMaterial` of a loaded Mitsuba BSDF (``None``: the shape has none, :data:`DEFAULT`)."""
    if bsdf is None:
        return MappedMaterial(DEFAULT)
    from . import backend
    mi = backend.mitsuba()
    kind = str(bsdf).split("[")[0].split(" ")[0].strip() or "BSDF"
    try:
        params = mi.traverse(bsdf)
        flat = {k: params[k] for k in params.keys()}
    except Exception as e:                      # some plugins' parameters cannot be read back (e.g. hair)
        return MappedMaterial(DEFAULT, False, (f"{kind}: its parameters cannot be read ({' '.join(str(e).split())[:80]}"
                                               f"); using albedo {DEFAULT.albedo}, roughness {DEFAULT.roughness}, "
                                               f"metallic {DEFAULT.metallic}",))
    return _map(flat, kind)
