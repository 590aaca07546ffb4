"""Mitsuba 3 scene files written the way users write them, built by the tests in a temporary folder.

* :func:`cornell_box` — in the style of the Mitsuba documentation's Cornell box: ``$``-defaults, an integrator,
  a sampler, a film with a tent filter and a pixel format, ``focus_distance``, OBJ walls, ``twosided`` diffuse
  BSDFs by ``<ref>``, a principled box, an area light.
* :func:`mesh_pile` — an environment map and ``n`` (≥ 100) small PLY meshes piled on a PLY floor, one file each.
* :func:`matrix_sensor` — a sensor given by a ``<matrix>``, shapes by ``rotate``/``scale``/``translate`` chains,
  a textured diffuse quad, an ``<include>`` and a point light.
"""
from __future__ import annotations

import math
import random
from pathlib import Path

import numpy as np

CUBE_V = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
CUBE_F = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def write_obj(path: Path, verts, quads) -> None:
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    lines += ["f " + " ".join(str(i + 1) for i in q) for q in quads]
    path.write_text("\n".join(lines) + "\n")


def write_ply(path: Path, verts, quads) -> None:
    """An ASCII PLY of triangles (each quad split in two)."""
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    head = ["ply", "format ascii 1.0", f"element vertex {len(verts)}", "property float x", "property float y",
            "property float z", f"element face {len(tris)}", "property list uchar int vertex_indices", "end_header"]
    body = [f"{x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts] + [f"3 {a} {b} {c}" for a, b, c in tris]
    path.write_text("\n".join(head + body) + "\n")


def box(centre, half, turn_deg: float = 0.0):
    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
    out = []
    for x, y, z in CUBE_V:
        x, y, z = x * half[0], y * half[1], z * half[2]
        out.append((centre[0] + c * x + s * z, centre[1] + y, centre[2] - s * x + c * z))
    return out


CORNELL = """<?xml version="1.0" encoding="utf-8"?>
<scene version="3.0.0">
    <default name="spp" value="64"/>
    <default name="res" value="96"/>
    <default name="max_depth" value="6"/>
    <integrator type="path">
        <integer name="max_depth" value="$max_depth"/>
    </integrator>
    <sensor type="perspective" id="sensor">
        <string name="fov_axis" value="smaller"/>
        <float name="near_clip" value="0.001"/>
        <float name="far_clip" value="100.0"/>
        <float name="focus_distance" value="1000"/>
        <float name="fov" value="39.3077"/>
        <transform name="to_world">
            <lookat origin="0, 0, 4.1" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="$res"/>
            <integer name="height" value="72"/>
            <rfilter type="tent"/>
            <string name="pixel_format" value="rgb"/>
            <string name="component_format" value="float32"/>
        </film>
    </sensor>
    <bsdf type="twosided" id="gray">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.885809, 0.698859, 0.666422"/></bsdf>
    </bsdf>
    <bsdf type="twosided" id="green">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.105421, 0.37798, 0.076425"/></bsdf>
    </bsdf>
    <bsdf type="twosided" id="red">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.570068, 0.0430135, 0.0443706"/></bsdf>
    </bsdf>
    <bsdf type="twosided" id="lightbsdf">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.78, 0.78, 0.78"/></bsdf>
    </bsdf>
    <shape type="obj" id="floor"><string name="filename" value="meshes/floor.obj"/><ref id="gray"/></shape>
    <shape type="obj" id="ceiling"><string name="filename" value="meshes/ceiling.obj"/><ref id="gray"/></shape>
    <shape type="obj" id="back"><string name="filename" value="meshes/back.obj"/><ref id="gray"/></shape>
    <shape type="obj" id="greenwall"><string name="filename" value="meshes/greenwall.obj"/><ref id="green"/></shape>
    <shape type="obj" id="redwall"><string name="filename" value="meshes/redwall.obj"/><ref id="red"/></shape>
    <shape type="obj" id="tallbox"><string name="filename" value="meshes/tallbox.obj"/>
        <bsdf type="principled">
            <rgb name="base_color" value="0.7, 0.7, 0.2"/>
            <float name="roughness" value="0.3"/>
            <float name="metallic" value="0.5"/>
        </bsdf>
    </shape>
    <shape type="obj" id="shortbox"><string name="filename" value="meshes/shortbox.obj"/><ref id="gray"/></shape>
    <shape type="obj" id="light"><string name="filename" value="meshes/light.obj"/><ref id="lightbsdf"/>
        <emitter type="area"><rgb name="radiance" value="18.387, 13.9873, 6.75357"/></emitter>
    </shape>
</scene>
"""


def cornell_box(folder: Path) -> Path:
    """The Cornell box of :data:`CORNELL` with its OBJ meshes under ``folder/meshes``."""
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    quad = [(0, 1, 2, 3)]
    walls = {"floor": [(-1, -1, 1), (1, -1, 1), (1, -1, -1), (-1, -1, -1)],
             "ceiling": [(-1, 1, 1), (-1, 1, -1), (1, 1, -1), (1, 1, 1)],
             "back": [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1)],
             "greenwall": [(1, -1, -1), (1, -1, 1), (1, 1, 1), (1, 1, -1)],
             "redwall": [(-1, -1, 1), (-1, -1, -1), (-1, 1, -1), (-1, 1, 1)],
             "light": [(-0.24, 0.99, -0.22), (0.23, 0.99, -0.22), (0.23, 0.99, 0.16), (-0.24, 0.99, 0.16)]}
    for name, v in walls.items():
        write_obj(folder / "meshes" / f"{name}.obj", v, quad)
    write_obj(folder / "meshes" / "tallbox.obj", box((-0.33, -0.4, -0.28), (0.3, 0.6, 0.3), 18), CUBE_F)
    write_obj(folder / "meshes" / "shortbox.obj", box((0.33, -0.7, 0.3), (0.3, 0.3, 0.3), -17), CUBE_F)
    path = folder / "cbox.xml"
    path.write_text(CORNELL)
    return path


