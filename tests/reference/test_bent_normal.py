"""Ray-traced bent normals: the same draws as the cosine AO truth, the unoccluded floor's bent normal is its normal
within the stated error bar (whose size matches the closed form), and next to a wall it leans away from it."""
import math

import pytest
import torch

from ssbench.reference import ambient_occlusion, gbuffer
from ssbench.reference.bent_normal import bent_normals
from ssbench.scenes import load

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
CH = ["position", "normal", "mask", "shape_id", "view_z"]


def test_visible_share_is_the_cosine_ao_truth_bit_for_bit():
    sc = load("crease")
    g = gbuffer(sc, 48, 36, channels=CH)
    ref = bent_normals(sc, g, 0.8, rays=32, seed=4, use_cache=False)
    ao = ambient_occlusion(sc, g, 0.8, rays=32, weighting="cosine", seed=4, use_cache=False)
    assert torch.equal(ref.visible, ao.ao)
    again = bent_normals(sc, g, 0.8, rays=32, seed=4, use_cache=False)
    assert torch.equal(again.normal, ref.normal) and torch.equal(again.stderr_deg, ref.stderr_deg)
    assert not torch.equal(bent_normals(sc, g, 0.8, rays=32, seed=5, use_cache=False).normal, ref.normal)
    with pytest.raises(ValueError, match="rays"):
        bent_normals(sc, g, 0.8, rays=1)


def test_open_floor_is_its_normal_within_the_error_bar_and_a_wall_tilts_it_away():
    sc, R, n = load("crease"), 0.8, 256
    g = gbuffer(sc, 120, 90, channels=CH)
    ref = bent_normals(sc, g, R, rays=n, seed=1, use_cache=False)
    floor = g.shape_id[0, 0] == sc.shape_index("floor")
    x = g.camera.view_to_world(g.position.double())[0][2] + 3.0         # distance from the wall (z = −3)
    open_floor = floor & (x > 1.05 * R)
    ang = torch.rad2deg(torch.acos((ref.normal * g.normal).sum(1)[0].double().clamp(-1, 1)))
    se = ref.stderr_deg[0, 0].double()
    # every ray is free there: cos-weighted directions have E[cos θ] = 2/3, E[sin² θ] = 1/2, so the error bar (the
    # RMS angle of the estimate) is √(½/n)/(2/3) rad; the observed angles have that RMS and the Rayleigh mean √π/2 of it
    expected = math.degrees(math.sqrt(0.5 / n) / (2 / 3))
    assert se[open_floor].mean().item() == pytest.approx(expected, rel=0.1)
    assert ang[open_floor].pow(2).mean().sqrt().item() == pytest.approx(expected, rel=0.1)
    assert ang[open_floor].mean().item() == pytest.approx(expected * math.sqrt(math.pi) / 2, rel=0.1)
    band = floor & (x < 0.5 * R)
    assert band.sum() > 100
    bent_world = g.camera.view_to_world_dir(ref.normal.double())[0]       # (3, H, W)
    lean = bent_world[2][band]                                             # +z: away from the wall
    assert lean.mean().item() > 0.15 and (lean > 0).float().mean().item() > 0.95
    assert torch.all(ref.normal[:, :, ~g.mask[0, 0]] == 0) and torch.all(ref.stderr_deg[0, 0][~g.mask[0, 0]] == 0)


def test_a_pixel_with_no_free_ray_keeps_its_shading_normal_and_an_infinite_error_bar():
    sc = load("cornell_box")
    g = gbuffer(sc, 32, 24, channels=CH)
    ref = bent_normals(sc, g, 5.0, rays=2, seed=0, use_cache=False)         # a closed room, a long radius
    none = g.mask[0, 0] & (ref.visible[0, 0] == 0)
    assert none.sum() > 20 and torch.isinf(ref.stderr_deg[0, 0][none]).all()
    assert torch.allclose(ref.normal[0][:, none], g.normal[0][:, none].float(), atol=1e-5)
