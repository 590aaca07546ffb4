"""GGX visible-normal sampling: frames, the mirror limit, the density of the reflected direction, and Mitsuba's
own microfacet distribution as an independent check."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.passes.ssr.ggx import (alpha_of, frame, from_local, ggx_d, reflection_pdf, sample_vndf, smith_g1,
                                    to_local)

F64 = torch.float64


def _unit(n, seed):
    v = torch.randn(n, 3, generator=torch.Generator().manual_seed(seed), dtype=F64)
    return v / v.norm(dim=1, keepdim=True)


def test_frame_is_orthonormal_and_round_trips():
    n = torch.cat([_unit(500, 1), torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]], dtype=F64)])
    t, b = frame(n)
    for a, c in ((t, b), (t, n), (b, n)):
        assert float((a * c).sum(1).abs().max()) < 1e-12
    assert float((torch.cross(t, b, dim=1) - n).abs().max()) < 1e-12
    v = _unit(502, 2)
    assert float((from_local(to_local(v, t, b, n), t, b, n) - v).abs().max()) < 1e-12


def test_mirror_limit_is_exact():
    v = _unit(100, 3)
    v[:, 2] = v[:, 2].abs() + 0.01
    v = v / v.norm(dim=1, keepdim=True)
    u = torch.rand(2, 100, generator=torch.Generator().manual_seed(4), dtype=F64)
    m = sample_vndf(v, torch.zeros(100, dtype=F64), u[0], u[1])
    assert torch.equal(m, torch.tensor([0.0, 0.0, 1.0], dtype=F64).expand(100, 3))
    assert float(alpha_of(torch.tensor([0.5]))) == 0.25


@pytest.mark.parametrize("alpha,theta", [(0.1, 0.3), (0.5, 1.0), (0.25, 0.0)])
def test_reflection_pdf_is_the_density_of_the_sampler(alpha, theta):
    """E[q(l)/p(l)] = ∫ q = 1 for the cosine density q, if p is what the sampler draws (full-support lobe)."""
    N = 400_000
    v = torch.tensor([[math.sin(theta), 0.0, math.cos(theta)]], dtype=F64).expand(N, 3)
    u = torch.rand(2, N, generator=torch.Generator().manual_seed(5), dtype=F64)
    a = torch.full((N,), alpha, dtype=F64)
    m = sample_vndf(v, a, u[0], u[1])
    assert bool((m[:, 2] >= 0).all()) and bool(((v * m).sum(1) >= -1e-12).all())   # visible normals only
    l = 2.0 * (v * m).sum(1, keepdim=True) * m - v
    p = reflection_pdf(v[:, 2], m[:, 2], a)
    est = torch.where(l[:, 2] > 0, l[:, 2] / math.pi / p, 0.0)
    mean, se = float(est.mean()), float(est.std() / math.sqrt(N))
    assert abs(mean - 1.0) < max(4 * se, 0.01), (mean, se)


def test_d_integrates_to_one_over_projected_area():
    """∫ D(m) cos θ_m dm = 1 (the microfacets' projected area is the macro-surface's)."""
    th = torch.linspace(0, math.pi / 2, 200_001, dtype=F64)
    for alpha in (0.05, 0.3, 0.9):
        f = ggx_d(torch.cos(th), torch.tensor(alpha, dtype=F64)) * torch.cos(th) * torch.sin(th) * 2 * math.pi
        assert float(torch.trapezoid(f, th)) == pytest.approx(1.0, abs=2e-3)


def test_matches_mitsuba_microfacet_distribution():
    from ssbench.reference import backend
    if not backend.is_jit():
        pytest.skip("needs a vectorised Mitsuba variant")
    mi = backend.mitsuba()
    v, m = _unit(64, 6), _unit(64, 7)
    v[:, 2], m[:, 2] = v[:, 2].abs() + 0.05, m[:, 2].abs() + 0.05
    v, m = v / v.norm(dim=1, keepdim=True), m / m.norm(dim=1, keepdim=True)
    alpha = 0.3
    d = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, alpha, True)
    V, M = mi.Vector3f(*[mi.Float(c.float().numpy()) for c in v.T]), mi.Vector3f(*[mi.Float(c.float().numpy()) for c in m.T])
    a = torch.tensor(alpha, dtype=F64)
    assert torch.allclose(ggx_d(m[:, 2], a).float(), d.eval(M).torch().float(), rtol=1e-4)
    facing = (v * m).sum(1) > 0                                  # Mitsuba's G1 is 0 where v·m < 0
    assert int(facing.sum()) > 20
    assert torch.allclose(smith_g1(v[:, 2], a).float()[facing], d.smith_g1(V, M).torch().float()[facing], rtol=1e-4)
    vndf = smith_g1(v[:, 2], a) * (v * m).sum(1).clamp_min(0) * ggx_d(m[:, 2], a) / v[:, 2]
    assert torch.allclose(vndf.float(), d.pdf(V, M).torch().float(), rtol=1e-4)
