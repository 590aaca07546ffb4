"""SSR resolve: Fresnel, roughness blur and blend against closed forms."""
import math

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
    nan_rough = torch.zeros(1, 1, 21, 21, dtype=torch.float64)
    nan_rough[..., 3, 4] = math.nan
    with pytest.raises(ValueError, match="^roughness: contains NaN"):              # not an index error from torch
        roughness_blur(x, nan_rough, 4.0, 5)
    with pytest.raises(ValueError, match="^roughness"):
        resolve(_gbuffer(roughness=math.nan), torch.zeros(1, 3, 12, 16, dtype=torch.float64))


def _every_level_blur(x, roughness, max_sigma, levels):
    """The blur with every σ level computed, interpolated pixel by pixel (the form before the skipped levels)."""
    import kornia
    stack = [x if s < 1e-3 else kornia.filters.gaussian_blur2d(x, (2 * int(3 * s) + 1,) * 2, (s, s),
                                                               border_type="replicate")
             for s in torch.linspace(0.0, max_sigma, levels).tolist()]
    out = torch.empty_like(x)
    for row in range(x.shape[-2]):
        for col in range(x.shape[-1]):
            pos = roughness[0, 0, row, col].clamp(0, 1) * (levels - 1)
            i = min(int(pos.floor()), levels - 2)
            a, b = stack[i][0, :, row, col], stack[i + 1][0, :, row, col]
            out[0, :, row, col] = a + (b - a) * (pos - i)
    return out


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_roughness_blur_blurs_only_the_weighed_levels_and_gives_the_bits_of_every_level(monkeypatch, dtype):
    """Levels that no pixel weighs are not blurred (a mirror-and-matte scene needs two of five), and the result is
    the blur of every level interpolated per pixel, bit for bit, for continuous, two-valued and on-level maps."""
    import kornia
    gen = torch.Generator().manual_seed(4)
    x = torch.rand(1, 3, 9, 11, generator=gen, dtype=dtype)
    u = torch.rand(1, 1, 9, 11, generator=gen, dtype=dtype)
    maps = {"continuous": u, "mirror and matte": (u > 0.5).to(dtype), "on levels": (u * 5).floor() / 4,
            "mirror": torch.zeros_like(u), "half": torch.full_like(u, 0.5)}
    blurs = {"continuous": 4, "mirror and matte": 2, "on levels": 4, "mirror": 0, "half": 1}   # of σ = 1, 2, 3, 4
    blur, sigmas = kornia.filters.gaussian_blur2d, []
    monkeypatch.setattr(kornia.filters, "gaussian_blur2d", lambda *a, **k: sigmas.append(a[2]) or blur(*a, **k))
    for name, rough in maps.items():
        sigmas.clear()
        got = roughness_blur(x, rough, 4.0, 5)
        assert len(sigmas) == blurs[name], (name, sigmas)
        assert torch.equal(got, _every_level_blur(x, rough, 4.0, 5)), name
