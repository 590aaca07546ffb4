"""The depth buffer as geometry: what the screen-space oracle (:func:`ssbench.reference.screen_space_oracle`) traces.

Every pixel centre's view-space ``position`` is a vertex (background pixels on the far plane) and every 2×2 block of
pixels is two triangles, so the mesh is a **height field over the screen**: each triangle projects exactly onto half
of the square between four pixel centres, and each line of sight through the image meets exactly one triangle.

Two ways to ask it something:

* as a Mitsuba scene (:class:`HeightField` ``.scene``), for rays in any direction (the uniform, cosine and obscurance
  flavours trace hemisphere rays through it with Embree);
* by **lookup** (:func:`behind`), for the volume flavours' question "is the point ``S`` behind the depth buffer?". The
  segment from ``S`` to the eye lies on one line of sight, so it can only meet the one triangle under ``S``'s
  projection: project ``S`` to its pixel, pick the triangle, and compare ``S`` with that triangle's plane. This is
  the same test :func:`ssbench.reference.ao_volume.inside` makes by tracing the segment against the mesh, without
  the traversal: at 640×360 and 128 points per pixel, on the five AO scenes, 0.18–0.22 s per image where tracing
  the segments took 0.9–2.9 s (they are long and cross much of the BVH).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gbuffer import GBuffer


def heightfield_mesh(gbuffer: GBuffer) -> tuple[np.ndarray, np.ndarray]:
    """View-space vertices :math:`(H·W, 3)` (pixel-centre positions; background on the far plane) and
    triangle indices :math:`(2(H−1)(W−1), 3)` joining every 2×2 block of pixels, counter-clockwise as seen
    from the camera."""
    gbuffer.require("position")
    H, W = gbuffer.height, gbuffer.width
    verts = gbuffer.position[0].permute(1, 2, 0).reshape(-1, 3).double().numpy().astype(np.float32)
    j, i = np.meshgrid(np.arange(H - 1), np.arange(W - 1), indexing="ij")
    a = (j * W + i).ravel()                       # top-left of each block (row 0 is the top)
    b, c, d = a + 1, a + W, a + W + 1              # top-right, bottom-left, bottom-right
    faces = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)]).astype(np.uint32)
    return verts, faces


@dataclass(frozen=True)
class HeightField:
    """The depth buffer as a loaded Mitsuba scene (:func:`heightfield_mesh`), its vertices for :func:`behind`, and the
    oracle's ray origins: the G-buffer's ``position`` and ``normal`` per pixel (Dr.Jit arrays of length H·W) and
    ``hit`` (its ``mask``). ``camera`` is the G-buffer's."""

    scene: object
    vertices: object
    origin: object
    n_view: object
    hit: object
    camera: object


#: the last G-buffer's height field (its BVH takes ~0.2 s at 640×360 and every flavour of the oracle traces it)
_LAST: dict = {}