def mesh_pile(folder: Path, n: int = 120, seed: int = 0) -> Path:
    """An envmap scene with ``n`` PLY bricks (one file each) on a PLY floor, seen from above at an angle."""
    import mitsuba as mi                                   # the caller has set a variant (backend.mitsuba())
    rng = random.Random(seed)
    (folder / "bricks").mkdir(parents=True, exist_ok=True)
    sky = np.ones((16, 32, 3), np.float32) * np.array([0.6, 0.7, 0.9], np.float32)
    sky[8:] *= 0.25                                                          # darker lower hemisphere
    mi.Bitmap(sky).write(str(folder / "sky.exr"))
    write_ply(folder / "floor.ply", [(-4, 0, -4), (-4, 0, 4), (4, 0, 4), (4, 0, -4)], [(0, 1, 2, 3)])
    shapes = ['    <shape type="ply" id="floor"><string name="filename" value="floor.ply"/><ref id="stone"/></shape>']
    side = math.ceil(math.sqrt(n))
    for k in range(n):
        i, j = divmod(k, side)
        layer = k % 3
        centre = (-2.2 + 4.4 * i / side + rng.uniform(-0.05, 0.05), 0.08 + 0.16 * layer,
                  -2.2 + 4.4 * j / side + rng.uniform(-0.05, 0.05))
        write_ply(folder / "bricks" / f"b{k:03d}.ply", box(centre, (0.14, 0.08, 0.07), rng.uniform(0, 180)), CUBE_F)
        mat = "brick" if k % 4 else "mortar"
        shapes.append(f'    <shape type="ply" id="b{k:03d}"><string name="filename" value="bricks/b{k:03d}.ply"/>'
                      f'<ref id="{mat}"/></shape>')
    text = f"""<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="50"/>
        <transform name="to_world"><lookat origin="0, 4.5, 5.5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="80"/><integer name="height" value="60"/></film>
    </sensor>
    <emitter type="envmap"><string name="filename" value="sky.exr"/><float name="scale" value="1.0"/></emitter>
    <bsdf type="diffuse" id="stone"><rgb name="reflectance" value="0.5"/></bsdf>
    <bsdf type="roughplastic" id="brick"><rgb name="diffuse_reflectance" value="0.55, 0.2, 0.12"/>
        <float name="alpha" value="0.36"/></bsdf>
    <bsdf type="diffuse" id="mortar"><rgb name="reflectance" value="0.7, 0.7, 0.65"/></bsdf>
{chr(10).join(shapes)}
</scene>
"""
    path = folder / "pile.xml"
    path.write_text(text)
    return path


