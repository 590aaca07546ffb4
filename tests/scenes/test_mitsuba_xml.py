"""Mitsuba XML import: values against closed forms, errors naming file:line, and a ray-level cross-check."""
import json
import math
import os
import random
import re
import subprocess
import sys

import pytest

from ssbench.scenes import SceneError, load
from ssbench.scenes.mitsuba_xml import parse_mitsuba_xml
from ssbench.scenes.transforms import decompose, matmul4, rotate4, scale4, translate4

TRI_OBJ = "v -1 0 -1\nv 1 0 -1\nv 0 1.5 0.5\nv 0 0 1\nf 1 2 3\nf 2 4 3\nf 4 1 3\n"

SCENE = """<?xml version="1.0" encoding="utf-8"?>
<!-- a realistic hand-written scene -->
<scene version="3.0.0">
    <default name="res" value="320"/>
    <default name="spp" value="16"/>
    <integrator type="path">
        <integer name="max_depth" value="5"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="60"/>
        <float name="near_clip" value="0.05"/>
        <float name="far_clip" value="200"/>
        <transform name="to_world">
            <lookat origin="0, 2, 6" target="0 0.6 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/>
            <integer name="height" value="240"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <bsdf type="twosided" id="red">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
    </bsdf>
    <shape type="sphere" id="ball">
        <point name="center" x="0" y="1" z="0"/>
        <float name="radius" value="1"/>
        <ref id="red"/>
    </shape>
    <shape type="sphere" id="small_ball">
        <transform name="to_world"><scale value="0.5"/><translate x="-2" y="0.5" z="1"/></transform>
        <bsdf type="principled">
            <rgb name="base_color" value="0.2 0.3 0.8"/>
            <float name="roughness" value="0.4"/>
            <float name="metallic" value="0.25"/>
        </bsdf>
    </shape>
    <shape type="cube" id="crate">
        <transform name="to_world">
            <scale value="0.5"/>
            <rotate y="1" angle="30"/>
            <translate x="2" y="0.5"/>
        </transform>
        <bsdf type="roughconductor"><float name="alpha" value="0.04"/></bsdf>
    </shape>
    <shape type="rectangle" id="floor">
        <transform name="to_world"><scale x="10" y="5"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="conductor"/>
        <emitter type="area"><rgb name="radiance" value="1"/></emitter>
    </shape>
    <shape type="cylinder">
        <point name="p0" value="1 0 -1"/>
        <point name="p1" value="1, 2, -1"/>
        <float name="radius" value="0.1"/>
    </shape>
    <emitter type="point">
        <point name="position" value="2, 5, 3"/>
        <rgb name="intensity" value="40"/>
    </emitter>
    <emitter type="constant"><rgb name="radiance" value="0.3"/></emitter>
</scene>
"""


BALL, CRATE = 'id="ball"', 'id="crate"'


def line_of(text: str, needle: str, nth: int = 0) -> int:
    hits = [i for i, line in enumerate(text.splitlines(), 1) if needle in line]
    return hits[nth]


