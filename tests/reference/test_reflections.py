"""Exact mirror reflections against the closed form, and their radiance against the rendered image."""
import pytest
import torch

from ssbench.reference import color, gbuffer, reflections
from ssbench.scenes import load

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]

CENTER, RADIUS = (0.0, 1.0, 0.0), 0.8
SCENE = {"name": "mirror_and_ball",
         "camera": {"eye": [0.3, 1.5, 4.0], "target": [0, 0.4, 0], "fovy": 50, "width": 160, "height": 120},
         "shapes": [{"type": "rectangle", "id": "mirror", "size": [40, 40], "rotate": [-90, 0, 0],
                     "material": {"albedo": 0.9, "roughness": 0.0, "metallic": 1.0}},
                    {"type": "sphere", "id": "ball", "center": list(CENTER), "radius": RADIUS,
                     "material": {"albedo": [0.8, 0.3, 0.2]}}],
         "lights": [{"type": "point", "position": [2, 5, 3], "intensity": 40},
                    {"type": "environment", "radiance": 0.3}]}


def _closed_form(g):
    """Mirror ray of every floor pixel against the sphere, float64: (hit, hit point, |cos| at the hit)."""
    cam = g.camera
    p = cam.view_to_world(g.position.double())[0].reshape(3, -1)              # floor points
    eye = torch.tensor(cam.eye, dtype=torch.float64)[:, None]
    d = (p - eye) / (p - eye).norm(dim=0, keepdim=True)
    r = d * torch.tensor([1.0, -1.0, 1.0], dtype=torch.float64)[:, None]      # reflect about +y
    oc = p - torch.tensor(CENTER, dtype=torch.float64)[:, None]
    b = (oc * r).sum(0)
    disc = b * b - ((oc * oc).sum(0) - RADIUS ** 2)
    t = -b - disc.clamp_min(0).sqrt()
    hit = (disc > 0) & (t > 0)
    q = p + t * r
    cos = (((q - torch.tensor(CENTER, dtype=torch.float64)[:, None]) / RADIUS) * -r).sum(0).abs()
    H, W = g.height, g.width
    return hit.reshape(H, W), q.reshape(3, H, W), cos.reshape(H, W)


def test_mirror_plane_with_sphere_matches_closed_form():
    sc = load(SCENE)
    g = gbuffer(sc, channels=["position", "shape_id", "mask"])
    ref = reflections(sc, g, spp=4, use_cache=False)
    floor = g.shape_id[0, 0] == 0
    hit, q, cos = _closed_form(g)
    clear = floor & ((cos > 0.1) | ~hit)                                     # grazing edge pixels excluded
    assert floor.sum() > 1000 and (hit & floor).sum() > 200
    assert torch.equal(ref.hit[0, 0][clear] & (ref.hit_shape[0, 0][clear] == 1), hit[clear])
    sel = clear & hit
    err = (ref.hit_world[0].double() - q).norm(dim=0) / q.norm(dim=0)
    assert err[sel].max() <= 1e-4
    assert torch.all(ref.valid == g.mask)
    assert not (ref.back_face & ref.visible)[0, 0][sel].any()                # a back face is never seen


def test_flags_are_consistent_and_finite():
    sc = load("reflective_floor")
    g = gbuffer(sc, 96, 72, channels=["mask"])
    ref = reflections(sc, g, spp=2, use_cache=False)
    assert not (ref.hit & ~ref.valid).any() and not (ref.on_screen & ~ref.hit).any()
    assert not (ref.visible & ~ref.hit).any() and not (ref.back_face & ~ref.hit).any()
    for t in (ref.hit_pixel, ref.hit_view, ref.radiance):
        assert torch.isfinite(t).all()
    px = ref.hit_pixel[0]
    on = ref.on_screen[0, 0]
    assert (px[0][on] >= 0).all() and (px[0][on] < 96).all() and (px[1][on] < 72).all()
    # the scene is built to show every failure class of SSR article §4
    assert ref.on_screen.any() and (ref.hit & ~ref.on_screen).any()            # off-screen targets
    assert (ref.on_screen & ~ref.visible).any()                              # occluded targets
    assert ref.back_face.any()                                                # back-facing targets
    with pytest.raises(ValueError, match="spp"):
        reflections(sc, g, spp=0)


def test_radiance_matches_the_rendered_image_at_the_hit_pixel():
    sc = load(SCENE)
    g = gbuffer(sc, channels=["position", "shape_id", "mask"])
    ref = reflections(sc, g, spp=64, seed=1, use_cache=False)
    img = color(sc, spp=64, seed=2, use_cache=False)
    sel = ref.on_screen[0, 0] & ref.visible[0, 0] & (ref.hit_shape[0, 0] == 1)
    px = ref.hit_pixel[0].floor().long()
    # keep hits whose pixel and its 8 neighbours all show the ball: a pixel average at a silhouette mixes colours
    ball = torch.nn.functional.max_pool2d(-(g.shape_id != 1).float(), 3, 1, 1)[0, 0] == 0
    sel &= ball[px[1].clamp(0, g.height - 1), px[0].clamp(0, g.width - 1)]
    # and that the camera does not see at a grazing angle (there a pixel spans a long strip of surface)
    hw = ref.hit_world[0].double()
    view = torch.tensor(g.camera.eye, dtype=torch.float64)[:, None, None] - hw
    nrm = (hw - torch.tensor(CENTER, dtype=torch.float64)[:, None, None]) / RADIUS
    sel &= (nrm * view).sum(0) / view.norm(dim=0) > 0.5
    seen = img[0][:, px[1][sel], px[0][sel]]                                   # (3, n)
    mine = ref.radiance[0][:, sel]
    assert sel.sum() > 50
    rel = (mine.mean(1) - seen.mean(1)).abs() / seen.mean(1)
    assert rel.max() < 0.03                                                    # unbiased within noise
