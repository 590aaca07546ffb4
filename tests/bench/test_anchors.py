"""The Dr.Jit anchor of hemisphere SSAO counts exactly the samples the torch pass counts (same inputs, same float32
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
