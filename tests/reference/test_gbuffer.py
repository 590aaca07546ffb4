"""Reference G-buffer against closed forms and the camera module (acceptance items of the foundation)."""
import math

import pytest
import torch
import torch.nn.functional as F

from ssbench.camera import Camera
from ssbench.reconstruct import normals_from_depth, position_from_depth
from ssbench.reference import gbuffer
from ssbench.scenes import catalog, load

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]

CAMERAS = {   # (eye, target, up, fovy)
    "default": ((0, 2, 6), (0, 0.6, 0), (0, 1, 0), 45.0),
    "wide": ((1.5, 1.0, 4.0), (-0.5, 0.5, 0), (0, 1, 0), 100.0),
    "tilted": ((3.0, 4.0, -2.5), (0, 0.5, 0), (0.3, 1, 0.2), 30.0),
}


def scene_with(cam_key: str, width: int, height: int, name: str = "sphere_on_plane"):
    eye, target, up, fovy = CAMERAS[cam_key]
    cam = Camera.from_look_at(eye, target, up, fovy, width, height, 0.1, 100.0)
    return load(name).with_camera(cam)


@pytest.mark.parametrize("size", [(320, 240), (640, 360)])
@pytest.mark.parametrize("cam_key", list(CAMERAS))
def test_reprojection_lands_on_pixel_centre(cam_key, size):
    g = gbuffer(scene_with(cam_key, *size), channels=["position", "mask"])
    cam = g.camera
    assert g.mask.float().mean() > 0.3                              # the camera sees geometry
    px = cam.view_to_pixel(g.position.double())                     # (1, 2, H, W)
    err = (px - cam.pixel_centers(torch.float64)).abs()[g.mask.expand(-1, 2, -1, -1)]
    assert err.max().item() <= 1e-3


def test_view_z_depth_round_trip():
    for name in ("sphere_on_plane", "grazing_floor", "cornell_box"):
        g = gbuffer(name, channels=["view_z", "mask"])
        cam, m = g.camera, g.mask
        z = g.view_z.double()
        back = cam.depth_to_view_z(cam.view_z_to_depth(z))
        assert ((back - z).abs() / z.abs()).max() <= 1e-5             # all pixels, background included
        # float32 GL depth: the buffer's own rounding bounds the error (CONVENTIONS.md, depth precision)
        z32 = g.view_z
        back32 = cam.depth_to_view_z(cam.view_z_to_depth(z32))
        bound = 4 * 2 ** -24 * z.abs() ** 2 * (cam.far - cam.near) / (cam.far * cam.near) + 4e-7 * z.abs()
        assert ((back32.double() - z).abs() <= bound)[m].all()


def test_position_from_depth_both_ways():
    g = gbuffer("stairs", channels=["view_z", "position", "mask"])
    m = g.mask[:, 0]
    for method in ("uv_to_view", "inverse_projection"):
        p = position_from_depth(g.depth, g.camera, method)          # float32 GL depth, as a shader would
        rel = (p - g.position).norm(dim=1) / g.position.norm(dim=1)
        assert rel[m].max() <= 1e-4, method


def _flat_mask(g):
    """Pixels whose 3x3 neighbourhood is one shape with one reference normal (planar interior)."""
    sid = g.shape_id.float()
    same = F.max_pool2d(sid, 3, 1, 1) == -F.max_pool2d(-sid, 3, 1, 1)
    planar = F.avg_pool2d(g.normal, 3, 1, 1, count_include_pad=False).norm(dim=1, keepdim=True) > 1 - 1e-6
    return (g.mask & same & planar)[:, 0]


@pytest.mark.parametrize("name", ["crease", "stairs", "cornell_box", "fence", "grazing_floor"])
def test_normals_from_depth_on_flat_regions(name):
    g = gbuffer(name, channels=["view_z", "normal", "shape_id", "mask"])
    flat = _flat_mask(g)
    assert flat.float().mean() > 0.3
    n = normals_from_depth(g.depth, g.camera, g.mask)
    cos = (n * g.normal).sum(1).clamp(-1, 1)
    assert torch.rad2deg(torch.acos(cos))[flat].max() <= 1.0


def _sphere_roots(cam: Camera, center, radius):
    """Closed-form entry/exit view z of the pixel-centre rays (float64), and the cosine at entry."""
    d = cam.pixel_rays(torch.float64)                               # view space, z = -1
    d = d / d.norm(dim=0, keepdim=True)
    c = cam.world_to_view(torch.tensor(center, dtype=torch.float64), dim=-1)[:, None, None]
    b = (d * c).sum(0)
    disc = b * b - ((c * c).sum(0) - radius ** 2)
    hit = disc > 0
    sq = disc.clamp_min(0).sqrt()
    t0, t1 = b - sq, b + sq
    p0 = d * t0
    cos = ((p0 - c) / radius * -d).sum(0)
    return hit, (t0 * d[2]), (t1 * d[2]), cos


@pytest.mark.parametrize("size", [(320, 240), (200, 300)])
def test_sphere_entry_and_exit_depths(size):
    center, radius = (0.3, -0.2, -1.0), 1.7
    scene = {"name": "big_sphere", "camera": {"eye": [0, 0, 5], "target": [0, 0, 0], "fovy": 50,
                                              "width": size[0], "height": size[1]},
             "shapes": [{"type": "sphere", "id": "ball", "center": list(center), "radius": radius}]}
    g = gbuffer(scene, channels=["view_z", "back_z", "mask"])
    hit, z0, z1, cos = _sphere_roots(g.camera, center, radius)
    ok = hit & (cos.abs() >= 0.1)
    assert (g.mask[0, 0] == hit)[cos.abs() >= 0.02].all()                       # same silhouette
    assert ((g.view_z[0, 0].double() - z0).abs() / z0.abs())[ok].max() <= 1e-4
    assert ((g.back_z[0, 0].double() - z1).abs() / z1.abs())[ok].max() <= 1e-4