def load(mi, dr, gbuffer: GBuffer, digest: str) -> HeightField:
    """:class:`HeightField` of ``gbuffer`` (``digest``: the hash of its position, normal and mask), built once and
    kept for the next call on the same G-buffer."""
    key = (digest, gbuffer.height, gbuffer.width)
    if key in _LAST:
        return _LAST[key]
    _LAST.clear()
    verts, faces = heightfield_mesh(gbuffer)
    mesh = mi.Mesh("heightfield", len(verts), len(faces), has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(verts.ravel())
    params["faces"] = mi.UInt32(faces.ravel())
    params.update()
    mscene = mi.load_dict({"type": "scene", "heightfield": mesh})
    p = gbuffer.position[0].reshape(3, -1).float()
    n = gbuffer.normal[0].reshape(3, -1).float()
    origin = dr.zeros(mi.SurfaceInteraction3f, gbuffer.height * gbuffer.width)   # spawn_ray reads p, n, time, λ
    origin.p = mi.Point3f(mi.Float(p[0].contiguous()), mi.Float(p[1].contiguous()), mi.Float(p[2].contiguous()))
    n_view = mi.Vector3f(mi.Float(n[0].contiguous()), mi.Float(n[1].contiguous()), mi.Float(n[2].contiguous()))
    origin.n = mi.Normal3f(n_view)
    vertices = mi.Float64(verts.astype(np.float64).ravel())
    hf = HeightField(mscene, vertices, origin, n_view, mi.Bool(gbuffer.mask.reshape(-1).contiguous()),
                     gbuffer.camera)
    _LAST[key] = hf
    return hf


def behind(mi, dr, hf: HeightField, s, active):
    """Mask of view-space points ``s`` (a Dr.Jit ``Point3f``) behind the depth buffer: the segment from ``s`` to the
    eye (the view-space origin) meets the height field's triangle under ``s`` from its back side. This is
    :func:`ssbench.reference.ao_volume.inside` run against ``hf.scene``, answered by lookup (module docstring).

    ``s`` projects to continuous pixel coordinates ``(px, py)`` (:meth:`ssbench.camera.Camera.view_to_pixel`): the
    cell ``(i, j)`` with ``i ≤ px − ½ < i + 1`` and ``j ≤ py − ½ < j + 1`` holds two triangles of
    :func:`heightfield_mesh`, split by its diagonal from the top-right vertex ``b`` to the bottom-left ``c``. The side
    of the plane through the eye, ``b`` and ``c`` that ``s`` lies on picks the triangle (the sign of ``(b × c)·s``,
    as the top-left vertex ``a`` gives for the upper one). With its vertices ``v₀, v₁, v₂`` in face order and
    ``n = (v₁ − v₀) × (v₂ − v₀)`` (Mitsuba's geometric normal, facing the camera), the line of sight ``t·s`` meets
    the plane at ``t* = n·v₀ / n·s``; ``s`` is inside when ``0 ≤ t* ≤ 1`` (the hit lies between the eye and ``s``)
    and ``n·s < 0`` (the segment toward the eye leaves through the back side). Points behind the eye (``z ≥ 0``) or
    outside the pixel-centre grid meet nothing.

    The test runs in float64 on the float32 vertices: across a depth discontinuity a triangle joins a near vertex to
    one on the far plane and is almost parallel to the line of sight, and in float32 its plane's rounding moved the
    answer for about 1 point in 2 000 near it.
    """
    cam = hf.camera
    W, H = cam.width, cam.height
    if W < 2 or H < 2:                                        # no triangles
        return dr.zeros(mi.Bool, dr.width(s))
    s = mi.Point3d(s)
    front = active & (s.z < 0)
    z = dr.select(front, s.z, -1.0)                           # keep the divide finite where the answer is "no"
    scale = cam.ndc_scale()
    ndc_x, ndc_y = cam.scaled_ndc_xy(s.x, s.y, z, (dr.opaque(mi.Float64, scale[0]), dr.opaque(mi.Float64, scale[1])))
    px, py = cam.uv_to_pixel_xy(cam.ndc_to_uv(ndc_x), cam.ndc_to_uv(ndc_y))
    fx, fy = px - 0.5, py - 0.5                               # pixel-centre grid coordinates
    on = front & (fx >= 0) & (fy >= 0) & (fx <= W - 1) & (fy <= H - 1)
    i = dr.minimum(mi.Int32(dr.floor(dr.select(on, fx, 0.0))), W - 2)
    j = dr.minimum(mi.Int32(dr.floor(dr.select(on, fy, 0.0))), H - 2)
    ia = mi.UInt32(j * W + i)
    a, b, c, d = (dr.gather(mi.Point3d, hf.vertices, k, on) for k in (ia, ia + 1, ia + W, ia + W + 1))
    bc = dr.cross(mi.Vector3d(b), mi.Vector3d(c))
    upper = dr.dot(bc, mi.Vector3d(s)) * dr.dot(bc, mi.Vector3d(a)) >= 0     # s on a's side of the diagonal
    v0 = dr.select(upper, a, b)
    n = dr.cross(c - v0, dr.select(upper, b, d) - v0)
    n_s, n_v0 = dr.dot(n, mi.Vector3d(s)), dr.dot(n, mi.Vector3d(v0))
    return on & (n_s < 0) & (n_s <= n_v0) & (n_v0 <= 0)
