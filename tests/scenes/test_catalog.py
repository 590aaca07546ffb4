"""The built-in catalog: every scene validates, is described, and the scaled copies really are scaled."""
import math

import pytest

from ssbench.scenes import Scene, catalog, load

NAMES = catalog.names()


def test_catalog_size_and_descriptions():
    assert len(NAMES) >= 8 and len(set(NAMES)) == len(NAMES)
    desc = catalog.describe()
    assert list(desc) == NAMES
    for name, text in desc.items():
        assert isinstance(text, str) and text.strip() and "\n" not in text, name
        assert text == text.strip(), name


@pytest.mark.parametrize("name", NAMES)
def test_every_scene_loads(name):
    s = load(name)
    assert isinstance(s, Scene) and s.name == name and s.source == f"<catalog:{name}>"
    assert s.description == catalog.describe()[name]
    ids = [sh.id for sh in s.shapes]
    assert ids and len(set(ids)) == len(ids)
    assert all(s.shape_index(i) == k for k, i in enumerate(ids))
    assert s.lights and s.camera.width > 0 and s.camera.height > 0
    assert load(name).content_hash() == catalog.get(name).content_hash()     # deterministic
    assert catalog.as_dict(name)["name"] == name


def test_scenes_differ():
    hashes = {load(n).content_hash() for n in NAMES}
    assert len(hashes) == len(NAMES)


def test_unknown_name_is_a_key_error_naming_the_argument():
    with pytest.raises(KeyError, match="name_or_path") as e:
        load("no_such_scene")
    assert "no_such_scene" in str(e.value) and "sphere_on_plane" in str(e.value)
    with pytest.raises(KeyError, match="name_or_path"):
        catalog.get("no_such_scene")
    with pytest.raises(TypeError, match="name_or_path"):
        load(42)


def _close(a, b, rel=1e-12):
    return all(math.isclose(x, y, rel_tol=rel, abs_tol=1e-12 * max(1.0, abs(y))) for x, y in zip(a, b)) \
        and len(a) == len(b)


@pytest.mark.parametrize("suffix,s", [("_small", 0.01), ("_large", 100.0)])
def test_scaled_copies_are_exact_scalings(suffix, s):
    base, scaled = load("sphere_on_plane"), load("sphere_on_plane" + suffix)
    assert scaled.content_hash() != base.content_hash()
    cb, cs = base.camera, scaled.camera
    assert _close(cs.eye, [v * s for v in cb.eye]) and _close(cs.target, [v * s for v in cb.target])
    assert cs.up == cb.up and cs.fovy_deg == cb.fovy_deg and (cs.width, cs.height) == (cb.width, cb.height)
    assert _close([cs.near, cs.far], [cb.near * s, cb.far * s])
    assert [sh.id for sh in scaled.shapes] == [sh.id for sh in base.shapes]
    for a, b in zip(base.shapes, scaled.shapes):
        assert a.type == b.type and a.material == b.material
        for key, value in a.params:
            other = b.param(key)
            if key in ("center", "size", "p0", "p1"):
                assert _close(other, [v * s for v in value]), (a.id, key)
            elif key == "radius":
                assert math.isclose(other, value * s, rel_tol=1e-12), (a.id, key)
            else:
                assert other == value, (a.id, key)
        # rotation part unchanged, translation scaled
        for i in range(3):
            assert _close(b.to_world[i][:3], a.to_world[i][:3])
        assert _close([b.to_world[i][3] for i in range(3)], [a.to_world[i][3] * s for i in range(3)])
    for la, lb in zip(base.lights, scaled.lights):
        assert la.type == lb.type
        if la.type == "point":
            assert _close(lb.param("position"), [v * s for v in la.param("position")])
            # the same irradiance at the scaled distance: I' / (s d)^2 == I / d^2
            assert _close(lb.param("intensity"), [v * s * s for v in la.param("intensity")])
        else:
            assert la.params == lb.params
    assert len(base.lights) == len(scaled.lights) and scaled.max_depth == base.max_depth