MATRIX = """<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="60"/>
        <string name="fov_axis" value="y"/>
        <float name="near_clip" value="0.05"/>
        <float name="far_clip" value="50"/>
        <transform name="to_world">
            <matrix value="{m}"/>
        </transform>
        <film type="hdrfilm"><integer name="width" value="72"/><integer name="height" value="54"/></film>
    </sensor>
    <include filename="parts/objects.xml"/>
    <shape type="rectangle" id="poster">
        <transform name="to_world"><scale x="0.8" y="0.5"/><translate x="0" y="0.7" z="-1.5"/></transform>
        <bsdf type="diffuse">
            <texture type="bitmap" name="reflectance">
                <string name="filename" value="parts/stripes.png"/>
                <string name="filter_type" value="nearest"/>
            </texture>
        </bsdf>
    </shape>
    <emitter type="point"><point name="position" value="1, 3, 2"/><rgb name="intensity" value="20"/></emitter>
    <emitter type="constant"><rgb name="radiance" value="0.2"/></emitter>
</scene>
"""

OBJECTS = """<scene version="3.0.0">
    <shape type="rectangle" id="ground">
        <transform name="to_world"><scale value="5"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf>
    </shape>
    <shape type="sphere" id="ball">
        <transform name="to_world"><scale value="0.4"/><translate x="-0.6" y="0.4" z="-0.5"/></transform>
        <bsdf type="roughconductor"><float name="alpha" value="0.09"/></bsdf>
    </shape>
    <shape type="cube" id="crate">
        <transform name="to_world"><scale value="0.3"/><rotate y="1" angle="30"/><translate x="0.7" y="0.3"/></transform>
        <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.5, 0.7"/></bsdf></bsdf>
    </shape>
</scene>
"""

#: the two texel colours of the poster's texture (left half, right half), as stored (sRGB 8-bit)
STRIPES = ((230, 20, 20), (20, 230, 20))


def camera_matrix(eye, target) -> list[list[float]]:
    """Mitsuba's ``look_at`` written out: columns (left, up, forward, eye)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    f = (target - eye) / np.linalg.norm(target - eye)
    left = np.cross([0.0, 1.0, 0.0], f)
    left /= np.linalg.norm(left)
    up = np.cross(f, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, up, f, eye
    return m.tolist()


def matrix_sensor(folder: Path, eye=(0.4, 1.6, 3.2), target=(0.0, 0.4, 0.0)) -> Path:
    """A scene whose sensor is a ``<matrix>``; objects come from ``parts/objects.xml`` by ``<include>``."""
    import mitsuba as mi
    (folder / "parts").mkdir(parents=True, exist_ok=True)
    (folder / "parts" / "objects.xml").write_text(OBJECTS)
    img = np.zeros((2, 2, 3), np.uint8)
    img[:, 0], img[:, 1] = STRIPES
    mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB).write(str(folder / "parts" / "stripes.png"))
    m = " ".join(f"{v:.9f}" for row in camera_matrix(eye, target) for v in row)
    path = folder / "matrix.xml"
    path.write_text(MATRIX.format(m=m))
    return path
