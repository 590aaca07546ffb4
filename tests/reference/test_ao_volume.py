"""The volume flavours (what point-counting SSAO estimates) against an independent half-space computation."""
import math

import pytest
import torch

from ssbench.reference import ambient_occlusion, gbuffer, screen_space_oracle
from ssbench.scenes import load

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
CH = ["position", "normal", "mask", "shape_id", "view_z"]


def _kernel_law(weighting: str, n: int, g: torch.Generator) -> torch.Tensor:
    """Independent draw of the kernel law in the frame (t1, t2, normal), written from the docstring."""
    if weighting == "volume_sphere":
        d = torch.randn(n, 3, generator=g, dtype=torch.float64)
        return d / d.norm(dim=1, keepdim=True) * torch.rand(n, 1, generator=g, dtype=torch.float64) ** (1 / 3)
    u = torch.rand(n, 6, generator=g, dtype=torch.float64)
    d = torch.stack([2 * u[:, 0] - 1, 2 * u[:, 1] - 1, u[:, 2]], 1)
    d = d / d.norm(dim=1, keepdim=True)
    phi = 2 * math.pi * u[:, 5]
    x, y = torch.cos(phi) * d[:, 0] - torch.sin(phi) * d[:, 1], torch.sin(phi) * d[:, 0] + torch.cos(phi) * d[:, 1]
    return torch.stack([x, y, d[:, 2]], 1) * (u[:, 3] * (0.1 + 0.9 * u[:, 4] ** 2))[:, None]


def _crease_truth(weighting: str, x: torch.Tensor, R: float) -> torch.Tensor:
    """AO of a floor point at distance ``x`` from the wall: the kernel (normal +y) is inside where it goes
    below the floor or behind the wall plane; the law is symmetric about the normal, so one tangent axis
    stands for the wall's normal."""
    k = _kernel_law(weighting, 400_000, torch.Generator().manual_seed(5))
    below = k[:, 2] < 0                                               # under the floor (sphere only)
    t = k[:, 0]                                                       # component toward the wall
    inside = below[None, :] | (x.reshape(-1, 1) - R * t[None, :] < 0)
    return 1 - inside.double().mean(1)


@pytest.mark.parametrize("weighting,open_value", [("volume_hemisphere", 1.0), ("volume_sphere", 0.5)])
def test_crease_matches_the_half_space_volume_fraction(weighting, open_value):
    sc, R = load("crease"), 0.8
    g = gbuffer(sc, 160, 120, channels=CH)
    ref = ambient_occlusion(sc, g, R, rays=1024, weighting=weighting, seed=1, use_cache=False)
    floor = g.shape_id[0, 0] == sc.shape_index("floor")
    world = g.camera.view_to_world(g.position.double())[0]
    x = world[2] + 3.0                                                # distance from the wall (z = −3)
    expected = torch.full_like(x, open_value)
    band = floor & (x < R)
    expected[band] = _crease_truth(weighting, x[band], R)
    assert band.sum() > 300 and (expected[band] < open_value - 0.1).sum() > 50   # the crease shows
    z = (ref.ao[0, 0].double() - expected) / ref.stderr[0, 0].double()
    assert (z.abs()[floor] < 3).float().mean() >= 0.95
    assert abs((ref.ao[0, 0].double() - expected)[band].mean()) < 4e-3
    if weighting == "volume_hemisphere":                              # never inside above an open floor
        assert torch.all(ref.ao[0, 0][floor & (x > R)] == 1.0)


def test_oracle_counts_what_is_behind_the_depth_buffer():
    sc, R = load("crease"), 0.8
    g = gbuffer(sc, 160, 120, channels=CH)
    for w in ("volume_hemisphere", "volume_sphere"):
        full = ambient_occlusion(sc, g, R, rays=256, weighting=w, seed=2, use_cache=False)
        orc = screen_space_oracle(g, R, rays=256, weighting=w, seed=2, use_cache=False)
        W, H = g.width, g.height
        inner = g.mask[0, 0].clone()
        inner[:, : W // 8] = inner[:, -W // 8:] = False                  # samples can leave the image near
        inner[: H // 8] = inner[-H // 8:] = False                        # its border: the oracle misses those
        diff = (orc.ao - full.ao)[0, 0][inner]
        assert diff.abs().median() == 0.0 and diff.abs().mean() < 0.01, w   # paired samples, same geometry


def test_unknown_weighting_names_the_argument():
    sc = load("crease")
    g = gbuffer(sc, 16, 12, channels=CH)
    with pytest.raises(ValueError, match="weighting"):
        ambient_occlusion(sc, g, 0.5, weighting="volume")
