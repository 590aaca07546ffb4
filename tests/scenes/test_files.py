"""YAML and TOML scene files: the same scene in both, and errors that name file:line and the field."""
import pytest

from ssbench.scenes import SceneError, load, parse_toml, parse_yaml

TRI_OBJ = "v -1 0 -1\nv 1 0 -1\nv 0 1.5 0.5\nf 1 2 3\n"

YAML = """name: probe
description: a probe scene written twice
camera:
  eye: [0, 2, 6]
  target: [0, 0.6, 0]
  up: [0, 1, 0]
  fovy: 45
  width: 320
  height: 240
  near: 0.1
  far: 100
materials:
  grey: {albedo: [0.7, 0.7, 0.7]}
shapes:
  - type: rectangle
    id: floor
    size: [20, 20]
    rotate: [-90, 0, 0]
    material: grey
  - type: sphere
    id: ball
    center: [0, 1, 0]
    radius: 1
    material: {albedo: [0.2, 0.3, 0.8], roughness: 0.5}
  - type: mesh
    id: tri
    file: tri.obj
    translate: [2, 0, 0]
    scale: 0.5
lights:
  - {type: point, position: [2, 5, 3], intensity: 40}
  - {type: environment, radiance: 0.3}
render:
  max_depth: 4
"""

TOML = """name = "probe"
description = "a probe scene written twice"

[camera]
eye = [0, 2, 6]
target = [0, 0.6, 0]
up = [0, 1, 0]
fovy = 45
width = 320
height = 240
near = 0.1
far = 100

[materials.grey]
albedo = [0.7, 0.7, 0.7]

[[shapes]]
type = "rectangle"
id = "floor"
size = [20, 20]
rotate = [-90, 0, 0]
material = "grey"

[[shapes]]
type = "sphere"
id = "ball"
center = [0, 1, 0]
radius = 1
material = {albedo = [0.2, 0.3, 0.8], roughness = 0.5}

[[shapes]]
type = "mesh"
id = "tri"
file = "tri.obj"
translate = [2, 0, 0]
scale = 0.5

[[lights]]
type = "point"
position = [2, 5, 3]
intensity = 40

[[lights]]
type = "environment"
radiance = 0.3

[render]
max_depth = 4
"""

FORMATS = {"yaml": (YAML, "scene.yaml"), "toml": (TOML, "scene.toml")}


def line_of(text: str, needle: str) -> int:
    """The last line containing ``needle`` (for a duplicate id, the second definition)."""
    return [i for i, line in enumerate(text.splitlines(), 1) if needle in line][-1]


def write(tmp_path, text: str, name: str):
    (tmp_path / "tri.obj").write_text(TRI_OBJ)
    p = tmp_path / name
    p.write_text(text)
    return p


def test_yaml_and_toml_give_the_same_scene(tmp_path):
    sy, st = load(write(tmp_path, YAML, "scene.yaml")), load(write(tmp_path, TOML, "scene.toml"))
    assert sy.content_hash() == st.content_hash()
    assert sy.name == "probe" and sy.max_depth == 4 and [s.id for s in sy.shapes] == ["floor", "ball", "tri"]
    assert sy.shapes[0].material.albedo == (0.7, 0.7, 0.7)              # named material
    assert sy.shapes[1].material.roughness == 0.5
    mesh = sy.shapes[2]
    assert mesh.param("file") == str(tmp_path / "tri.obj")              # resolved next to the scene file
    assert mesh.to_world[0][3] == 2.0 and mesh.to_world[0][0] == 0.5
    assert [lt.type for lt in st.lights] == ["point", "environment"]
    assert st.lights[0].param("intensity") == (40.0, 40.0, 40.0)
    assert sy.shapes[1].where == f"{tmp_path / 'scene.yaml'}:{line_of(YAML, 'type: sphere')}"
    # a changed value changes the hash (the comparison above can fail)
    other = load(write(tmp_path, TOML.replace("radius = 1", "radius = 1.5"), "other.toml"))
    assert other.content_hash() != sy.content_hash()


