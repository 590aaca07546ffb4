"""Implicit scene files: YAML, TOML and dict give the same scene; errors name file:line and the field;
animation poses are piecewise linear; the mesh-scene loader refuses implicit files and vice versa."""
import copy

import pytest
import torch

from ssbench import scenes
from ssbench.implicit.scene import Animation, ImplicitScene, Segment, load
from ssbench.implicit.schema import scene_from_dict, scene_from_toml, scene_from_yaml
from ssbench.scenes import SceneError

YAML = """name: probe
description: torus and ball, written three times
camera: {eye: [0, 2, 5], target: [0, 0, 0], up: [0, 1, 0], fovy: 45, width: 160, height: 120, near: 0.1, far: 12}
materials:
  gold: {albedo: [1, 0.8, 0.3], roughness: 0.3, metallic: 1}
params: {R: 1.0, r: 0.35}
define:
  ring: "length(vec3(length(vec3(x, 0, z)) - R, y, 0)) - r"
implicit:
  - id: torus
    f: "ring"
    bounds: [[-1.4, -0.4, -1.4], [1.4, 0.4, 1.4]]
    lipschitz: 1.0
    material: gold
    translate: [0, 0, 0]
  - id: ball
    f: "length(p) - 1"
    bounds: [[-1.1, -1.1, -1.1], [1.1, 1.1, 1.1]]
    translate: [0, 1, 0]
    rotate: [0, 30, 0]
    scale: 0.5
lights: [{type: point, position: [3, 5, 4], intensity: 40}]
animation:
  frames: 60
  segments:
    - {frames: [20, 40], object: torus, translate_per_frame: [0.02, 0, 0]}
    - {frames: [40, 60], camera: {eye_per_frame: [0.05, 0, 0], target_per_frame: [0, 0.01, 0]}}
"""

TOML = """name = "probe"
description = "torus and ball, written three times"

[camera]
eye = [0, 2, 5]
target = [0, 0, 0]
up = [0, 1, 0]
fovy = 45
width = 160
height = 120
near = 0.1
far = 12

[materials.gold]
albedo = [1, 0.8, 0.3]
roughness = 0.3
metallic = 1

[params]
R = 1.0
r = 0.35

[define]
ring = "length(vec3(length(vec3(x, 0, z)) - R, y, 0)) - r"

[[implicit]]
id = "torus"
f = "ring"
bounds = [[-1.4, -0.4, -1.4], [1.4, 0.4, 1.4]]
lipschitz = 1.0
material = "gold"
translate = [0, 0, 0]

[[implicit]]
id = "ball"
f = "length(p) - 1"
bounds = [[-1.1, -1.1, -1.1], [1.1, 1.1, 1.1]]
translate = [0, 1, 0]
rotate = [0, 30, 0]
scale = 0.5

[[lights]]
type = "point"
position = [3, 5, 4]
intensity = 40

[animation]
frames = 60

[[animation.segments]]
frames = [20, 40]
object = "torus"
translate_per_frame = [0.02, 0, 0]

[[animation.segments]]
frames = [40, 60]
camera = {eye_per_frame = [0.05, 0, 0], target_per_frame = [0, 0.01, 0]}
"""

DICT = {
    "name": "probe", "description": "torus and ball, written three times",
    "camera": {"eye": [0, 2, 5], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 45, "width": 160, "height": 120,
               "near": 0.1, "far": 12},
    "materials": {"gold": {"albedo": [1, 0.8, 0.3], "roughness": 0.3, "metallic": 1}},
    "params": {"R": 1.0, "r": 0.35},
    "define": {"ring": "length(vec3(length(vec3(x, 0, z)) - R, y, 0)) - r"},
    "implicit": [{"id": "torus", "f": "ring", "bounds": [[-1.4, -0.4, -1.4], [1.4, 0.4, 1.4]], "lipschitz": 1.0,
                  "material": "gold", "translate": [0, 0, 0]},
                 {"id": "ball", "f": "length(p) - 1", "bounds": [[-1.1, -1.1, -1.1], [1.1, 1.1, 1.1]],
                  "translate": [0, 1, 0], "rotate": [0, 30, 0], "scale": 0.5}],
    "lights": [{"type": "point", "position": [3, 5, 4], "intensity": 40}],
    "animation": {"frames": 60, "segments": [
        {"frames": [20, 40], "object": "torus", "translate_per_frame": [0.02, 0, 0]},
        {"frames": [40, 60], "camera": {"eye_per_frame": [0.05, 0, 0], "target_per_frame": [0, 0.01, 0]}}]},
}


