"""Visibility-bitmask AO: the sector bits, the cosine sector shares against GTAO's slice integral, thickness as the
only knob that hides the sky (monotone; infinite thickness is a horizon), the teaching twin equal to the pass,
and the flat-surface bias of the paper's ``ceil`` (measured, pinned)."""
import math

import pytest
import torch

from ssbench.passes.ao.gtao_parts import slice_visibility
from ssbench.passes.ao.vbao import VBAO, VBAOParams, vbao
from ssbench.passes.ao.vbao_slices import as_unsigned, cosine_arc, popcount, sector_bits

from .test_gtao import crease, open_plane, quad_with_background


def test_sector_bits_touch_every_sector_an_arc_reaches():
    lo, hi = torch.tensor([0.0, 0.15, 0.0, 0.5, 0.99]), torch.tensor([0.0, 0.30, 1.0, 0.5, 1.0])
    got = sector_bits(lo, hi, 10).tolist()
    assert got == [0, 0b110, 2 ** 10 - 1, 0, 0b1000000000]       # [0.15, 0.3]: ceil(1.5) = 2 sectors from 1
    assert popcount(torch.tensor(got)).tolist() == [0, 2, 10, 0, 1]
    every = sector_bits(torch.tensor([0.0, 31.5 / 32]), torch.tensor([1.0, 1.0]), 32)   # one uint, in int32
    assert every.dtype == torch.int32 and as_unsigned(every).tolist() == [2 ** 32 - 1, 2 ** 31]
    assert popcount(as_unsigned(every)).tolist() == [32, 1]


def test_sector_bits_in_int32_equal_the_int64_formula():
    """The int32 bits (sector 31 the sign bit, shifts by 32 giving 0) read as unsigned equal the plain int64
    formula, with its mask, on arcs that end anywhere, at every sector count up to 32."""
    g = torch.Generator().manual_seed(0)
    x = torch.rand(2, 4000, generator=g, dtype=torch.float64)
    x[:, :64] = torch.arange(64, dtype=torch.float64).view(1, -1) / 63        # edges and both ends exactly
    lo, hi = x.min(0).values, x.max(0).values
    for n in (1, 7, 31, 32):
        start = torch.floor(lo * n).long().clamp(0, n)
        count = torch.ceil((hi - lo) * n).long().clamp(0, n)
        expected = (((1 << count) - 1) << start) & ((1 << n) - 1)
        assert torch.equal(as_unsigned(sector_bits(lo, hi, n)), expected), n


def test_cosine_sector_shares_add_up_to_gtaos_slice_integral():
    n = torch.linspace(-1.4, 1.4, 15, dtype=torch.float64)
    for sectors in (1, 7, 32):
        edges = [cosine_arc(n - math.pi / 2 + math.pi * i / sectors, n) for i in range(sectors + 1)]
        shares = torch.stack([b - a for a, b in zip(edges, edges[1:])])
        assert bool((shares >= -1e-15).all())                                      # every sector a share >= 0
        whole = slice_visibility(n - math.pi / 2, n + math.pi / 2, n)
        assert torch.allclose(shares.sum(0), whole, atol=1e-14)


def test_a_wall_facing_the_camera_is_unoccluded_and_background_is_one():
    g = quad_with_background()
    r = vbao(g, VBAOParams(radius=1.0))
    assert bool((r.ao[~g.mask] == 1).all()) and bool(torch.isfinite(r.ao).all())


def test_thicker_samples_hide_more_and_infinite_thickness_is_a_horizon():
    g = crease(w=24, h=18)[0]
    aos = [vbao(g, VBAOParams(radius=1.0, thickness=t, noise="none")).ao for t in (0.01, 0.1, 1.0, 1e6)]
    for thin, thick in zip(aos, aos[1:]):   # UpdateSectors marks ceil(width·N) sectors from floor(lo·N): a longer
        assert float(thick[g.mask].mean()) < float(thin[g.mask].mean())            # arc can drop its last sector,
        assert float((thick <= thin)[g.mask].float().mean()) > 0.99               # so: on average, not everywhere
    assert float(aos[0][g.mask].mean()) > float(aos[-1][g.mask].mean()) + 0.02     # and it matters on a crease
    bits = vbao(g, VBAOParams(radius=1.0, thickness=1e6, noise="none"), debug=True).debug["bits"]
    N = 32                                  # every slice: one run from sector 0 and one into sector N-1, no hole
    low = popcount((bits ^ (bits + 1)) >> 1)                                      # trailing ones
    high = popcount(bits) - low
    run_high = ((1 << high) - 1) << (N - high)
    assert bool(((((1 << low) - 1) | run_high) == bits).all())


