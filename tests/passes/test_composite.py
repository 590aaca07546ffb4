"""AO composite (ssbench.passes.composite): mix(OcclusionColor, color, ao^OcclusionPower), SSAO article §2.4."""
import pytest
import torch

from ssbench.passes.composite import Composite, composite

F64 = torch.float64


def rand(*shape, seed=0):
    return torch.rand(*shape, generator=torch.Generator().manual_seed(seed), dtype=F64)


def test_endpoints_and_power():
    color = rand(2, 3, 4, 5)
    occ = (0.1, 0.2, 0.3)
    occ_t = torch.tensor(occ, dtype=F64).view(1, 3, 1, 1)
    assert torch.allclose(composite(color, torch.ones(2, 1, 4, 5, dtype=F64), occ), color)
    assert torch.allclose(composite(color, torch.zeros(2, 1, 4, 5, dtype=F64), occ), occ_t.expand_as(color))
    ao = rand(2, 1, 4, 5, seed=1)
    t = ao ** 2.5
    assert torch.allclose(composite(color, ao, occ, 2.5), occ_t * (1 - t) + color * t)
    assert torch.allclose(composite(color, ao), color * ao)                # black OcclusionColor: a product


def test_tensor_occlusion_color_and_module():
    color, ao = rand(1, 3, 4, 5), rand(1, 1, 4, 5, seed=1)
    occ = rand(1, 3, 4, 5, seed=2)
    assert torch.allclose(composite(color, ao, occ), occ * (1 - ao) + color * ao)
    assert torch.equal(composite(color, ao, torch.tensor([0.5, 0.5, 0.5])), composite(color, ao, (0.5,) * 3))
    assert torch.equal(Composite((0.5,) * 3, 2.0)(color, ao), composite(color, ao, (0.5,) * 3, 2.0))


def test_gradcheck():
    color = rand(1, 3, 5, 5).requires_grad_()
    ao = (0.1 + 0.8 * rand(1, 1, 5, 5, seed=1)).requires_grad_()
    assert torch.autograd.gradcheck(lambda c, a: composite(c, a, (0.2, 0.3, 0.4), 1.7), (color, ao))


def test_exceptions():
    color, ao = rand(1, 3, 4, 5), rand(1, 1, 4, 5)
    with pytest.raises(ValueError, match="ao"):
        composite(color, ao * 2.0)
    with pytest.raises(ValueError, match="ao"):
        composite(color, ao[:, :, :3])
    with pytest.raises(ValueError, match="occlusion_power"):
        composite(color, ao, occlusion_power=0.0)
    with pytest.raises(ValueError, match="occlusion_color"):
        composite(color, ao, (0.0, 0.0))
    with pytest.raises(ValueError, match="occlusion_color"):
        composite(color, ao, "black")
    with pytest.raises(ValueError, match="color"):
        composite(color.long(), ao)