def _line(text, needle):
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def test_yaml_toml_and_dict_give_the_same_scene(tmp_path):
    (tmp_path / "s.yaml").write_text(YAML)
    (tmp_path / "s.toml").write_text(TOML)
    a, b, c = load(tmp_path / "s.yaml"), load(str(tmp_path / "s.toml")), load(copy.deepcopy(DICT))
    assert a.content_hash() == b.content_hash() == c.content_hash()
    assert a.objects.ids == ("torus", "ball") and a.materials[0].metallic == 1.0 and a.frames == 60
    assert a.objects.objects[0].where == f"{tmp_path / 's.yaml'}:10"
    ball_line = _line(TOML, 'id = "ball"') - 1                      # the [[implicit]] header
    assert b.objects.objects[1].where == f"{tmp_path / 's.toml'}:{ball_line}"
    assert load(a) is a
    assert a.surface(30).cache_key() == b.surface(30).cache_key() != a.surface(0).cache_key()
    other = copy.deepcopy(DICT)
    other["params"]["r"] = 0.3                                     # same text, another parameter value
    assert load(other).content_hash() != c.content_hash()


def test_animation_is_piecewise_linear():
    s = load(copy.deepcopy(DICT))
    x = lambda k: s.surface(k).objects[0].translate[0]
    assert [x(k) for k in (0, 20, 21, 30, 40, 59, 200)] == pytest.approx([0, 0, 0.02, 0.2, 0.4, 0.4, 0.4])
    assert s.surface(0) is s.objects and s.surface(25).objects[1] == s.objects.objects[1]
    p = torch.tensor([[1.65, 0.0, 0.0]], dtype=torch.float64)       # the ring's outer equator at frame 35
    assert s.surface(35).f(p).item() == pytest.approx(0.0, abs=1e-12)
    assert s.camera_at(40) == s.camera
    c = s.camera_at(50)
    assert c.eye == pytest.approx((0.5, 2, 5)) and c.target == pytest.approx((0, 0.1, 0)) and c.fovy_deg == 45
    with pytest.raises(ValueError, match="frame"):
        s.surface(-1)
    anim = Animation(10, (Segment(2, 5, object="a", translate_per_frame=(1, 0, 0)),
                          Segment(4, 8, object="a", translate_per_frame=(0, 1, 0))))
    assert anim.offset("a", 6) == (3, 2, 0) and anim.offset("b", 6) == (0, 0, 0)
    static = load("sphere")
    assert static.frames == 1 and static.surface(7) is static.objects and static.camera_at(7) == static.camera


def _yaml_error(text, tmp_path, name="bad.yaml"):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(SceneError) as e:
        load(path)
    return str(e.value), str(path)