def test_teaching_twin_equals_vectorised():
    from ssbench.passes.teaching.vbao_basic import vbao_basic
    g = crease(w=16, h=12)[0]
    for kw in ({}, {"weighting": "cosine"}, {"noise": "hash", "thickness": 0.05},
               {"slices": 2, "steps": 3, "sector_count": 8, "sample_distribution_power": 2.0}):
        for gb in (g, quad_with_background()):
            p = VBAOParams(radius=1.0, **kw)
            a = vbao(gb, p, generator=torch.Generator().manual_seed(3)).ao
            b = vbao_basic(gb, p, generator=torch.Generator().manual_seed(3)).ao
            assert float((a - b).abs().max()) < 1e-12, (kw, float((a - b).abs().max()))
    assert float(vbao(g, VBAOParams(radius=1.0)).ao[g.mask].min()) < 0.8         # the crease: not trivial


def test_the_papers_ceil_darkens_an_open_plane_a_little():
    """Samples on the pixel's own plane sit at its tangent; float round-off puts some a hair inside the half
    circle and ``ceil`` then marks a whole sector (the paper's and Blender's rounding). Pinned so a change shows."""
    g = open_plane()
    uni = vbao(g, VBAOParams()).ao[g.mask]
    cos = vbao(g, VBAOParams(weighting="cosine")).ao[g.mask]
    assert 0.9 < float(uni.mean()) < 0.97 and 0.98 < float(cos.mean()) <= 1.0
    assert float(uni.min()) >= 1 - 4 / 32                                         # at most a sector per side


def test_module_dtype_and_bad_params():
    g = crease(w=12, h=9, dtype=torch.float32)[0]
    r = VBAO(thickness=0.1)(g)
    assert r.ao.dtype == torch.float32 and r.ao.shape == (1, 1, 9, 12)
    for bad in ({"sector_count": 33}, {"thickness": 0.0}, {"weighting": "obscurance"}, {"slices": 0},
                {"noise": "perlin"}, {"noise": [[0.5] * 3] * 4}, {"sample_distribution_power": 0.0}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            VBAOParams(**bad)
    with pytest.raises(TypeError, match="params"):
        vbao(g, object())


def test_bent_normals_lean_away_from_occluders_and_follow_the_normal_in_the_open():
    g, world = crease(w=32, h=24)
    r = vbao(g, VBAOParams(radius=1.0, thickness=1.0, weighting="cosine", noise="none"), bent_normals=True)
    assert torch.equal(r.ao, vbao(g, VBAOParams(radius=1.0, thickness=1.0, weighting="cosine", noise="none")).ao)
    m = g.mask[0, 0]
    assert torch.allclose(r.bent_normal.norm(dim=1)[0][m], torch.ones(()).double(), atol=1e-9)
    assert torch.all(r.bent_normal[:, :, ~m] == 0)
    bent_w = g.camera.view_to_world_dir(r.bent_normal[0])                 # (3, H, W) world
    floor = m & (world[1].abs() < 1e-6)
    near = floor & (world[2] < -0.6)                                       # within 0.4 of the wall (z = -1)
    far = floor & (world[2] > 0.5)
    assert near.sum() > 10 and far.sum() > 10
    assert float(bent_w[2][near].mean()) > 0.1                              # tilted away from the wall (+z)
    assert float(bent_w[2][near].mean()) > float(bent_w[2][far].mean()) + 0.05
    o = open_plane()
    ro = vbao(o, VBAOParams(weighting="cosine"), bent_normals=True)
    ang = torch.rad2deg(torch.acos((ro.bent_normal * o.normal).sum(1).clamp(-1, 1)))[o.mask[:, 0]]
    assert float(ang.mean()) < 5.0                                          # the open plane: its own normal