def test_shape_ids_materials_and_fill_values():
    sc = load("sphere_on_plane")
    g = gbuffer(sc, channels=["view_z", "normal", "position", "albedo", "roughness", "metallic", "shape_id",
                              "mask", "back_z"])
    H, W = g.height, g.width
    assert g.shape_id[0, 0, H // 2, W // 2] == sc.shape_index("ball")
    assert g.shape_id[0, 0, H - 1, W // 2] == sc.shape_index("floor")
    assert g.shape_id[0, 0, 0, 0] == -1 and not g.mask[0, 0, 0, 0]
    for i, s in enumerate(sc.shapes):
        sel = g.shape_id[0, 0] == i
        assert torch.allclose(g.albedo[0][:, sel], torch.tensor(s.material.albedo)[:, None])
        assert torch.all(g.roughness[0, 0][sel] == s.material.roughness)
    bg = ~g.mask[0, 0]
    assert torch.all(g.view_z[0, 0][bg] == -sc.camera.far)
    assert torch.allclose(g.depth[0, 0][bg], torch.tensor(1.0))
    assert torch.all(g.normal[0][:, bg] == 0) and torch.all(g.albedo[0][:, bg] == 0)
    assert torch.all(g.back_z[0, 0][bg] == -math.inf)
    floor = g.shape_id[0, 0] == sc.shape_index("floor")
    assert torch.all(g.back_z[0, 0][floor] == -math.inf)                        # open rectangle: no exit
    ball = g.shape_id[0, 0] == sc.shape_index("ball")
    assert torch.all(g.back_z[0, 0][ball] < g.view_z[0, 0][ball])               # exit lies behind entry
    n = g.normal[0][:, g.mask[0, 0]]
    assert torch.allclose(n.norm(dim=0), torch.ones(n.shape[1]), atol=1e-5)
    assert torch.all((n * -g.position[0][:, g.mask[0, 0]]).sum(0) > 0)        # normals face the camera
    for t in g.as_dict().values():
        assert not (t.is_floating_point() and torch.isnan(t).any())


def test_scaled_copies_are_scale_invariant():
    base = gbuffer("sphere_on_plane", channels=["view_z", "normal", "mask"])
    for name, s in (("sphere_on_plane_small", 0.01), ("sphere_on_plane_large", 100.0)):
        g = gbuffer(name, channels=["view_z", "normal", "mask"])
        assert torch.equal(g.mask, base.mask)
        m = base.mask
        assert ((g.view_z / s - base.view_z).abs() / base.view_z.abs())[m].max() <= 1e-4
        assert (g.normal - base.normal).abs().max() <= 1e-4


def test_only_requested_channels_and_bad_arguments():
    g = gbuffer("crease", 16, 12, channels=["view_z"])
    assert g.channels == ("view_z",) and g.view_z.shape == (1, 1, 12, 16)
    with pytest.raises(ValueError, match="width"):
        gbuffer("crease", 0, 12)
    with pytest.raises(ValueError, match="height"):
        gbuffer("crease", 16, -3)
    with pytest.raises(ValueError, match="channels"):
        gbuffer("crease", 16, 12, channels=["depth_of_field"])
    with pytest.raises(KeyError, match="name_or_path"):
        gbuffer("no_such_scene")


def test_every_catalog_scene_renders_with_ids_from_the_scene():
    for name in catalog.names():
        g = gbuffer(name, 64, 48, channels=["view_z", "shape_id", "mask", "back_z"])
        assert g.mask.any(), name
        assert torch.equal(g.shape_id >= 0, g.mask), name                # every hit names its shape
        ids = set(g.shape_id.unique().tolist()) - {-1}
        assert ids <= set(range(len(load(name).shapes))), name
    g = gbuffer("cornell_box", channels=["shape_id", "mask"])            # shapes sharing one material
    assert set(g.shape_id.unique().tolist()) == {-1} | set(range(len(load("cornell_box").shapes)))


def test_second_layer_is_what_the_first_object_hides():
    """``second_z`` on the fence's slats is the depth the scene without them shows there (the sphere, the wall);
    everywhere it lies behind the first hit (the floor runs on behind the wall), −inf on the background."""
    from ssbench.scenes import catalog
    d = catalog.fence()
    d["camera"] = dict(d["camera"], width=48, height=36)
    g = gbuffer(d, channels=["view_z", "second_z", "shape_id", "mask"], use_cache=False)
    bare = dict(d, shapes=[s for s in d["shapes"] if not s["id"].startswith("slat")], name="fence_bare")
    h = gbuffer(bare, channels=["view_z", "mask"], use_cache=False)
    slat = (g.shape_id[0, 0] >= 3) & h.mask[0, 0]
    assert int(slat.sum()) > 20
    rel = ((g.second_z[0, 0] - h.view_z[0, 0]).abs() / h.view_z[0, 0].abs())[slat]
    assert float(rel.max()) < 1e-3
    found = torch.isfinite(g.second_z[0, 0])
    assert bool((g.second_z[0, 0][found] < g.view_z[0, 0][found]).all()) and not bool(found[~g.mask[0, 0]].any())
    assert 0 < int(found.sum()) < int(g.mask.sum())             # the wall's upper part: nothing behind
