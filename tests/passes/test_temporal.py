"""Temporal accumulation: an exponential moving average on a still camera, exact reprojection of a smooth field
on a moving one, rejection where the depth disagrees, and the clamp's bound."""
import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes.temporal import AccumulationParams, TemporalAccumulator, accumulate, reproject


def wall(cam: Camera, z: float = -3.0) -> GBuffer:
    vz = torch.full((1, 1, cam.height, cam.width), z, dtype=torch.float64)
    return GBuffer(cam, view_z=vz, mask=torch.ones_like(vz, dtype=torch.bool))


CAM = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 16, 12, 0.1, 100.0)


def test_still_camera_without_clamp_is_the_exponential_moving_average():
    g = wall(CAM)
    gen = torch.Generator().manual_seed(0)
    frames = [torch.rand(1, 1, 12, 16, generator=gen, dtype=torch.float64) for _ in range(6)]
    acc = TemporalAccumulator(AccumulationParams(alpha=0.2, clamp="none"))
    ema = frames[0]
    for t, f in enumerate(frames):
        out = acc.step(f, g)
        ema = f if t == 0 else ema + (f - ema) * 0.2
        assert torch.allclose(out, ema, atol=1e-12), t


def plane(cam: Camera, z: float = -3.0) -> tuple[GBuffer, torch.Tensor]:
    """The world plane ``z`` seen by ``cam``: its G-buffer and the world x of each pixel's surface point."""
    d = cam.pixel_rays(torch.float64).unsqueeze(0)                            # (1, 3, H, W) view directions
    dw = cam.view_to_world_dir(d, dim=1)
    eye = torch.tensor(cam.eye, dtype=torch.float64).view(1, 3, 1, 1)
    p = eye + dw * ((z - eye[:, 2:3]) / dw[:, 2:3])
    vz = cam.world_to_view(p, dim=1)[:, 2:3]
    return GBuffer(cam, view_z=vz, mask=torch.ones_like(vz, dtype=torch.bool)), p[:, :1]


def test_a_moving_camera_reprojects_a_smooth_field_to_where_it_was():
    """History = the world x of the surface seen in the last frame; after the camera turns it must read the world
    x of what each pixel sees now: bilinear on a field that perspective bends slightly, so to 5 % of a texel's
    footprint on the plane (2·3·tan 30° / 32 = 0.108)."""
    prev = Camera.from_look_at((0, 0, 0), (0.05, 0.02, -1), (0, 1, 0), 60.0, 32, 24, 0.1, 100.0)
    now = Camera.from_look_at((0.1, 0, 0), (0.1, 0, -1), (0, 1, 0), 60.0, 32, 24, 0.1, 100.0)
    (g0, x0), (g1, x1) = plane(prev), plane(now)
    here, valid = reproject(x0, prev, g0.view_z, g1)
    assert float(valid.float().mean()) > 0.8
    assert float((here - x1).abs()[valid].max()) < 0.05 * 0.108
    assert float((here - x1).abs()[valid].median()) < 1e-3
    assert float((x0 - x1).abs().max()) > 0.05                              # the views do differ


def test_history_from_another_depth_is_rejected():
    g = wall(CAM, -3.0)
    here, valid = reproject(torch.ones(1, 1, 12, 16, dtype=torch.float64), CAM,
                            torch.full((1, 1, 12, 16), -6.0, dtype=torch.float64), g, depth_tolerance=0.02)
    assert not bool(valid.any())
    out = accumulate(torch.zeros(1, 1, 12, 16, dtype=torch.float64), here, valid)
    assert bool((out == 0).all())                                           # rejected: the current frame


def test_clamp_bounds_history_by_the_current_neighbourhood():
    cur = torch.zeros(1, 1, 8, 8, dtype=torch.float64)
    cur[..., 4, 4] = 0.5
    hist = torch.ones_like(cur)
    ok = torch.ones_like(cur, dtype=torch.bool)
    out = accumulate(cur, hist, ok, AccumulationParams(alpha=0.1))
    assert out[0, 0, 0, 0] == 0.0 and math.isclose(float(out[0, 0, 4, 4]), 0.5)
    assert math.isclose(float(out[0, 0, 3, 3]), 0.45)                       # history 1 clamped to the 3×3 max 0.5
    with pytest.raises(ValueError, match="alpha"):
        AccumulationParams(alpha=0.0)
    with pytest.raises(ValueError, match="clamp"):
        AccumulationParams(clamp="variance")


def test_motion_vectors_follow_a_moving_surface():
    """A textured plane slides 0.3 world units along x under a still camera; the history is its texture
    coordinate ``u = x − offset``. With the plane's motion vectors the reprojected history reads, at every pixel,
    the coordinate the surface point there had last frame, which is its coordinate now (exactly, but for the column
    whose source lies half off screen, read with border padding). Reprojecting by the camera alone reads the texture 0.3 away."""
    from ssbench.passes.temporal import object_motion
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 32, 24, 0.1, 100.0)
    g, x = plane(cam)
    g = GBuffer(cam, view_z=g.view_z, mask=g.mask, shape_id=torch.zeros_like(g.view_z, dtype=torch.int32))
    u_prev, u_now = x - 0.0, x - 0.3                                        # the plane moved by +0.3 in x
    motion = object_motion(g, 0, (0.3, 0.0, 0.0))
    here, valid = reproject(u_prev, cam, g.view_z, g, motion=motion)
    assert float(valid.float().mean()) > 0.8
    err = (here - u_now).abs()[valid]
    assert float((err > 1e-9).float().mean()) < 0.05 and float(err.max()) < 0.25 * 0.108   # exact but the border
    still, valid_still = reproject(u_prev, cam, g.view_z, g)
    assert float((still - u_now).abs()[valid_still].min()) > 0.29
    assert bool((object_motion(g, 1, (0.3, 0.0, 0.0)) == 0).all())             # another shape: no motion
    with pytest.raises(ValueError, match="displacement"):
        object_motion(g, 0, (0.3, float("nan"), 0.0))
    with pytest.raises(ValueError, match="shape_id"):
        object_motion(wall(cam), 0, (0.3, 0.0, 0.0))
