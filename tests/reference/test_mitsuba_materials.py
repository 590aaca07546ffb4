"""The BSDF → (albedo, roughness, metallic) mapping, one documented row at a time, on BSDFs Mitsuba built."""
import math

import numpy as np
import pytest

from ssbench.reference import backend
from ssbench.reference.mitsuba_materials import DEFAULT, map_bsdf

pytestmark = pytest.mark.mitsuba
RGB = {"type": "rgb", "value": [0.2, 0.4, 0.6]}


@pytest.fixture(scope="module")
def mi():
    return backend.mitsuba()


@pytest.mark.parametrize("bsdf,albedo,roughness,metallic", [
    ({"type": "diffuse", "reflectance": RGB}, (0.2, 0.4, 0.6), 1.0, 0.0),
    ({"type": "principled", "base_color": RGB, "roughness": 0.3, "metallic": 0.7}, (0.2, 0.4, 0.6), 0.3, 0.7),
    ({"type": "conductor"}, (1.0, 1.0, 1.0), 0.0, 1.0),
    ({"type": "conductor", "specular_reflectance": RGB}, (0.2, 0.4, 0.6), 0.0, 1.0),
    ({"type": "roughconductor", "alpha": 0.09, "specular_reflectance": RGB}, (0.2, 0.4, 0.6), 0.3, 1.0),
    ({"type": "plastic", "diffuse_reflectance": RGB}, (0.2, 0.4, 0.6), 0.0, 0.0),
    ({"type": "roughplastic", "diffuse_reflectance": RGB, "alpha": 0.25}, (0.2, 0.4, 0.6), 0.5, 0.0),
    ({"type": "dielectric"}, (1.0, 1.0, 1.0), 0.0, 0.0),
    ({"type": "thindielectric"}, (1.0, 1.0, 1.0), 0.0, 0.0),
    ({"type": "roughdielectric", "alpha": 0.16}, (1.0, 1.0, 1.0), 0.4, 0.0),
    ({"type": "twosided", "material": {"type": "roughconductor", "alpha": 0.04}}, (1.0, 1.0, 1.0), 0.2, 1.0),
    ({"type": "mask", "opacity": 0.5, "material": {"type": "diffuse", "reflectance": RGB}}, (0.2, 0.4, 0.6), 1.0,
     0.0),
    ({"type": "blendbsdf", "weight": 0.25, "bsdf_0": {"type": "diffuse", "reflectance": RGB},
      "bsdf_1": {"type": "roughconductor", "alpha": 0.01}}, (0.4, 0.55, 0.7), 0.775, 0.25),
])
def test_each_bsdf_maps_as_documented(mi, bsdf, albedo, roughness, metallic):
    m = map_bsdf(mi.load_dict(bsdf))
    assert m.material.albedo == pytest.approx(albedo, abs=1e-6)
    assert m.material.roughness == pytest.approx(roughness, abs=1e-6)
    assert m.material.metallic == pytest.approx(metallic, abs=1e-6)
    assert not m.albedo_at_hit and m.notes == ()


def test_unknown_bsdf_gets_the_default_and_a_note(mi):
    m = map_bsdf(mi.load_dict({"type": "null"}))
    assert m.material == DEFAULT and len(m.notes) == 1 and "no mapping" in m.notes[0]
    m = map_bsdf(mi.load_dict({"type": "hair"}))                     # Mitsuba cannot traverse it: no crash
    assert m.material == DEFAULT and len(m.notes) == 1 and "cannot be read" in m.notes[0]
    assert map_bsdf(None).material == DEFAULT


def test_textures_diffuse_at_the_hit_other_parameters_by_their_mean(mi, tmp_path):
    img = np.zeros((2, 2, 3), np.uint8)
    img[:, 0], img[:, 1] = (255, 0, 0), (0, 0, 255)
    mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB).write(str(tmp_path / "t.png"))
    tex = {"type": "bitmap", "filename": str(tmp_path / "t.png")}
    d = map_bsdf(mi.load_dict({"type": "twosided", "material": {"type": "diffuse", "reflectance": tex}}))
    assert d.albedo_at_hit and d.notes == ()
    assert d.material.albedo == pytest.approx((0.5, 0.0, 0.5), abs=1e-6)          # the mean, for the tables
    p = map_bsdf(mi.load_dict({"type": "principled", "base_color": tex}))
    assert not p.albedo_at_hit and "replaced by its mean" in p.notes[0]
    b = map_bsdf(mi.load_dict({"type": "blendbsdf", "weight": 0.5, "bsdf_0": {"type": "diffuse", "reflectance": tex},
                               "bsdf_1": {"type": "diffuse"}}))
    assert not b.albedo_at_hit and any("blend" in n for n in b.notes)
    assert math.isclose(b.material.albedo[0], 0.5 * 0.5 + 0.5 * 0.5)
