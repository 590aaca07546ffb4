"""Synthetic cases for the tuning tests: a V-shaped trough seen head-on (no Mitsuba), analytic depth and normals."""
import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.reconstruct import normals_from_depth
from ssbench.tune import Case


def trough_gbuffer(width: int = 32, height: int = 24, slope: float = 1.5, dtype=torch.float64) -> GBuffer:
    """Two walls ``z = −3 + slope·|x|`` meeting in a concave crease on the optical axis (view space)."""
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, width, height, 0.1, 100.0)
    rays = cam.pixel_rays(torch.float64)                                    # (3, H, W), z = -1
    t = 3.0 / (1.0 + slope * rays[0].abs())                                 # ray parameter to the wall
    view_z = (-t).view(1, 1, height, width)
    mask = torch.ones(1, 1, height, width, dtype=torch.bool)
    normal = normals_from_depth(cam.view_z_to_depth(view_z), cam, mask)
    return GBuffer(cam, view_z=view_z.to(dtype), normal=normal.to(dtype), mask=mask)


def trough_case(name: str = "trough", target: float = 0.85, **kw) -> Case:
    """A :class:`Case` with a smooth made-up target (AO darker toward the crease)."""
    g = trough_gbuffer(**kw)
    x = g.camera.pixel_rays(torch.float64)[0].abs().view(1, 1, g.height, g.width)
    return Case(name, g, (target + (1 - target) * (x / x.max())).to(g.view_z.dtype))


@pytest.fixture
def trough():
    return trough_case()
