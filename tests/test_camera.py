"""Camera conventions (ssbench/CONVENTIONS.md) checked against closed forms written here, independently."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from ssbench.camera import Camera

F64 = torch.float64

# (eye, target, up, fovy, W, H, near, far)
CAMERAS = {
    "default_4x3": ((0, 2, 6), (0, 0.6, 0), (0, 1, 0), 45.0, 320, 240, 0.1, 100.0),
    "wide_640x360_fov90": ((1.5, 0.7, -2.0), (-0.3, 0.2, 1.0), (0, 1, 0), 90.0, 640, 360, 0.05, 20.0),
    "down_up_minus_z": ((0, 5, 0), (0, 0, 0), (0, 0, -1), 60.0, 64, 48, 0.5, 50.0),
    "tall_odd": ((-3, 1, 2), (0.5, 0.2, -1), (0.1, 1, 0.2), 30.0, 37, 53, 1.0, 9.0),
}


@pytest.fixture(params=list(CAMERAS), ids=list(CAMERAS))
def cam(request) -> Camera:
    return Camera.from_look_at(*CAMERAS[request.param])


def gen(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def random_view_points(cam: Camera, n: int = 500, seed: int = 0, margin: float = 1.0) -> torch.Tensor:
    """(n, 3) float64 view points inside the frustum (``margin`` < 1 shrinks it)."""
    g = gen(seed)
    z = -(cam.near + (cam.far - cam.near) * torch.rand(n, generator=g, dtype=F64))
    ndc = (torch.rand(n, 2, generator=g, dtype=F64) * 2 - 1) * margin
    t = math.tan(math.radians(cam.fovy_deg) / 2)
    x = ndc[:, 0] * t * cam.aspect * -z
    y = ndc[:, 1] * t * -z
    return torch.stack([x, y, z], -1)


# ---------------------------------------------------------------------------------------------- references
def glu_look_at(eye, center, up) -> np.ndarray:
    """gluLookAt as in the OpenGL man page."""
    eye, center, up = (np.asarray(v, dtype=np.float64) for v in (eye, center, up))
    f = center - eye
    f /= np.linalg.norm(f)
    s = np.cross(f, up)
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    t = np.eye(4)
    t[:3, 3] = -eye
    return m @ t


def glu_perspective(fovy_deg, aspect, near, far) -> np.ndarray:
    """gluPerspective as in the OpenGL man page."""
    f = 1.0 / math.tan(math.radians(fovy_deg) / 2)
    return np.array([[f / aspect, 0, 0, 0],
                     [0, f, 0, 0],
                     [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
                     [0, 0, -1, 0]], dtype=np.float64)


# three.js packing.glsl, transcribed
def three_view_z_to_perspective_depth(view_z, near, far):
    return ((near + view_z) * far) / ((far - near) * view_z)


def three_perspective_depth_to_view_z(inv_clip_z, near, far):
    return (near * far) / ((far - near) * inv_clip_z - far)


def three_view_z_to_orthographic_depth(view_z, near, far):
    return (view_z + near) / (near - far)


def three_orthographic_depth_to_view_z(linear_clip_z, near, far):
    return linear_clip_z * (near - far) - near


# ---------------------------------------------------------------------------------------------- matrices
def test_view_matrix_equals_glu_look_at(cam):
    ref = glu_look_at(cam.eye, cam.target, cam.up)
    np.testing.assert_allclose(cam.view_matrix().numpy(), ref, rtol=0, atol=1e-12)


def test_view_times_camera_to_world_is_identity(cam):
    eye4 = torch.eye(4, dtype=F64)
    torch.testing.assert_close(cam.view_matrix() @ cam.camera_to_world(), eye4, rtol=0, atol=1e-12)
    torch.testing.assert_close(cam.camera_to_world() @ cam.view_matrix(), eye4, rtol=0, atol=1e-12)


def test_basis_is_right_handed_orthonormal(cam):
    r, u, b = (np.array(v) for v in cam.basis)
    m = np.stack([r, u, b], 1)
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-12)
    assert np.linalg.det(m) == pytest.approx(1.0, abs=1e-12)
    fwd = np.subtract(cam.target, cam.eye)
    np.testing.assert_allclose(-b, fwd / np.linalg.norm(fwd), atol=1e-12)   # the camera looks down −z


def test_projection_matrix_closed_form(cam):
    n, f = cam.near, cam.far
    t = math.tan(math.radians(cam.fovy_deg) / 2)
    P = cam.projection_matrix().numpy()
    expected = np.zeros((4, 4))
    expected[0, 0] = 1 / (t * cam.width / cam.height)
    expected[1, 1] = 1 / t
    expected[2, 2] = -(f + n) / (f - n)
    expected[2, 3] = -2 * f * n / (f - n)
    expected[3, 2] = -1
    np.testing.assert_allclose(P, expected, rtol=1e-14, atol=0)
    np.testing.assert_allclose(P, glu_perspective(cam.fovy_deg, cam.aspect, n, f), rtol=1e-14, atol=0)


def test_inverse_projection_matrix(cam):
    P, Pinv = cam.projection_matrix(), cam.inverse_projection_matrix()
    torch.testing.assert_close(Pinv @ P, torch.eye(4, dtype=F64), rtol=0, atol=1e-12)
    torch.testing.assert_close(P @ Pinv, torch.eye(4, dtype=F64), rtol=0, atol=1e-12)


def test_matrices_respect_dtype():
    cam = Camera.from_look_at(*CAMERAS["default_4x3"])
    for fn in (cam.view_matrix, cam.camera_to_world, cam.projection_matrix, cam.inverse_projection_matrix):
        assert fn(dtype=torch.float32).dtype == torch.float32
        assert fn().dtype == F64


# ---------------------------------------------------------------------------------------------- view <-> NDC
def test_view_to_ndc_matches_homogeneous_multiply(cam):
    p = random_view_points(cam, seed=1)
    h = torch.cat([p, torch.ones(len(p), 1, dtype=F64)], 1) @ cam.projection_matrix().T
    assert torch.allclose(h[:, 3], -p[:, 2], rtol=0, atol=0)                   # w = −z
    expected = h[:, :3] / h[:, 3:]
    got = cam.view_to_ndc(p, dim=-1)
    torch.testing.assert_close(got, expected, rtol=1e-12, atol=1e-12)
    assert bool((got.abs() <= 1 + 1e-12).all())                                 # inside the frustum


def test_near_far_map_to_ndc_minus_one_and_one(cam):
    p = torch.tensor([[0.0, 0.0, -cam.near], [0.0, 0.0, -cam.far]], dtype=F64)
    ndc = cam.view_to_ndc(p, dim=-1)
    torch.testing.assert_close(ndc[:, 2], torch.tensor([-1.0, 1.0], dtype=F64), rtol=0, atol=1e-12)


def test_view_ndc_view_round_trip(cam):
    p = random_view_points(cam, seed=2)
    back = cam.ndc_to_view(cam.view_to_ndc(p, dim=-1), dim=-1)
    torch.testing.assert_close(back, p, rtol=1e-9, atol=1e-10)


def test_uv_ndc_helpers():
    x = torch.tensor([-1.0, 0.0, 1.0], dtype=F64)
    torch.testing.assert_close(Camera.ndc_to_uv(x), torch.tensor([0.0, 0.5, 1.0], dtype=F64))
    torch.testing.assert_close(Camera.uv_to_ndc(Camera.ndc_to_uv(x)), x)


# ---------------------------------------------------------------------------------------------- UV <-> pixel
def test_uv_pixel_formulas_and_round_trip(cam):
    uv = torch.rand(300, 2, generator=gen(3), dtype=F64)
    px = cam.uv_to_pixel(uv, dim=-1)
    torch.testing.assert_close(px[:, 0], uv[:, 0] * cam.width, rtol=0, atol=0)
    torch.testing.assert_close(px[:, 1], (1 - uv[:, 1]) * cam.height, rtol=0, atol=0)
    torch.testing.assert_close(cam.pixel_to_uv(px, dim=-1), uv, rtol=0, atol=1e-15)
    q = torch.rand(300, 2, generator=gen(4), dtype=F64) * torch.tensor([cam.width, cam.height])
    torch.testing.assert_close(cam.uv_to_pixel(cam.pixel_to_uv(q, dim=-1), dim=-1), q, rtol=0, atol=1e-12)


def test_uv_corners_map_to_image_corners():
    cam = Camera.from_look_at(*CAMERAS["wide_640x360_fov90"])
    uv = torch.tensor([[0.0, 1.0], [1.0, 0.0], [0.0, 0.0]], dtype=F64)     # top-left, bottom-right, bottom-left
    expected = torch.tensor([[0.0, 0.0], [640.0, 360.0], [0.0, 360.0]], dtype=F64)
    torch.testing.assert_close(cam.uv_to_pixel(uv, dim=-1), expected, rtol=0, atol=0)


def test_view_to_pixel_round_trip(cam):
    p = random_view_points(cam, seed=5)
    px = cam.view_to_pixel(p, dim=-1)
    assert bool(((px >= 0) & (px <= torch.tensor([cam.width, cam.height]))).all())
    back = cam.uv_to_view(cam.pixel_to_uv(px, dim=-1), p[:, 2], dim=-1)
    torch.testing.assert_close(back, p, rtol=1e-10, atol=1e-10)


def test_pixel_centers_and_uv_grid_corners(cam):
    W, H = cam.width, cam.height
    c = cam.pixel_centers(F64)
    assert c.shape == (2, H, W)
    assert c[:, 0, 0].tolist() == [0.5, 0.5]
    assert c[:, 0, W - 1].tolist() == [W - 0.5, 0.5]
    assert c[:, H - 1, 0].tolist() == [0.5, H - 0.5]
    assert c[:, H - 1, W - 1].tolist() == [W - 0.5, H - 0.5]
    uv = cam.uv_grid(F64)
    assert uv.shape == (2, H, W)
    torch.testing.assert_close(uv[:, 0, 0], torch.tensor([0.5 / W, 1 - 0.5 / H], dtype=F64), rtol=0, atol=1e-15)
    torch.testing.assert_close(uv[:, H - 1, W - 1], torch.tensor([1 - 0.5 / W, 0.5 / H], dtype=F64),
                               rtol=0, atol=1e-15)
    assert bool((uv[1, 1:] < uv[1, :-1]).all())                               # v decreases down the rows
    assert bool((uv[0, :, 1:] > uv[0, :, :-1]).all())
    assert cam.pixel_centers().dtype == torch.float32


@pytest.mark.parametrize("size", [(7, 5), (640, 360), (1921, 3)])
@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_pixel_centers_at_are_the_grid_columns_they_index(size, dtype):
    """Per-index centres equal the image-wide grid's columns bit for bit (and so does ``pixel_to_uv`` of them, the
    ``uv_grid`` values): the set-ups of chunked SSR marchers use them in its place."""
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, *size, 0.1, 10.0)
    W, H = size
    index = torch.cat([torch.arange(W * H), torch.randperm(W * H, generator=torch.Generator().manual_seed(0))])
    grid = cam.pixel_centers(dtype).reshape(2, -1)
    at = cam.pixel_centers_at(index, dtype)
    assert at.dtype == dtype and torch.equal(at, grid[:, index])
    assert torch.equal(cam.pixel_to_uv(at, dim=0), cam.uv_grid(dtype).reshape(2, -1)[:, index])
    assert torch.equal(cam.pixel_centers_at(index.to(torch.int32), dtype), at)


def test_pixel_centers_at_past_int32_pixels():
    """An image of more than 2³¹ pixels divides its indices in int64 (no grid is built: the closed form checks)."""
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 70000, 40000, 0.1, 10.0)
    W, H = cam.width, cam.height
    index = torch.tensor([0, W - 1, W, 2 ** 31 + 5, W * H - 1])
    expect = [[float(i % W) + 0.5 for i in index.tolist()], [float(i // W) + 0.5 for i in index.tolist()]]
    assert cam.pixel_centers_at(index, F64).tolist() == expect


def test_pixel_rays_hand_built_and_reproject_to_pixel_centres(cam):
    W, H = cam.width, cam.height
    rays = cam.pixel_rays(F64)
    assert rays.shape == (3, H, W)
    # the ray of the Mitsuba probe (notes/mitsuba_probe.md Q1), built by hand
    t = math.tan(math.radians(cam.fovy_deg) / 2)
    i = torch.arange(W, dtype=F64).view(1, W) + 0.5
    j = torch.arange(H, dtype=F64).view(H, 1) + 0.5
    hand = torch.stack([((2 * i / W - 1) * t * cam.aspect).expand(H, W), ((1 - 2 * j / H) * t).expand(H, W),
                        torch.full((H, W), -1.0, dtype=F64)])
    torch.testing.assert_close(rays, hand, rtol=1e-13, atol=1e-13)
    for depth in (cam.near * 1.5, 0.5 * (cam.near + cam.far), cam.far * 0.99):
        px = cam.view_to_pixel(rays * depth, dim=0)
        torch.testing.assert_close(px, cam.pixel_centers(F64), rtol=0, atol=1e-9)


def test_pixel_rays_float32_is_close():
    cam = Camera.from_look_at(*CAMERAS["default_4x3"])
    torch.testing.assert_close(cam.pixel_rays().double(), cam.pixel_rays(F64), rtol=0, atol=1e-6)


# ---------------------------------------------------------------------------------------------- depth
def test_gl_depth_at_near_and_far(cam):
    d = cam.view_z_to_depth(torch.tensor([-cam.near, -cam.far], dtype=F64))
    assert d.tolist() == [0.0, 1.0]
    assert math.copysign(1.0, d[0].item()) == 1.0                               # +0, not −0
    # (f − n)·d − f cancels at d = 1: relative error ≈ ε·f/n (the precision note in CONVENTIONS.md)
    eps = torch.finfo(F64).eps
    assert cam.depth_to_view_z(torch.tensor([0.0, 1.0], dtype=F64)).tolist() == pytest.approx(
        [-cam.near, -cam.far], rel=4 * eps * cam.far / cam.near)


def test_depth_encodings_agree_with_threejs(cam):
    z = random_view_points(cam, seed=6)[:, 2]
    n, f = cam.near, cam.far
    torch.testing.assert_close(cam.view_z_to_depth(z), three_view_z_to_perspective_depth(z, n, f),
                               rtol=1e-13, atol=1e-15)
    torch.testing.assert_close(cam.view_z_to_orthographic_depth(z), three_view_z_to_orthographic_depth(z, n, f),
                               rtol=1e-14, atol=1e-15)
    d = torch.rand(200, generator=gen(7), dtype=F64)
    torch.testing.assert_close(cam.depth_to_view_z(d), three_perspective_depth_to_view_z(d, n, f),
                               rtol=1e-14, atol=0)
    torch.testing.assert_close(cam.orthographic_depth_to_view_z(d), three_orthographic_depth_to_view_z(d, n, f),
                               rtol=1e-14, atol=1e-15)


def test_gl_depth_equals_ndc_z_remapped(cam):
    p = random_view_points(cam, seed=8)
    torch.testing.assert_close(cam.view_z_to_depth(p[:, 2]), cam.view_to_ndc(p, dim=-1)[:, 2] * 0.5 + 0.5,
                               rtol=1e-12, atol=1e-13)


def test_depth_round_trips(cam):
    z = random_view_points(cam, seed=9)[:, 2]
    torch.testing.assert_close(cam.depth_to_view_z(cam.view_z_to_depth(z)), z, rtol=1e-10, atol=0)
    torch.testing.assert_close(cam.orthographic_depth_to_view_z(cam.view_z_to_orthographic_depth(z)), z,
                               rtol=1e-13, atol=0)
    lin = cam.view_z_to_orthographic_depth(z)
    assert bool(((lin >= 0) & (lin <= 1)).all())
    assert cam.view_z_to_orthographic_depth(torch.tensor([-cam.near, -cam.far], dtype=F64)).tolist() == \
        pytest.approx([0.0, 1.0], abs=1e-15)


def test_gl_depth_monotonic_and_float32_precision_formula():
    """d(d)/dz = −f·n / ((f−n)·z²)  ⇒  |Δz| / |z| ≈ ulp(d) · (f−n)·|z| / (f·n) (CONVENTIONS.md)."""
    cam = Camera.from_look_at(*CAMERAS["default_4x3"])
    z = -torch.logspace(math.log10(0.2), math.log10(90.0), 50, dtype=F64)
    d = cam.view_z_to_depth(z)
    assert bool((d[1:] > d[:-1]).all())
    n, f = cam.near, cam.far
    d32 = d.float()
    step = torch.nextafter(d32, torch.tensor(2.0)) - d32                        # ulp(d) in float32
    dz_next = cam.depth_to_view_z(d32.double() + step.double()) - cam.depth_to_view_z(d32.double())
    predicted = step.double() * (f - n) * z.abs() ** 2 / (f * n)
    torch.testing.assert_close(dz_next.abs(), predicted, rtol=1e-2, atol=0)


# ---------------------------------------------------------------------------------------------- uvToView
def test_uv_to_view_params_equal_seed_js(cam):
    fov = cam.fovy_deg
    focal1 = 1.0 / math.tan(math.radians(fov * 0.5)) * (cam.height / cam.width)
    focal2 = 1.0 / math.tan(math.radians(fov * 0.5))
    expected = (-2.0 / focal1, -2.0 / focal2, 1.0 / focal1, 1.0 / focal2)
    assert cam.uv_to_view_params() == pytest.approx(expected, rel=1e-14)
    assert cam.focal == pytest.approx(focal2, rel=1e-15)


def test_uv_to_view_agrees_with_inverse_projection(cam):
    g = gen(10)
    uv = torch.rand(400, 2, generator=g, dtype=F64)
    d = torch.rand(400, generator=g, dtype=F64) * 0.999
    a = cam.uv_to_view(uv, cam.depth_to_view_z(d), dim=-1)
    b = cam.view_position_from_depth(uv, d, dim=-1)
    torch.testing.assert_close(a, b, rtol=0, atol=1e-10 * max(1.0, cam.far))
    torch.testing.assert_close(a, b, rtol=1e-10, atol=1e-12)
    # and it is the inverse of the projection
    torch.testing.assert_close(cam.view_to_pixel(a, dim=-1), cam.uv_to_pixel(uv, dim=-1), rtol=0, atol=1e-8)


# ---------------------------------------------------------------------------------------------- world <-> view
def test_world_view_inverse_and_matrix(cam):
    g = gen(11)
    pw = torch.randn(300, 3, generator=g, dtype=F64) * 5
    pv = cam.world_to_view(pw, dim=-1)
    V = torch.tensor(glu_look_at(cam.eye, cam.target, cam.up))
    expected = (torch.cat([pw, torch.ones(300, 1, dtype=F64)], 1) @ V.T)[:, :3]
    torch.testing.assert_close(pv, expected, rtol=0, atol=1e-12)
    torch.testing.assert_close(cam.view_to_world(pv, dim=-1), pw, rtol=0, atol=1e-12)
    # directions: no translation, lengths kept
    v = torch.randn(300, 3, generator=g, dtype=F64)
    vv = cam.world_to_view_dir(v, dim=-1)
    torch.testing.assert_close(vv, v @ V[:3, :3].T, rtol=0, atol=1e-12)
    torch.testing.assert_close(vv.norm(dim=-1), v.norm(dim=-1), rtol=1e-13, atol=0)
    torch.testing.assert_close(cam.view_to_world_dir(vv, dim=-1), v, rtol=0, atol=1e-12)


def test_eye_and_target_in_view_space(cam):
    pts = torch.tensor([cam.eye, cam.target], dtype=F64)
    pv = cam.world_to_view(pts, dim=-1)
    dist = math.dist(cam.eye, cam.target)
    torch.testing.assert_close(pv, torch.tensor([[0.0, 0, 0], [0, 0, -dist]], dtype=F64), rtol=0, atol=1e-12)


def test_camera_looking_down_with_up_minus_z():
    cam = Camera.from_look_at((0, 5, 0), (0, 0, 0), (0, 0, -1), 60.0, 64, 48, 0.5, 50.0)
    r, u, b = cam.basis
    assert r == pytest.approx((1, 0, 0), abs=1e-15)       # image right = world +x
    assert u == pytest.approx((0, 0, -1), abs=1e-15)      # image up = world −z
    assert b == pytest.approx((0, 1, 0), abs=1e-15)
    px = cam.view_to_pixel(cam.world_to_view(torch.tensor([[1.0, 0, 0], [0, 0, -1.0]], dtype=F64), dim=-1), dim=-1)
    assert px[0, 0] > 32 and px[0, 1] == pytest.approx(24)   # +x lands right of centre
    assert px[1, 1] < 24 and px[1, 0] == pytest.approx(32)   # −z lands above centre (row 0 is the top)


def test_wide_camera_fov_and_corners():
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, 640, 360, 0.1, 10.0)
    assert cam.fovx_deg == pytest.approx(math.degrees(2 * math.atan(16 / 9)), rel=1e-14)
    # the view point at x = −z·tan(fovx/2) is on the right image edge; y = −z·tan(fovy/2) on the top edge
    p = torch.tensor([[2 * math.tan(math.radians(cam.fovx_deg) / 2), 2.0, -2.0]], dtype=F64)
    torch.testing.assert_close(cam.view_to_pixel(p, dim=-1), torch.tensor([[640.0, 0.0]], dtype=F64),
                               rtol=0, atol=1e-10)


def test_fovx_closed_form(cam):
    expected = 2 * math.degrees(math.atan(math.tan(math.radians(cam.fovy_deg) / 2) * cam.width / cam.height))
    assert cam.fovx_deg == pytest.approx(expected, rel=1e-14)
    # the right edge of pixel_rays' extent is at tan(fovx/2)
    right_edge = cam.uv_to_view(torch.tensor([[1.0, 0.5]], dtype=F64), torch.tensor([-1.0], dtype=F64), dim=-1)
    assert right_edge[0, 0].item() == pytest.approx(math.tan(math.radians(cam.fovx_deg) / 2), rel=1e-13)


def test_with_resolution_keeps_fovy():
    cam = Camera.from_look_at(*CAMERAS["default_4x3"])
    c2 = cam.with_resolution(64, 16)
    assert (c2.width, c2.height, c2.fovy_deg, c2.eye) == (64, 16, cam.fovy_deg, cam.eye)
    assert c2.projection_matrix()[1, 1] == cam.projection_matrix()[1, 1]
    with pytest.raises(ValueError, match="width"):
        cam.with_resolution(0, 16)


def test_camera_is_hashable_and_frozen():
    a = Camera.from_look_at(*CAMERAS["default_4x3"])
    b = Camera.from_look_at(*CAMERAS["default_4x3"])
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.near = 1.0  # type: ignore[misc]


# ---------------------------------------------------------------------------------------------- Mitsuba
def test_mitsuba_sensor(cam):
    s = cam.mitsuba_sensor()
    to_world = np.array(s["to_world"], dtype=np.float64)
    np.testing.assert_allclose(to_world, cam.camera_to_world().numpy() @ np.diag([-1.0, 1, -1, 1]), atol=0)
    right, up, back = (np.array(v) for v in cam.basis)
    fwd = np.subtract(cam.target, cam.eye)
    np.testing.assert_allclose(to_world[:3, 0], -right, atol=1e-15)            # Mitsuba local +x = image LEFT
    np.testing.assert_allclose(to_world[:3, 0], np.cross(up, -back), atol=1e-12)  # = cross(up, forward)
    np.testing.assert_allclose(to_world[:3, 1], up, atol=1e-15)
    np.testing.assert_allclose(to_world[:3, 2], fwd / np.linalg.norm(fwd), atol=1e-12)  # looks down local +z
    np.testing.assert_allclose(to_world[:3, 3], cam.eye, atol=0)
    assert np.linalg.det(to_world[:3, :3]) == pytest.approx(1.0, abs=1e-12)   # a rotation, not a mirror
    assert s["fov_axis"] == "y" and s["fov"] == cam.fovy_deg
    assert (s["width"], s["height"], s["near_clip"], s["far_clip"]) == (cam.width, cam.height, cam.near, cam.far)
    assert s["type"] == "perspective"


# ---------------------------------------------------------------------------------------------- dim=-1 vs dim=-3
def test_point_list_form_equals_image_form(cam):
    g = gen(12)
    B, H, W = 2, 3, 5
    img = random_view_points(cam, n=B * H * W, seed=13).view(B, H, W, 3).permute(0, 3, 1, 2).contiguous()
    pts = img.permute(0, 2, 3, 1).reshape(-1, 3)

    def as_img(x, c):
        return x.view(B, H, W, c).permute(0, 3, 1, 2)

    for fn in (cam.world_to_view, cam.view_to_world, cam.world_to_view_dir, cam.view_to_world_dir,
               cam.view_to_ndc):
        torch.testing.assert_close(fn(img), as_img(fn(pts, dim=-1), 3), rtol=0, atol=0)
    ndc = cam.view_to_ndc(img)
    torch.testing.assert_close(cam.ndc_to_view(ndc), as_img(cam.ndc_to_view(ndc.permute(0, 2, 3, 1).reshape(-1, 3),
                                                                            dim=-1), 3), rtol=0, atol=0)
    torch.testing.assert_close(cam.view_to_pixel(img), as_img(cam.view_to_pixel(pts, dim=-1), 2), rtol=0, atol=0)
    uv = torch.rand(B, 2, H, W, generator=g, dtype=F64)
    uv_pts = uv.permute(0, 2, 3, 1).reshape(-1, 2)
    torch.testing.assert_close(cam.uv_to_pixel(uv), as_img(cam.uv_to_pixel(uv_pts, dim=-1), 2), rtol=0, atol=0)
    torch.testing.assert_close(cam.pixel_to_uv(uv), as_img(cam.pixel_to_uv(uv_pts, dim=-1), 2), rtol=0, atol=0)
    z = img[:, 2:3]
    z_pts = z.permute(0, 2, 3, 1).reshape(-1)
    torch.testing.assert_close(cam.uv_to_view(uv, z), as_img(cam.uv_to_view(uv_pts, z_pts, dim=-1), 3),
                               rtol=0, atol=0)
    torch.testing.assert_close(cam.uv_to_view(uv, z), as_img(cam.uv_to_view(uv_pts, z_pts[:, None], dim=-1), 3),
                               rtol=0, atol=0)
    d = cam.view_z_to_depth(z)
    d_pts = d.permute(0, 2, 3, 1).reshape(-1)
    torch.testing.assert_close(cam.view_position_from_depth(uv, d),
                               as_img(cam.view_position_from_depth(uv_pts, d_pts, dim=-1), 3), rtol=0, atol=0)
    # unbatched (3, H, W) images use the same default dim
    torch.testing.assert_close(cam.world_to_view(img[0]), cam.world_to_view(img)[0], rtol=0, atol=0)


def test_uv_to_view_broadcasts_grid_over_batch():
    cam = Camera.from_look_at(*CAMERAS["default_4x3"]).with_resolution(5, 4)
    uv = cam.uv_grid(F64).unsqueeze(0)                                          # (1, 2, H, W)
    z = -1 - torch.rand(3, 1, 4, 5, generator=gen(14), dtype=F64)               # (B, 1, H, W)
    out = cam.uv_to_view(uv, z)
    assert out.shape == (3, 3, 4, 5)
    for b in range(3):
        torch.testing.assert_close(out[b:b + 1], cam.uv_to_view(uv, z[b:b + 1]), rtol=0, atol=0)


def test_wrong_component_count_names_argument():
    cam = Camera.from_look_at(*CAMERAS["default_4x3"])
    with pytest.raises(ValueError, match="^p:"):
        cam.world_to_view(torch.zeros(4, 2), dim=-1)
    with pytest.raises(ValueError, match="^uv:"):
        cam.uv_to_pixel(torch.zeros(1, 3, 2, 2))
    with pytest.raises(ValueError, match="^ndc:"):
        cam.ndc_to_view(torch.zeros(5, 2), dim=-1)


# ---------------------------------------------------------------------------------------------- bad input
GOOD = dict(eye=(0, 2, 6), target=(0, 0.6, 0), up=(0, 1, 0), fovy_deg=45.0, width=320, height=240,
            near=0.1, far=100.0)

BAD = [
    ("near", dict(near=0.0)),
    ("near", dict(near=-1.0)),
    ("near", dict(near=float("nan"))),
    ("far", dict(far=0.1)),
    ("far", dict(far=0.05)),
    ("far", dict(far=float("inf"))),
    ("fovy_deg", dict(fovy_deg=0.0)),
    ("fovy_deg", dict(fovy_deg=180.0)),
    ("fovy_deg", dict(fovy_deg=float("nan"))),
    ("fovy_deg", dict(fovy_deg=-10.0)),
    ("width", dict(width=0)),
    ("width", dict(width=2.5)),
    ("width", dict(width=True)),
    ("height", dict(height=-1)),
    ("target", dict(target=(0, 2, 6))),                   # eye == target
    ("up", dict(up=(0, -1.4, -6))),                       # parallel to forward = target − eye
    ("up", dict(up=(0, 1.4, 6))),                         # anti-parallel
    ("up", dict(up=(0, 0, 0))),
    ("eye", dict(eye=(0, 2))),
    ("eye", dict(eye=(0, float("nan"), 1))),
    ("target", dict(target="abc")),
    ("up", dict(up=(0, 1, 0, 0))),
]


@pytest.mark.parametrize("name,override", BAD, ids=[f"{n}-{i}" for i, (n, _) in enumerate(BAD)])
def test_bad_input_names_the_argument(name, override):
    kwargs = {**GOOD, **override}
    with pytest.raises(ValueError) as info:
        Camera.from_look_at(**kwargs)
    assert str(info.value).startswith(name), str(info.value)
    assert name in str(info.value)


def test_eye_equal_target_message_mentions_eye():
    with pytest.raises(ValueError) as info:
        Camera.from_look_at(**{**GOOD, "target": GOOD["eye"]})
    assert "eye" in str(info.value) and "target" in str(info.value)


def test_good_input_passes():
    Camera.from_look_at(**GOOD)
    Camera(**{**GOOD, "eye": (0.0, 2.0, 6.0), "target": (0.0, 0.6, 0.0), "up": (0.0, 1.0, 0.0)})


def test_sampling_an_image_at_shader_uv():
    """CONVENTIONS.md NOTE: texel at uv is row (1 − v)·H − 0.5; grid_sample grid is (2u − 1, 1 − 2v)."""
    cam = Camera.from_look_at(*CAMERAS["tall_odd"])
    img = torch.rand(1, 2, cam.height, cam.width, generator=gen(15), dtype=F64)
    uv = cam.uv_grid(F64)
    grid = torch.stack([2 * uv[0] - 1, 1 - 2 * uv[1]], -1)[None]               # (1, H, W, 2)
    out = torch.nn.functional.grid_sample(img, grid, mode="bilinear", align_corners=False)
    torch.testing.assert_close(out, img, rtol=0, atol=1e-12)
    row = (1 - uv[1]) * cam.height - 0.5
    col = uv[0] * cam.width - 0.5
    torch.testing.assert_close(row, torch.arange(cam.height, dtype=F64)[:, None].expand_as(row), rtol=0, atol=1e-12)
    torch.testing.assert_close(col, torch.arange(cam.width, dtype=F64)[None, :].expand_as(col), rtol=0, atol=1e-12)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_scaled_uv_xy_gives_the_two_step_uv_bit_for_bit_and_its_texels_at_the_extremes(dtype):
    """``scaled_uv_xy`` (one ``addcdiv`` per axis) against ``ndc_to_uv(scaled_ndc_xy(…))``: the same bits on
    ordinary points in front of and behind the camera; the same texel (``texel_of``, NaN read as 0) on every
    combination of zeros, subnormals, huge values, infinities and NaN, z = 0 and the smallest normal z included."""
    from ssbench.passes.common import nan_to_zero, texel_of
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 70.0, 97, 61, 0.1, 100.0)
    scale = cam.ndc_scale()
    two_step = lambda x, y, z: tuple(cam.ndc_to_uv(c) for c in cam.scaled_ndc_xy(x, y, z, scale))
    g = torch.Generator().manual_seed(2)
    x, y = (torch.randn(8, 61, 97, generator=g, dtype=torch.float64).to(dtype) * 3 for _ in range(2))
    z = (-torch.rand(8, 61, 97, generator=g, dtype=torch.float64) * 20 + 1.0).to(dtype)     # some behind
    z = torch.where(z == 0, -0.5, z)
    got, want = cam.scaled_uv_xy(x, y, z, scale), two_step(x, y, z)
    assert all(torch.equal(a, b) for a, b in zip(got, want))
    tiny, big = torch.finfo(dtype).tiny, torch.finfo(dtype).max
    vals = torch.tensor([0.0, -0.0, tiny, -tiny / 8, 1e-30, 3.0, -7.5, big, -big, math.inf, -math.inf, math.nan],
                        dtype=dtype)
    xe, ye, ze = torch.meshgrid(vals, vals, torch.cat([vals, torch.tensor([-tiny], dtype=dtype)]), indexing="ij")
    texels = [texel_of(*(nan_to_zero(c) for c in uv), 61, 97, nan_free=True)
              for uv in (cam.scaled_uv_xy(xe, ye, ze, scale), two_step(xe, ye, ze))]
    assert all(torch.equal(a, b) for a, b in zip(*texels))
