"""The Dr.Jit anchors: hemisphere SSAO counts exactly the samples the torch pass counts, and the linear SSR march ends,
counts steps and places hits exactly as the torch pass (same inputs, same float32
operations in the same order), for both ways of getting the view position, on a scene with real occlusion."""
import dataclasses

import pytest
import torch

from ssbench.bench.anchors import ssao_anchor
from ssbench.passes.ao.ssao import HemisphereSSAOParams, hemisphere_ssao


@pytest.mark.parametrize("position_from", ["depth", "view_z"])
def test_the_ssao_anchor_counts_what_the_torch_pass_counts(position_from):
    from tests.passes.ssr_scenes import room
    g = dataclasses.replace(room(40, 30, torch.float32, slat=True), color=None)
    p = HemisphereSSAOParams(kernel_size=16, position_from=position_from)
    call = ssao_anchor(g, p, generator=torch.Generator().manual_seed(5))
    if call is None:
        pytest.skip("no Dr.Jit LLVM backend on this machine")
    torch_pass = hemisphere_ssao(g, p, generator=torch.Generator().manual_seed(5), debug=True)
    count = torch.where(g.mask, call().long(), 0)
    assert torch.equal(count, torch_pass.debug["samples"].long())
    assert 0 < int(count.sum()) < 16 * int(g.mask.sum())                      # some samples occlude, not all
    other = ssao_anchor(g, p, generator=torch.Generator().manual_seed(6))()
    assert not torch.equal(torch.where(g.mask, other.long(), 0), count)        # the draws matter: a live check


@pytest.mark.parametrize("kw", [{}, {"jitter": 1.0, "position_from": "view_z"},
                                {"iterations": 200, "max_iterations": 40, "binary_search_iterations": 0}])
def test_the_linear_ssr_anchor_marches_what_the_torch_pass_marches(kw):
    from ssbench.bench.anchors import linear_ssr_anchor
    from ssbench.passes.ssr.common import HIT, OUT_OF_STEPS
    from ssbench.passes.ssr.linear import LinearSSRParams, ssr_linear
    from tests.passes.ssr_scenes import room
    g = room(48, 36, torch.float32, slat=True)
    p = LinearSSRParams(thickness=0.2, **kw)
    call = linear_ssr_anchor(g, p, generator=torch.Generator().manual_seed(2))
    if call is None:
        pytest.skip("no Dr.Jit LLVM backend on this machine")
    got, want = call(), ssr_linear(g, p, generator=torch.Generator().manual_seed(2))
    assert torch.equal(got["termination"], want.termination) and torch.equal(got["steps"], want.steps)
    assert torch.equal(got["hit_view"], want.hit_view)                      # bisection included, bit for bit
    hits = int((want.termination == HIT).sum())
    assert 0 < hits < int(g.mask.sum())                                     # some rays hit, not all
    assert ("max_iterations" in kw) == bool((want.termination == OUT_OF_STEPS).any())
    thin = linear_ssr_anchor(g, dataclasses.replace(p, thickness=0.01), generator=torch.Generator().manual_seed(2))()
    assert not torch.equal(thin["termination"], got["termination"])        # the thickness test is live


def test_the_linear_ssr_anchor_refuses_back_faces_and_float64():
    from ssbench.bench.anchors import linear_ssr_anchor
    from ssbench.passes.ssr.linear import LinearSSRParams
    from tests.passes.ssr_scenes import room
    with pytest.raises(ValueError, match="use_back_face_depth"):
        linear_ssr_anchor(room(8, 6, torch.float32), LinearSSRParams(use_back_face_depth=True))
    with pytest.raises(ValueError, match="float32"):
        linear_ssr_anchor(room(8, 6, torch.float64), LinearSSRParams())
