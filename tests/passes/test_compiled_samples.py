"""Sample layouts, groups and bands of the AO band kernels, eager and compiled (ssbench/passes/compiled_samples.py)."""
from __future__ import annotations

import pytest
import torch

import ssbench.passes.compiled as C
import ssbench.passes.compiled_samples as S


def test_sample_groups_are_all_samples_eager_and_groups_of_their_own_compiled():
    samples = torch.arange(60.0).reshape(20, 3)
    with C.compiling(False):
        (whole,) = S.sample_groups(samples)
        assert whole is samples
    with C.compiling(True):
        groups = S.sample_groups(samples)
    assert [g.shape[0] for g in groups] == [S.SAMPLES_PER_CALL] * 2 + [20 - 2 * S.SAMPLES_PER_CALL]
    assert torch.equal(torch.cat(groups), samples)
    assert all(g.storage_offset() == 0 and g.is_contiguous() for g in groups)   # no offsets to compile again for


def test_a_counting_kernel_counts_one_block_eager_and_each_sample_alone_compiled():
    from ssbench.passes.ao.ssao_common import range_check_count
    from tests.passes.ssr_scenes import room

    @C.kernel
    def count(cam, pts, real_depth, total):          # the same sample points, counted in sample_blocks()
        blocks = S.sample_blocks(pts[0].shape[2])
        for ks in blocks:
            total = total + range_check_count(cam, tuple(t[:, :, ks] for t in pts), real_depth, 0.0005, 0.02, 2)
        return len(blocks), total

    g = room(24, 18, torch.float32, slat=True)
    pts = tuple(torch.randn(1, 1, 5, 18, 24, generator=torch.Generator().manual_seed(c)) - (2.0 if c == 2 else 0.0)
                for c in range(3))
    real_depth = g.camera.view_z_to_orthographic_depth(g.view_z)
    zero = torch.zeros(1, 1, 18, 24, dtype=torch.int64)
    with C.compiling(False):
        blocks_e, n_e = count(g.camera, pts, real_depth, zero)
    with C.compiling(True):
        blocks_c, n_c = count(g.camera, pts, real_depth, zero)
    assert (blocks_e, blocks_c) == (1, 5) and n_e.shape == n_c.shape == (1, 1, 18, 24)
    assert torch.equal(n_e, n_c) and 0 < int(n_e.sum()) < 5 * 18 * 24          # the same counts, some counted


@pytest.mark.slow
@pytest.mark.parametrize("kernel_size, dtype", [(12, torch.float32), (20, torch.float64)])
def test_hemisphere_ssao_counts_uneven_sample_groups_compiled_as_eager(kernel_size, dtype):
    """Compiled, hemisphere SSAO counts its samples in groups of SAMPLES_PER_CALL (the last one shorter) on one
    band; eager all at once on cache-sized bands: the same AO and counts, on a batch of two images."""
    from ssbench.gbuffer import GBuffer
    from ssbench.passes.ao.ssao import HemisphereSSAOParams, hemisphere_ssao
    from tests.passes.ssr_scenes import room
    one = room(24, 18, dtype, slat=True)
    g = GBuffer(one.camera, **{f: torch.cat([getattr(one, f), getattr(one, f).flip(-2)])
                               for f in ("view_z", "normal", "mask")})
    p = HemisphereSSAOParams(kernel_size=kernel_size, seed=3)
    with C.compiling(True):
        assert len(S.sample_groups(torch.zeros(kernel_size, 3))) == -(-kernel_size // S.SAMPLES_PER_CALL) > 1
        comp = hemisphere_ssao(g, p, debug=True)
    with C.compiling(False):
        eager = hemisphere_ssao(g, p, debug=True)
    assert torch.equal(eager.ao, comp.ao) and torch.equal(eager.debug["samples"], comp.debug["samples"])
    assert 0 < float(eager.ao.mean()) < 1 and not torch.equal(eager.ao[0], eager.ao[1])


def test_a_band_kernel_lays_its_samples_on_axis_2_eager_and_last_compiled():
    from ssbench.passes.ao.ssao_common import kernel_components, range_check_count
    from tests.passes.ssr_scenes import room

    @C.kernel
    def count(cam, pts, real_depth):             # the same sample points, laid out along sample_axis()
        axis = S.sample_axis()
        laid = tuple(t.movedim(2, -1) if axis == -1 else t for t in pts)
        return axis, range_check_count(cam, laid, real_depth, 0.0005, 0.02, axis)

    g = room(24, 18, torch.float32, slat=True)
    pts = tuple(torch.randn(1, 1, 5, 18, 24, generator=torch.Generator().manual_seed(c)) - (2.0 if c == 2 else 0.0)
                for c in range(3))
    real_depth = g.camera.view_z_to_orthographic_depth(g.view_z)
    with C.compiling(False):
        axis_e, n_e = count(g.camera, pts, real_depth)
    with C.compiling(True):
        axis_c, n_c = count(g.camera, pts, real_depth)
    assert (axis_e, axis_c) == (2, -1) and n_e.shape == n_c.shape == (1, 1, 18, 24)
    assert torch.equal(n_e, n_c) and 0 < int(n_e.sum()) < 5 * 18 * 24          # the same counts, some counted
    k = torch.arange(12.0).reshape(4, 3)
    assert [c.shape for c in kernel_components(k, -1)] == [(1, 1, 1, 1, 4)] * 3
    assert torch.equal(kernel_components(k, 2)[1].flatten(), k[:, 1])