def write(tmp_path, text, name="scene.xml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def close(a, b, tol=1e-9):
    return all(abs(x - y) <= tol for x, y in zip(a, b)) and len(a) == len(b)


def mat_close(a, b, tol=1e-9):
    return all(close(ra, rb, tol) for ra, rb in zip(a, b))


def test_realistic_scene(tmp_path):
    s = load(write(tmp_path, SCENE))
    cam = s.camera
    assert cam.eye == (0.0, 2.0, 6.0) and cam.target == (0.0, 0.6, 0.0) and cam.up == (0.0, 1.0, 0.0)
    assert (cam.width, cam.height, cam.near, cam.far) == (320, 240, 0.05, 200.0)   # $res substituted
    # Mitsuba's fov is horizontal by default: fovy = 2 atan(tan(fovx / 2) * H / W)
    assert cam.fovy_deg == pytest.approx(math.degrees(2 * math.atan(math.tan(math.radians(30)) * 240 / 320)), abs=1e-12)
    assert s.max_depth == 5 and s.name == "scene"
    sh = {x.id: x for x in s.shapes}
    assert [x.id for x in s.shapes] == ["ball", "small_ball", "crate", "floor", "cylinder_4"]

    assert sh["ball"].type == "sphere" and sh["ball"].param("center") == (0, 1, 0) and sh["ball"].param("radius") == 1
    assert sh["ball"].material.albedo == (0.8, 0.1, 0.1)                              # via <ref>, unwrapped
    assert (sh["ball"].material.roughness, sh["ball"].material.metallic) == (1.0, 0.0)
    assert sh["ball"].where == f"{tmp_path / 'scene.xml'}:{line_of(SCENE, BALL)}"

    # scale then translate folds into the sphere's own centre and radius
    assert close(sh["small_ball"].param("center"), (-2, 0.5, 1)) and sh["small_ball"].param("radius") == 0.5
    assert sh["small_ball"].material.albedo == (0.2, 0.3, 0.8)
    assert (sh["small_ball"].material.roughness, sh["small_ball"].material.metallic) == (0.4, 0.25)

    # cube [-1, 1]^3 scaled by 0.5 -> box of size 1; to_world keeps the rotation and translation
    crate = sh["crate"]
    assert crate.type == "box" and close(crate.param("size"), (1, 1, 1))
    c, si = math.cos(math.radians(30)), math.sin(math.radians(30))
    expected = [[c, 0, si, 2], [0, 1, 0, 0.5], [-si, 0, c, 0], [0, 0, 0, 1]]
    assert mat_close(crate.to_world, expected)
    # Mitsuba maps the cube corner (1, 1, 1) to R·(0.5, 0.5, 0.5) + t; so must our box (local corner size/2)
    corner = [sum(crate.to_world[i][j] * 0.5 for j in range(3)) + crate.to_world[i][3] for i in range(3)]
    assert close(corner, (0.5 * c + 0.5 * si + 2, 1.0, -0.5 * si + 0.5 * c))
    assert crate.material.metallic == 1.0 and crate.material.roughness == pytest.approx(0.2)   # sqrt(alpha)

    # rectangle [-1, 1]^2 scaled (10, 5) -> size (20, 10), lying on the floor (normal +y)
    floor = sh["floor"]
    assert floor.type == "rectangle" and close(floor.param("size"), (20, 10))
    assert mat_close(floor.to_world, [[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
    assert floor.material.albedo == (0.9, 0.9, 0.9)
    assert (floor.material.roughness, floor.material.metallic) == (0.0, 1.0)

    cyl = sh["cylinder_4"]
    assert cyl.param("p0") == (1, 0, -1) and cyl.param("p1") == (1, 2, -1) and cyl.param("radius") == 0.1
    assert cyl.param("caps") is False                                                  # Mitsuba cylinders are open
    assert cyl.material.albedo == (0.5, 0.5, 0.5)                                      # Mitsuba's default bsdf

    assert [lt.type for lt in s.lights] == ["point", "environment"]
    assert s.lights[0].param("position") == (2, 5, 3) and s.lights[0].param("intensity") == (40, 40, 40)
    assert s.lights[1].param("radiance") == (0.3, 0.3, 0.3)


@pytest.mark.parametrize("axis,w,h,tan_half_y", [
    ("x", 320, 240, lambda t, w, h: t * h / w),
    ("y", 320, 240, lambda t, w, h: t),
    ("smaller", 320, 240, lambda t, w, h: t),             # landscape: the smaller axis is y
    ("smaller", 200, 300, lambda t, w, h: t * h / w),     # portrait: x
    ("larger", 320, 240, lambda t, w, h: t * h / w),
    ("larger", 200, 300, lambda t, w, h: t),
    ("diagonal", 320, 240, lambda t, w, h: t * h / math.hypot(w, h)),
])
def test_fov_axis_converts_to_vertical_fov(tmp_path, axis, w, h, tan_half_y):
    text = SCENE.replace('<float name="fov" value="60"/>',
                         f'<float name="fov" value="50"/><string name="fov_axis" value="{axis}"/>')
    text = text.replace('value="$res"', f'value="{w}"')
    text = text.replace('name="height" value="240"', f'name="height" value="{h}"')
    cam = load(write(tmp_path, text)).camera
    expected = math.degrees(2 * math.atan(tan_half_y(math.tan(math.radians(25)), w, h)))
    assert cam.fovy_deg == pytest.approx(expected, abs=1e-12)
    assert (cam.width, cam.height) == (w, h)


def test_film_defaults_and_unlimited_depth(tmp_path):
    text = SCENE.replace('value="5"', 'value="-1"')
    start, end = text.index("        <film"), text.index("</film>") + len("</film>")
    s = load(write(tmp_path, text[:start] + text[end:]))
    assert (s.camera.width, s.camera.height) == (768, 576) and s.max_depth == 64
    assert s.camera.fovy_deg == pytest.approx(math.degrees(2 * math.atan(math.tan(math.radians(30)) * 576 / 768)))


def test_mesh_resolved_next_to_the_xml_and_same_scene_as_yaml(tmp_path):
    (tmp_path / "tri.obj").write_text(TRI_OBJ)
    xml = """<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="4"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="45"/><string name="fov_axis" value="y"/>
    <float name="near_clip" value="0.1"/><float name="far_clip" value="100"/>
    <transform name="to_world"><lookat origin="0 2 6" target="0 0.6 0" up="0 1 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="320"/><integer name="height" value="240"/></film>
  </sensor>
  <shape type="rectangle" id="floor">
    <transform name="to_world"><scale x="10" y="10"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.7"/></bsdf>
  </shape>
  <shape type="obj" id="tri">
    <string name="filename" value="tri.obj"/><boolean name="face_normals" value="true"/>
    <transform name="to_world"><rotate y="1" angle="30"/><translate x="2"/></transform>
  </shape>
  <emitter type="point"><point name="position" x="2" y="5" z="3"/><float name="intensity" value="40"/></emitter>
</scene>
"""
    yaml_text = """name: probe
camera: {eye: [0, 2, 6], target: [0, 0.6, 0], up: [0, 1, 0], fovy: 45, width: 320, height: 240,
         near: 0.1, far: 100}
shapes:
  - {type: rectangle, id: floor, size: [20, 20], rotate: [-90, 0, 0], material: {albedo: 0.7}}
  - {type: mesh, id: tri, file: tri.obj, face_normals: true, rotate: [0, 30, 0], translate: [2, 0, 0],
     material: {albedo: 0.5}}
lights:
  - {type: point, position: [2, 5, 3], intensity: 40}
render: {max_depth: 4}
"""
    sx = load(write(tmp_path, xml, "probe.xml"))
    sy = load(write(tmp_path, yaml_text, "probe.yaml"))
    mesh = sx.shapes[1]
    assert mesh.type == "mesh" and mesh.param("file") == str(tmp_path / "tri.obj") and mesh.param("face_normals")
    assert sx.content_hash() == sy.content_hash()


def test_decompose_round_trips():
    rng = random.Random(7)
    cases = [((0, 0, 0), (0, 0, 0), (1, 1, 1)), ((1, 2, 3), (0, 90, 0), (1, 2, 3)),
             ((0, 0, 0), (30, -90, 45), (2, 2, 2)),
             ((-1, 0, 5), (180, 0, 0), (0.5, 1, 1)), ((0, 0, 0), (-90, 0, 0), (10, 5, 1))]
    for _ in range(200):
        cases.append(([rng.uniform(-10, 10) for _ in range(3)],
                      [rng.uniform(-179, 179), rng.uniform(-89.9, 89.9), rng.uniform(-179, 179)],
                      [math.exp(rng.uniform(-3, 3)) for _ in range(3)]))
    for t, r, s in cases:
        m = matmul4(translate4(t), matmul4(rotate4(r), scale4(s)))
        t2, r2, s2 = decompose(m)
        assert mat_close(matmul4(translate4(t2), matmul4(rotate4(r2), scale4(s2))), m), (t, r, s)
        assert close(t2, t) and close(s2, s, 1e-9 * max(s))
        if abs(r[1]) < 89:                      # away from gimbal lock the angles themselves come back
            assert close(r2, r, 1e-7), (r, r2)
    # exact gimbal lock (cos y == 0 exactly, as a typed matrix has): x and z rotations share one axis
    for r in ((30, 90, 45), (-120, -90, 10), (170, 90, -100)):
        m = [[0.0 if abs(v) < 1e-15 else v for v in row] for row in rotate4(r)]
        assert m[2][1] == m[2][2] == m[0][0] == m[1][0] == 0.0
        t2, r2, s2 = decompose(m)
        assert mat_close(rotate4(r2), m) and close(s2, (1, 1, 1)) and close(t2, (0, 0, 0)), (r, r2)


@pytest.mark.parametrize("matrix,what", [
    ("1 0.5 0 0  0 1 0 0  0 0 1 0  0 0 0 1", "shear"),
    ("-1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1", "negative determinant"),
    ("1 0 0 0  0 0 0 0  0 0 1 0  0 0 0 1", "singular"),
    ("1 0 0 0  0 1 0 0  0 0 1 0  0 0 0.5 1", "projective"),
])
def test_unsupported_matrices(tmp_path, matrix, what):
    text = SCENE.replace('<transform name="to_world">\n            <scale value="0.5"/>',
                         f'<transform name="to_world">\n            <matrix value="{matrix}"/>')
    p = write(tmp_path, text)
    with pytest.raises(SceneError) as e:
        load(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}:{line_of(text, CRATE) + 1}:"), msg
    assert what in msg and "shapes[2].to_world" in msg


def _err(tmp_path, text) -> str:
    p = write(tmp_path, text)
    with pytest.raises(SceneError) as e:
        load(p)
    return str(e.value)


@pytest.mark.parametrize("old,new,needle,words", [
    ('<shape type="cylinder">', '<shape type="teapot">', 'type="teapot"',
     ["unknown object type", "teapot", "shapes[4].type"]),
    ('<bsdf type="conductor"/>', '<bsdf type="plastic"/>', 'type="plastic"',
     ["unknown bsdf type", "plastic", "shapes[3].material"]),
    ('<float name="radius" value="1"/>', '<float name="radius" value="-1"/>', 'value="-1"',
     ["shapes[0].radius", "> 0"]),
    ('<float name="radius" value="1"/>', '<float name="radiu" value="1"/>', 'name="radiu"',
     ["radiu", "unsupported property"]),
    ('value="0.8, 0.1, 0.1"', 'value="1.8, 0.1, 0.1"', "1.8, 0.1", ["shapes[0].material.albedo", "[0, 1]"]),
    ('<integer name="width" value="$res"/>', '<integer name="width" value="0"/>', 'name="width"', ["camera.width"]),
    ('<float name="far_clip" value="200"/>', '<float name="far_clip" value="0.01"/>', 'far_clip',
     ["camera.far", "near"]),
    ('<lookat origin', '<translate x="1"/><lookat origin', '<translate x="1"/>', ["lookat", "sensor"]),
    ('<float name="fov" value="60"/>', '<float name="fov" value="60"/><string name="fov_axis" value="z"/>',
     'fov_axis', ["fov_axis", "'z'"]),
    ('<rotate y="1" angle="30"/>', '<rotate y="2" angle="30"/>', 'y="2"', ["rotate", "unit length"]),
    ('<sampler type="independent">', '<sampler type="$nope">', '$nope', ["undefined parameter", "$nope"]),
    ('<emitter type="constant">', '<emitter type="envmap">', 'type="envmap"', ["emitter", "envmap", "lights[1].type"]),
    ('<bsdf type="twosided" id="red">', '<include filename="other.xml"/><bsdf type="twosided" id="red">',
     "<include", ["include"]),
    ('<ref id="red"/>', '<ref id="blue"/>', 'id="blue"', ["blue", "shapes[0].material"]),
    ('up="0, 1, 0"', 'up="0, -1.4, -6"', "<lookat", ["lookat", "parallel"]),
    ('<default name="spp" value="16"/>', '<default value="16"/>', '<default value', ["<default>", "name"]),
    ('<float name="alpha" value="0.04"/>', '<float name="alpha" value="nan"/>', '"nan"', ["finite", "nan"]),
    ('</shape>\n    <shape type="cube"', '</shap>\n    <shape type="cube"', "</shap>", ["malformed XML", "mismatched"]),
])
def test_errors_name_file_line_and_field(tmp_path, old, new, needle, words):
    assert SCENE.count(old) == 1
    text = SCENE.replace(old, new, 1)
    msg = _err(tmp_path, text)
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:{line_of(text, needle)}:"), msg
    for w in words:
        assert w in msg, (w, msg)


def test_mutated_files_raise_only_scene_errors_with_file_line():
    """Random attribute and tag mutations: every failure is a SceneError naming file:line, never a crash."""
    rng = random.Random(1234)
    values = ["0", "-1", "1e400", "nan", "", "a", "1 2", "1,2,3,4", "$x", "0 0 0", "y", "diagonal", "maybe",
              "sphere", "ref", "twosided", "-90", "1e-12"]
    tags = ["shape", "bsdf", "ref", "transform", "lookat", "float", "rgb", "point", "sensor", "film", "emitter",
            "matrix", "scale", "integer", "spectrum", "texture", "default", "include"]
    attr, failures = re.compile(r'"[^"]*"'), 0
    for _ in range(400):
        text = SCENE
        for _ in range(rng.randint(1, 3)):
            m = rng.choice(list(attr.finditer(text)))
            text = text[:m.start()] + '"' + rng.choice(values) + '"' + text[m.end():]
        if rng.random() < 0.5:                  # rename an element (and its closing tag)
            m = rng.choice(list(re.finditer(r"<(\w+)", text)))
            new, end = rng.choice(tags), text.find(">", m.start())
            if text[end - 1] != "/":
                close_at = text.find(f"</{m.group(1)}>", end)
                text = text[:close_at] + f"</{new}>" + text[close_at + len(m.group(1)) + 3:]
            text = text[:m.start(1)] + new + text[m.end(1):]
        try:
            parse_mitsuba_xml(text, "fuzz.xml", None)
        except SceneError as e:
            assert re.match(r"^fuzz\.xml:\d+: ", str(e)), str(e)
            failures += 1
    assert failures > 100                       # the mutations do break files


def test_missing_sensor_mesh_and_version(tmp_path):
    start, end = SCENE.index("    <sensor"), SCENE.index("</sensor>") + len("</sensor>\n")
    msg = _err(tmp_path, SCENE[:start] + SCENE[end:])
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:{line_of(SCENE, '<scene')}:") and "sensor" in msg
    text = SCENE.replace('<shape type="cylinder">', '<shape type="ply"><string name="filename" value="gone.ply"/>')
    text = text.replace('<point name="p0" value="1 0 -1"/>', "").replace('<point name="p1" value="1, 2, -1"/>', "")
    text = text.replace('<float name="radius" value="0.1"/>', "")
    msg = _err(tmp_path, text)
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:{line_of(text, 'gone.ply')}:") and "shapes[4].file" in msg
    msg = _err(tmp_path, SCENE.replace('<scene version="3.0.0">', "<scene>"))
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:3:") and "version" in msg
    msg = _err(tmp_path, SCENE.replace("<scene version", "<world version").replace("</scene>", "</world>"))
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:3:") and "<scene" in msg


def test_doctype_and_entities_are_refused_without_resolving(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOP-SECRET")
    xxe = (f'<?xml version="1.0"?>\n<!DOCTYPE scene [\n  <!ENTITY xxe SYSTEM "file://{secret}">\n]>\n'
           '<scene version="3.0.0"><shape type="&xxe;"/></scene>\n')
    msg = _err(tmp_path, xxe)
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:2:") and "DOCTYPE" in msg and "TOP-SECRET" not in msg
    laughs = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;&lol;">]>\n'
              '<scene version="3.0.0">&lol2;</scene>\n')
    assert "DOCTYPE" in _err(tmp_path, laughs)
    msg = _err(tmp_path, SCENE.replace("<!-- a realistic hand-written scene -->", "<a>&undefined;</a>"))
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:2:") and "malformed XML" in msg
    assert _err(tmp_path, "").startswith(f"{tmp_path / 'scene.xml'}:1: malformed XML")


def test_parse_mitsuba_xml_directly_names_the_given_filename():
    with pytest.raises(SceneError, match=r"^my/scene\.xml:4: .*unknown object type 'torus'"):
        parse_mitsuba_xml('<scene version="3.0.0">\n<sensor type="perspective"><float name="fov" value="40"/>'
                          '</sensor>\n\n<shape type="torus"/>\n</scene>', "my/scene.xml", None)


# ---------------------------------------------------------------------- against Mitsuba itself
CROSS_XML = """<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="55"/><string name="fov_axis" value="{axis}"/>
    <float name="near_clip" value="0.1"/><float name="far_clip" value="100"/>
    <transform name="to_world"><lookat origin="3, 2.5, 5" target="0 0.5 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film>
  </sensor>
  <shape type="disk" id="coin"><transform name="to_world"><scale x="0.5" y="0.3"/>
    <rotate x="0.6917144638660746" y="0.6917144638660746" z="0.20751433915982237" angle="70"/>
    <translate value="-1 1 0.5"/></transform></shape>
  <shape type="cylinder" id="post"><float name="radius" value="0.2"/><transform name="to_world"><scale value="1 1 2"/>
    <rotate x="1" angle="-90"/><rotate y="1" angle="20"/><translate x="1.2"/></transform></shape>
  <shape type="obj" id="tri"><string name="filename" value="tri.obj"/>
    <transform name="to_world"><matrix value="0.8 0 0 -0.5  0 0.8 0 0  0 0 0.8 -1  0 0 0 1"/>
    <rotate z="1" angle="15"/></transform></shape>
  <shape type="sphere" id="ball"><point name="center" value="0.5"/><float name="radius" value="0.4"/>
    <transform name="to_world"><lookat origin="0.5 0.3 1.5" target="1 2 3" up="0 1 0"/><scale value="0.8"/>
    </transform></shape>
  <shape type="rectangle" id="floor">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="10"/></transform></shape>
  <shape type="cube" id="tilted"><transform name="to_world"><scale x="0.2" y="0.4" z="0.3"/>
    <rotate x="0.28221626051507914" y="0.9407208683835973" z="0.18814417367671946" angle="-130"/>
    <translate value="-1.5, 0.6, -1"/></transform></shape>
</scene>
"""

CROSS = r"""
import json, sys
from ssbench.reference import backend, convert
from ssbench.scenes import load
mi = backend.mitsuba()
path = sys.argv[1]

def mi_load(f, arg):          # optimize=False (Mitsuba >= 3.7) keeps meshes with equal bsdfs apart, ids intact
    try:
        return f(arg, optimize=False)
    except TypeError:
        return f(arg)
orig, conv = mi_load(mi.load_file, path), convert.load(load(path))
fov = lambda s: mi.traverse(s.sensors()[0])["x_fov"]
out = {"x_fov": [float(fov(s)) if isinstance(fov(s), float) else float(fov(s)[0]) for s in (orig, conv)],
       "rays": 0, "hits": {},
       "mismatch": 0, "worst": 0.0}
s0, s1 = orig.sensors()[0], conv.sensors()[0]
for j in range(30):
    for i in range(40):
        uv = mi.Point2f((i + 0.5) / 40, (j + 0.5) / 30)
        a = orig.ray_intersect(s0.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))[0])
        b = conv.ray_intersect(s1.sample_ray(0.0, 0.5, uv, mi.Point2f(0.5, 0.5))[0])
        out["rays"] += 1
        if bool(a.is_valid()) != bool(b.is_valid()):
            out["mismatch"] += 1
        elif a.is_valid():
            name = a.shape.id()
            out["hits"][name] = out["hits"].get(name, 0) + 1
            if not b.shape.id().endswith("__" + name):
                out["mismatch"] += 1
            out["worst"] = max(out["worst"], max(abs(float(a.p[k]) - float(b.p[k])) for k in range(3)))
print(json.dumps(out))
"""


def _mitsuba_available() -> bool:
    import importlib.util
    return importlib.util.find_spec("mitsuba") is not None


@pytest.mark.slow
@pytest.mark.mitsuba
@pytest.mark.skipif(not _mitsuba_available(), reason="Mitsuba not installed")
@pytest.mark.parametrize("axis,w,h", [("x", 160, 120), ("diagonal", 120, 180), ("smaller", 120, 180)])
def test_converted_scene_hits_what_mitsuba_hits(tmp_path, axis, w, h):
    """Mitsuba loads the XML itself; ssbench converts it and rebuilds it: the same rays hit the same points."""
    (tmp_path / "tri.obj").write_text(TRI_OBJ)
    p = write(tmp_path, CROSS_XML.format(axis=axis, w=w, h=h))
    env = dict(os.environ, SSBENCH_VARIANT="scalar_rgb")
    r = subprocess.run([sys.executable, "-c", CROSS, str(p)], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["x_fov"][0] == pytest.approx(out["x_fov"][1], abs=1e-4)
    assert out["mismatch"] == 0 and out["worst"] < 1e-4, out
    assert set(out["hits"]) >= {"coin", "post", "tri", "ball", "floor", "tilted"}, out["hits"]
