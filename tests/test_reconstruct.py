"""Position and normals from depth (ssbench.reconstruct) on analytic planes."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.reconstruct import normals_from_depth, normals_from_position, position_from_depth

F64 = torch.float64
METHODS = ("uv_to_view", "inverse_projection")

CAMERAS = {
    "square_60": Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 48, 48, 0.1, 100.0),
    "wide_640x360_fov90": Camera.from_look_at((1, 2, 3), (0, 0, 0), (0, 1, 0), 90.0, 64, 36, 0.05, 20.0),
    "tall_30": Camera.from_look_at((0, 5, 0), (0, 0, 0), (0, 0, -1), 30.0, 27, 41, 1.0, 9.0),
}

# view-space planes n·p = c: the normal is +z tilted by a fraction of the largest tilt that keeps the plane
# across the whole frustum (90° − the half-diagonal fov), toward azimuth phi; the plane passes through
# (0, 0, −√(near·far)).   name: (tilt fraction, phi in degrees)
PLANES = {
    "tilted": (0.5, 30.0),
    "steep": (0.85, 200.0),
    "fronto": (0.0, 0.0),
}


def plane_view_z(cam: Camera, normal, point) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Ray–plane intersection at every pixel centre (float64). Returns (view_z (1,1,H,W), p (1,3,H,W), n (3,))."""
    n = torch.tensor(normal, dtype=F64)
    n = n / n.norm()
    c = (n * torch.tensor(point, dtype=F64)).sum()
    rays = cam.pixel_rays(F64)                                         # (3, H, W), z = −1
    t = c / (n[:, None, None] * rays).sum(0)                           # p = t·ray
    p = rays * t
    if c > 0:                                                          # orient toward the camera: n·(0 − p) > 0
        n = -n
    return p[2:3].unsqueeze(0), p.unsqueeze(0), n


def make_plane(cam: Camera, key: str):
    frac, phi = PLANES[key]
    half_diag = math.atan(math.tan(math.radians(cam.fovy_deg) / 2) * math.hypot(1.0, cam.aspect))
    theta = frac * (math.pi / 2 - half_diag)
    phi = math.radians(phi)
    normal = (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))
    point = (0.0, 0.0, -math.sqrt(cam.near * cam.far))
    z, p, n = plane_view_z(cam, normal, point)
    assert bool(((z < -cam.near) & (z > -cam.far)).all()), "the plane must cover the whole image"
    return z, p, n


