"""SSR resolve: Fresnel, roughness blur and blend against closed forms."""
import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes.ssr.resolve import (Resolve, ResolveParams, resolve, roughness_blur, schlick_fresnel)

CAM = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 16, 12, 0.1, 10.0)


def _gbuffer(roughness=0.0, metallic=1.0, albedo=0.9, dtype=torch.float64):
    full = lambda c, v: torch.full((1, c, 12, 16), float(v), dtype=dtype)        # noqa: E731
    pos = CAM.uv_to_view(CAM.uv_grid(dtype).unsqueeze(0), full(1, -2.0))       # a wall facing the camera
    normal = torch.cat([full(2, 0), full(1, 1)], 1)
    return GBuffer(CAM, position=pos, normal=normal, albedo=full(3, albedo), roughness=full(1, roughness),
                   metallic=full(1, metallic), color=full(3, 0.25), mask=torch.ones(1, 1, 12, 16, dtype=torch.bool))


def test_schlick_closed_form():
    f0 = torch.tensor(0.04, dtype=torch.float64)
    assert torch.allclose(schlick_fresnel(torch.tensor(1.0, dtype=torch.float64), f0), f0)
    assert torch.allclose(schlick_fresnel(torch.tensor(0.0, dtype=torch.float64), f0), torch.tensor(1.0).double())
    c = torch.tensor(0.5, dtype=torch.float64)
    assert torch.allclose(schlick_fresnel(c, f0), f0 + (1 - f0) * 0.5 ** 5)


def test_mirror_shows_fresnel_weighted_reflection_and_rough_dielectric_keeps_colour():
    refl = torch.rand(1, 3, 12, 16, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    g = _gbuffer(roughness=0.0, metallic=1.0, albedo=0.9)
    cos = (g.normal * -g.position / g.position.norm(dim=1, keepdim=True)).sum(1, keepdim=True)
    expected = schlick_fresnel(cos, torch.tensor(0.9, dtype=torch.float64)) * refl      # base = 0 for metals
    assert torch.allclose(resolve(g, refl), expected, atol=1e-12)
    rough = _gbuffer(roughness=1.0, metallic=0.0)
    assert torch.allclose(resolve(rough, refl), rough.color)                           # (1 − r) = 0
    assert torch.allclose(Resolve()(g, refl), resolve(g, refl))


def test_roughness_blur_levels_and_interpolation():
    x = torch.zeros(1, 3, 21, 21, dtype=torch.float64)
    x[..., 10, 10] = 1.0
    sharp = roughness_blur(x, torch.zeros(1, 1, 21, 21, dtype=torch.float64), 4.0, 5)
    assert torch.equal(sharp, x)                                                       # roughness 0: no blur
    half = roughness_blur(x, torch.full((1, 1, 21, 21), 0.5, dtype=torch.float64), 4.0, 5)
    assert abs(float(half.sum()) - 3.0) < 1e-6 and float(half[..., 10, 10].max()) < 1.0   # energy kept
    with pytest.raises(ValueError, match="levels"):
        ResolveParams(levels=1)
    with pytest.raises(ValueError, match="gbuffer"):
        resolve(GBuffer(CAM, color=torch.zeros(1, 3, 12, 16)), torch.zeros(1, 3, 12, 16))
    with pytest.raises(ValueError, match="reflection"):
        resolve(_gbuffer(), torch.zeros(1, 3, 5, 5, dtype=torch.float64))