# (format, old, new, needle for the line, words the message must contain)
CASES = [
    ("yaml", "radius: 1", "radius: -1", "radius: -1", ["shapes[1].radius", "> 0"]),
    ("toml", "radius = 1", "radius = -1", "radius = -1", ["shapes[1].radius", "> 0"]),
    ("yaml", "type: sphere", "type: teapot", "teapot", ["shapes[1].type", "unknown object type", "teapot"]),
    ("toml", 'type = "sphere"', 'type = "teapot"', "teapot", ["shapes[1].type", "unknown object type", "teapot"]),
    ("yaml", "width: 320", "width: 0", "width: 0", ["camera.width"]),
    ("toml", "width = 320", "width = 0", "width = 0", ["camera.width"]),
    ("yaml", "far: 100", "far: 0.1", "far: 0.1", ["camera.far", "near"]),
    ("toml", "far = 100", "far = 0.05", "far = 0.05", ["camera.far", "near"]),
    ("yaml", "    radius: 1\n", "    radius: 1\n    colour: red\n", "colour", ["shapes[1].colour", "unknown field"]),
    ("toml", "radius = 1\n", "radius = 1\ncolour = \"red\"\n", "colour", ["shapes[1].colour", "unknown field"]),
    ("yaml", "id: ball", "id: floor", "id: floor", ["shapes[1].id", "duplicate", "floor"]),
    ("toml", 'id = "ball"', 'id = "floor"', 'id = "floor"', ["shapes[1].id", "duplicate", "floor"]),
    ("yaml", "file: tri.obj", "file: gone.obj", "gone.obj", ["shapes[2].file", "not found"]),
    ("toml", 'file = "tri.obj"', 'file = "gone.obj"', "gone.obj", ["shapes[2].file", "not found"]),
    ("yaml", "[0.2, 0.3, 0.8]", "[0.2, 1.3, 0.8]", "1.3", ["shapes[1].material.albedo", "[0, 1]"]),
    ("toml", "[0.2, 0.3, 0.8]", "[0.2, 1.3, 0.8]", "1.3", ["shapes[1].material.albedo", "[0, 1]"]),
    ("yaml", "fovy: 45", "fovy: 180", "fovy: 180", ["camera.fovy"]),
    ("toml", "max_depth = 4", "max_depth = 0", "max_depth = 0", ["render.max_depth"]),
    ("yaml", "  - {type: environment, radiance: 0.3}", "  - {type: spot, radiance: 0.3}", "spot",
     ["lights[1].type", "spot"]),
    ("yaml", "center: [0, 1, 0]", "center: [0, 1, 0]]", "center", ["malformed YAML"]),
    ("yaml", "  fovy: 45\n", "  fovy: 45\n  fovy: 50\n", "fovy: 50", ["duplicate key", "fovy"]),
    ("toml", "radius = 1\n", "radius = = 1\n", "radius = = 1", ["malformed TOML"]),
    ("toml", "fovy = 45\n", "fovy = 45\nfovy = 50\n", "fovy = 50", ["malformed TOML"]),
]


@pytest.mark.parametrize("fmt,old,new,needle,words", CASES, ids=[f"{c[0]}-{c[2][:24]}" for c in CASES])
def test_errors_name_file_line_and_field(tmp_path, fmt, old, new, needle, words):
    base, name = FORMATS[fmt]
    assert base.count(old) == 1
    text = base.replace(old, new)
    p = write(tmp_path, text, name)
    with pytest.raises(SceneError) as e:
        load(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}:{line_of(text, needle)}:"), msg
    for w in words:
        assert w in msg, (w, msg)


def test_yaml_python_tags_are_refused_and_run_nothing(tmp_path):
    marker = tmp_path / "pwned"
    for tag in (f'!!python/object/apply:os.system ["touch {marker}"]',
                f'!!python/object/apply:subprocess.call [["touch", "{marker}"]]',
                '!!python/name:os.system'):
        text = YAML.replace("description: a probe scene written twice", f"description: {tag}")
        p = write(tmp_path, text, "evil.yaml")
        with pytest.raises(SceneError) as e:
            load(p)
        assert str(e.value).startswith(f"{p}:{line_of(text, 'description')}:") and "malformed YAML" in str(e.value)
        assert not marker.exists()


def test_parsers_take_text_and_empty_files_are_errors(tmp_path):
    (tmp_path / "tri.obj").write_text(TRI_OBJ)
    a = parse_yaml(YAML, "mem.yaml", str(tmp_path))
    b = parse_toml(TOML, "mem.toml", str(tmp_path))
    assert a.content_hash() == b.content_hash() and a.source == "mem.yaml"
    with pytest.raises(SceneError, match=r"^e\.yaml:1: "):
        parse_yaml("", "e.yaml")
    with pytest.raises(SceneError, match=r"^e\.yaml:1: .*camera"):
        parse_yaml("name: x\nshapes: [{type: sphere, radius: 1}]\n", "e.yaml")
    with pytest.raises(SceneError, match=r"^e\.toml:1: .*shapes"):
        parse_toml('[camera]\neye = [0, 0, 5]\ntarget = [0, 0, 0]\nfovy = 40\n', "e.toml")


def test_unknown_paths_and_types(tmp_path):
    with pytest.raises(FileNotFoundError, match="name_or_path"):
        load(tmp_path / "missing.yaml")
    p = tmp_path / "scene.json"
    p.write_text("{}")
    with pytest.raises(SceneError, match=rf"^{p}:1: .*\.json"):
        load(p)