def angle(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Angle (rad) between (B, 3, H, W) fields, robust for tiny angles."""
    cross = torch.linalg.cross(a, b, dim=1).norm(dim=1)
    return torch.atan2(cross, (a * b).sum(1))


@pytest.fixture(params=list(CAMERAS), ids=list(CAMERAS))
def cam(request) -> Camera:
    return CAMERAS[request.param]


# ---------------------------------------------------------------------------------------------- positions
@pytest.mark.parametrize("plane", list(PLANES))
@pytest.mark.parametrize("method", METHODS)
def test_position_from_depth_float64(cam, plane, method):
    z, p, _ = make_plane(cam, plane)
    d = cam.view_z_to_depth(z)
    got = position_from_depth(d, cam, method)
    assert got.shape == p.shape and got.dtype == F64
    torch.testing.assert_close(got, p, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("plane", list(PLANES))
@pytest.mark.parametrize("method", METHODS)
def test_position_from_depth_float32(cam, plane, method):
    """Float32 error bound, per pixel.

    With u = 2⁻²⁴ (float32 unit round-off), view z = n·f / ((f − n)·d − f) and the denominator cancels to
    D = n·f/|z|. Three roundings of size ≈ u·f feed it: the float32 depth value itself ((f − n)·δd), the
    product (f − n)·d, and (f − n) rounded to float32; each is u·(f − n)|z|/(f·n) relative to z once divided
    by D. The remaining operations (subtraction, n·f, division, the uv grid and (A·uv + B)·z) add a few u
    relative to ‖p‖. Hence ‖Δp‖ ≤ 4·u·(1 + (f − n)|z|/(f·n))·‖p‖ (measured: ≤ 2× the unscaled bound).
    """
    z, p, _ = make_plane(cam, plane)
    d32 = cam.view_z_to_depth(z).float()                               # what a float32 depth buffer holds
    got = position_from_depth(d32, cam, method)
    assert got.dtype == torch.float32
    u = 2.0 ** -24
    n, f = cam.near, cam.far
    bound = 4 * u * (1 + (f - n) * z.abs() / (f * n)) * p.norm(dim=1, keepdim=True)
    err = (got.double() - p).norm(dim=1, keepdim=True)
    assert bool((err <= bound).all()), (err / bound).max().item()


def test_both_methods_agree_and_batch(cam):
    za, pa, _ = make_plane(cam, "tilted")
    zb, pb, _ = make_plane(cam, "steep")
    d = cam.view_z_to_depth(torch.cat([za, zb]))                        # batch of 2
    expected = torch.cat([pa, pb])
    for method in METHODS:
        got = position_from_depth(d, cam, method)
        assert got.shape == (2, 3, cam.height, cam.width)
        torch.testing.assert_close(got, expected, rtol=1e-9, atol=1e-9)
    torch.testing.assert_close(position_from_depth(d, cam, "uv_to_view"),
                               position_from_depth(d, cam, "inverse_projection"), rtol=1e-10, atol=1e-10)


def test_position_on_background_is_far_plane_point(cam):
    d = torch.ones(1, 1, cam.height, cam.width, dtype=F64)
    for method in METHODS:
        p = position_from_depth(d, cam, method)
        torch.testing.assert_close(p, cam.pixel_rays(F64)[None] * cam.far, rtol=1e-12, atol=1e-9)


def test_position_reprojects_to_pixel_centres(cam):
    z, _, _ = make_plane(cam, "steep")
    p = position_from_depth(cam.view_z_to_depth(z), cam)
    torch.testing.assert_close(cam.view_to_pixel(p)[0], cam.pixel_centers(F64), rtol=0, atol=1e-9)


@pytest.mark.parametrize("method", METHODS)
def test_gradcheck_position_from_depth(method):
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 50.0, 5, 4, 0.5, 10.0)
    d = (0.2 + 0.7 * torch.rand(1, 1, 4, 5, generator=torch.Generator().manual_seed(0), dtype=F64))
    d.requires_grad_(True)
    assert torch.autograd.gradcheck(lambda x: position_from_depth(x, cam, method), (d,))


# ---------------------------------------------------------------------------------------------- normals
@pytest.mark.parametrize("plane", list(PLANES))
def test_normals_on_plane_exact_everywhere(cam, plane):
    z, _, n = make_plane(cam, plane)
    p = position_from_depth(cam.view_z_to_depth(z), cam)
    normals = normals_from_position(p)
    ang = angle(normals, n.view(1, 3, 1, 1).expand_as(normals))
    assert ang.max().item() < 1e-6                                      # every pixel, border included
    torch.testing.assert_close(normals.norm(dim=1), torch.ones_like(normals[:, 0]), rtol=0, atol=1e-12)
    assert bool(((normals * -p).sum(1) > 0).all())                      # faces the camera
    # the one-call helper gives the same
    torch.testing.assert_close(normals_from_depth(cam.view_z_to_depth(z), cam), normals, rtol=0, atol=0)


def test_normals_float32_plane():
    cam = CAMERAS["square_60"]
    z, _, n = make_plane(cam, "tilted")
    normals = normals_from_depth(cam.view_z_to_depth(z).float(), cam)
    assert normals.dtype == torch.float32
    assert angle(normals.double(), n.view(1, 3, 1, 1).expand(1, 3, cam.height, cam.width)).max().item() < 0.05


def two_planes(cam: Camera):
    """Left half on a near tilted plane, right half on a far tilted plane (a depth discontinuity)."""
    za, pa, na = plane_view_z(cam, (0.3, 0.5, 0.81), (0, 0, -2.0))
    zb, pb, nb = plane_view_z(cam, (-0.4, 0.2, 0.89), (0, 0, -8.0))
    left = torch.zeros(1, 1, cam.height, cam.width, dtype=torch.bool)
    left[..., : cam.width // 2] = True
    z = torch.where(left, za, zb)
    p = torch.where(left, pa, pb)
    n = torch.where(left, na.view(1, 3, 1, 1), nb.view(1, 3, 1, 1))
    return z, p, n, left


def test_normals_at_depth_discontinuity_pick_same_plane():
    cam = CAMERAS["square_60"]
    z, p_true, n_true, left = two_planes(cam)
    assert bool(((z < -cam.near) & (z > -cam.far)).all())
    p = position_from_depth(cam.view_z_to_depth(z), cam)
    torch.testing.assert_close(p, p_true, rtol=1e-9, atol=1e-9)
    normals = normals_from_position(p)
    ang = angle(normals, n_true)
    assert ang.max().item() < 1e-6
    # and the columns next to the edge are really different planes
    c = cam.width // 2
    assert angle(n_true[..., c - 1:c], n_true[..., c:c + 1]).min().item() > 0.1


def test_normals_with_plain_central_difference_would_fail_at_the_edge():
    """Sanity check that the discontinuity test can fail: a central difference is wrong at the edge."""
    cam = CAMERAS["square_60"]
    z, _, n_true, _ = two_planes(cam)
    p = position_from_depth(cam.view_z_to_depth(z), cam)
    dpdu = p[..., 1:-1, 2:] - p[..., 1:-1, :-2]
    dpdv = p[..., :-2, 1:-1] - p[..., 2:, 1:-1]
    central = torch.nn.functional.normalize(torch.linalg.cross(dpdu, dpdv, dim=1), dim=1)
    assert angle(central, n_true[..., 1:-1, 1:-1]).max().item() > 0.1


def test_masked_and_isolated_pixels_get_zero_normals():
    cam = CAMERAS["square_60"]
    H, W = cam.height, cam.width
    z, _, n = make_plane(cam, "tilted")
    p = position_from_depth(cam.view_z_to_depth(z), cam)
    mask = torch.zeros(1, 1, H, W, dtype=torch.bool)
    mask[..., 5:20, 5:30] = True                                       # a block
    mask[..., 30, 30] = True                                           # isolated pixel: no neighbour at all
    mask[..., 40, 10:20] = True                                        # a row: horizontal but no vertical one
    mask[..., 10:20, 40] = True                                        # a column: vertical but no horizontal one
    normals = normals_from_position(p, mask)
    assert not bool(normals.isnan().any())
    zero = (normals == 0).all(1, keepdim=True)
    assert bool(zero[~mask].all())                                     # masked out
    assert bool(zero[..., 30, 30].all())
    assert bool(zero[..., 40, 10:20].all())
    assert bool(zero[..., 10:20, 40].all())
    block = normals[..., 5:20, 5:30]                                    # block edges use the inner neighbour
    assert angle(block, n.view(1, 3, 1, 1).expand_as(block)).max().item() < 1e-6


def test_no_nan_on_background_depth_one():
    cam = CAMERAS["wide_640x360_fov90"]
    H, W = cam.height, cam.width
    d = torch.ones(1, 1, H, W, dtype=F64)
    # all background, unmasked: the far plane is a fronto-parallel plane, normal +z
    nrm = normals_from_depth(d, cam)
    assert not bool(nrm.isnan().any())
    torch.testing.assert_close(nrm, torch.tensor([0.0, 0, 1], dtype=F64).view(1, 3, 1, 1).expand_as(nrm),
                               rtol=0, atol=1e-9)
    # all background, masked out
    assert bool((normals_from_depth(d, cam, d < 1) == 0).all())
    # a plane in front of the background
    z, _, n = make_plane(cam, "steep")
    dd = cam.view_z_to_depth(z)
    hole = torch.zeros_like(dd, dtype=torch.bool)
    hole[..., 10:20, 20:40] = True
    dd = torch.where(hole, torch.ones_like(dd), dd)
    for dtype in (F64, torch.float32):
        out = normals_from_depth(dd.to(dtype), cam, dd < 1)
        assert not bool(out.isnan().any())
        assert bool((out[hole.expand_as(out)] == 0).all())


def test_degenerate_positions_give_zero_not_nan():
    p = torch.zeros(2, 3, 4, 5, dtype=F64)                              # every neighbour coincides
    out = normals_from_position(p)
    assert not bool(out.isnan().any()) and bool((out == 0).all())
    p1 = torch.randn(1, 3, 1, 6, dtype=F64)                             # one row: no vertical neighbour
    assert bool((normals_from_position(p1) == 0).all())


# ---------------------------------------------------------------------------------------------- bad input
def test_bad_shapes_name_the_argument():
    cam = CAMERAS["square_60"]
    H, W = cam.height, cam.width
    for bad in (torch.zeros(1, 3, H, W), torch.zeros(1, 1, H + 1, W), torch.zeros(1, 1, H, W - 1),
                torch.zeros(H, W), torch.zeros(1, H, W)):
        with pytest.raises(ValueError, match="^depth"):
            position_from_depth(bad, cam)
    for bad in (torch.zeros(1, 1, 4, 5), torch.zeros(3, 4, 5), torch.zeros(1, 4, 4, 5)):
        with pytest.raises(ValueError, match="^position"):
            normals_from_position(bad)
    with pytest.raises(ValueError, match="^mask"):
        normals_from_position(torch.zeros(1, 3, 4, 5), torch.ones(1, 1, 4, 6, dtype=torch.bool))


def test_unknown_method_names_method():
    cam = CAMERAS["square_60"]
    with pytest.raises(ValueError, match="^method") as info:
        position_from_depth(torch.zeros(1, 1, cam.height, cam.width), cam, method="foo")
    assert "foo" in str(info.value)


def test_angle_helper_resolves_tiny_angles():
    a = torch.tensor([1.0, 0, 0], dtype=F64).view(1, 3, 1, 1)
    b = torch.tensor([1.0, 1e-8, 0], dtype=F64).view(1, 3, 1, 1)
    assert angle(a, b).item() == pytest.approx(1e-8, rel=1e-6)
    assert math.isclose(angle(a, -a).item(), math.pi)
