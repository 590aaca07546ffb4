"""The masked march shared by the DDA and its supercover walk (:mod:`ssbench.passes.ssr.masked_march`): the working
set leaves the hit-only columns out, and reading them back for chosen rows gives the set-up's values."""
from __future__ import annotations

import dataclasses

import torch

from ssbench.passes.ssr.dda import DDASSRParams
from ssbench.passes.ssr.dda_march import MarchingRays
from ssbench.passes.ssr.dda_rays import dda_rays
from ssbench.passes.ssr.dda_supercover_walk import WALK_HIT_ONLY
from ssbench.passes.ssr.masked_march import HIT_ONLY, hit_rows, marching_fields
from tests.passes.ssr_scenes import room


def test_the_working_set_leaves_the_hit_only_columns_out_and_hit_rows_reads_them_back():
    g = room()
    set_up = dda_rays(g, DDASSRParams(pixel_stride=2.0), torch.zeros(1, 1, g.height, g.width, dtype=torch.float64))[0]
    for hit_only in (HIT_ONLY, WALK_HIT_ONLY):
        s = MarchingRays(**marching_fields(set_up, g.view_z.numel(), hit_only))
        assert all(getattr(s, f) is None for f in hit_only)
        assert torch.equal(s.permute32, set_up.permute.to(torch.int32)) and torch.equal(s.b_index, set_up.b)
        later = s.select(torch.arange(3, s.count, 5))                          # a compaction: the columns stay out
        assert all(getattr(later, f) is None for f in hit_only)
        rows = torch.tensor([0, 7, later.count - 1])
        h = hit_rows(later, rows, set_up, hit_only)
        at = later.i.index_select(0, rows)                                      # their rows in the set-up
        for f in dataclasses.fields(set_up):
            v = getattr(set_up, f.name)
            if isinstance(v, torch.Tensor):
                assert torch.equal(getattr(h, f.name), v.index_select(0, at)), f.name