@pytest.mark.parametrize("old, new, where, what", [
    ("    lipschitz: 1.0\n", "    lipschitz: 1.0\n    colour: red\n", "14:", "implicit[0].colour: unknown field"),
    ('f: "ring"', 'f: "ring +"', "11:", "implicit[0].f: column"),
    ('f: "ring"', "f: \"__import__('os')\"", "11:", "implicit[0].f: column"),
    ('f: "ring"', 'f: "x.__class__"', "11:", "attribute access is not allowed"),
    ('f: "ring"', 'f: "lambda: 1"', "11:", "implicit[0].f: column"),
    ('f: "ring"', 'f: "x^100000"', "11:", "implicit[0].f:"),
    ("    scale: 0.5\n", "    scale: -2\n", "21:", "implicit[1].scale: must be > 0"),
    ("    scale: 0.5\n", "    scale: [1, 2, 1]\n", "21:", "implicit[1].scale: only a uniform scale"),
    ("bounds: [[-1.4, -0.4, -1.4], [1.4, 0.4, 1.4]]", "bounds: [[-1.4, 0.4, -1.4], [1.4, 0.4, 1.4]]", "12:",
     "implicit[0].bounds: lower corner must be < upper corner on every axis, got y"),
    ("    lipschitz: 1.0\n", "    lipschitz: 0\n", "13:", "implicit[0].lipschitz: must be > 0"),
    ("    material: gold\n", "    material: silver\n", "14:", "implicit[0].material: unknown material 'silver'"),
    ("  - id: ball\n", "  - id: torus\n", "16:", "implicit[1].id: duplicate object id"),
    ("params: {R: 1.0, r: 0.35}", "params: {R: 1.0, r: 0.35, x: 2}", "6:", "params.x: parameter name 'x' shadows"),
    ("params: {R: 1.0, r: 0.35}", "params: {R: 1.0, r: zero}", "6:", "params.r: expected a number"),
    ('  ring: "length', '  ring: "lengthh', "8:", "define.ring: column 1: unknown function 'lengthh'"),
    ("object: torus,", "object: donut,", "26:", "animation.segments[0].object: unknown object 'donut'"),
    ("frames: [40, 60]", "frames: [40, 61]", "27:", "animation.segments[1].frames: need 0 <= first < stop"),
    ("camera: {eye_per_frame", "object: ball, camera: {eye_per_frame", "27:", "give either 'object' or 'camera'"),
    ("eye_per_frame: [0.05, 0, 0]", "eye_per_frame: [0, -0.2, -0.25]", "25:", "camera invalid at frame 60"),
    ("name: probe\n", "name: probe\nshapez: []\n", "2:", "shapez: unknown field"),
    ("  frames: 60\n", "  frames: 0\n", "24:", "animation.frames: expected an integer >= 1"),
])
def test_errors_name_file_line_and_field(tmp_path, old, new, where, what):
    assert old in YAML
    msg, path = _yaml_error(YAML.replace(old, new, 1), tmp_path)
    assert msg.startswith(f"{path}:{where}"), msg
    assert what in msg, msg


def test_toml_errors_name_the_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(TOML.replace("scale = 0.5", "scale = -0.5"))
    with pytest.raises(SceneError, match=rf"^{path}:{_line(TOML, 'scale = 0.5')}: implicit\[1\]\.scale: must be > 0"):
        load(path)
    path.write_text(TOML.replace('f = "ring"', 'f = "open(1)"'))
    line = _line(TOML, 'f = "ring"')
    with pytest.raises(SceneError, match=rf"^{path}:{line}: implicit\[0\]\.f: column 1"):
        load(path)


def test_nothing_is_executed_yaml_tags_are_refused(tmp_path):
    msg, _ = _yaml_error("!!python/object/apply:os.system ['echo hi']\n", tmp_path)
    assert "malformed YAML" in msg


def test_the_two_loaders_point_at_each_other(tmp_path):
    path = tmp_path / "imp.yaml"
    path.write_text(YAML)
    with pytest.raises(SceneError, match=rf"^{path}:9: implicit: an implicit-surface scene; load it with "
                                         r"ssbench\.implicit\.load"):
        scenes.load(path)
    toml = tmp_path / "imp.toml"
    toml.write_text(TOML)
    with pytest.raises(SceneError, match=r"ssbench\.implicit\.load"):
        scenes.load(toml)
    with pytest.raises(SceneError, match=r"shapes: a mesh/analytic-shape scene; load it with ssbench\.scenes\.load"):
        load(scenes.catalog.as_dict("sphere_on_plane"))


def test_text_parsers_and_missing_fields():
    assert scene_from_yaml(YAML, "mem.yaml").content_hash() == scene_from_toml(TOML, "mem.toml").content_hash()
    d = copy.deepcopy(DICT)
    del d["implicit"][0]["bounds"]
    with pytest.raises(SceneError, match=r"^<dict>: implicit\[0\]\.bounds: missing required field"):
        scene_from_dict(d)
    d = copy.deepcopy(DICT)
    d["implicit"] = []
    with pytest.raises(SceneError, match="implicit: expected a non-empty list"):
        scene_from_dict(d)


def test_load_arguments():
    assert isinstance(load("torus"), ImplicitScene)
    with pytest.raises(TypeError, match="name_or_path"):
        load(3)
    with pytest.raises(FileNotFoundError, match="name_or_path"):
        load("missing.yaml")
