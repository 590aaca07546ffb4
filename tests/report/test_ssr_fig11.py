"""The report's one-ray visit figure (SSR article Fig. 11) on an analytic mirror floor (no Mitsuba)."""
from __future__ import annotations

import matplotlib.image as mimage
import torch

from ssbench.passes.ssr.dda import DDASSRParams, ssr_dda
from ssbench.passes.ssr.visits import crossed_pixels
from ssbench.report import ssr_fig11 as F
from tests.passes.ssr_scenes import room


def test_one_ray_counts_and_figure(tmp_path):
    g = room(96, 72)
    res = ssr_dda(g, DDASSRParams(max_ray_distance=50.0))
    pixel = F.pick_pixel(g, res)
    assert pixel is not None and pixel[1] >= 48 and bool(res.hit[0, 0, pixel[1], pixel[0]])
    rays = {r["method"]: r for r in F.one_ray(g, pixel)}
    lin, dda, sc = rays["linear"], rays["dda"], rays["dda_supercover"]
    # the supercover reads every crossed pixel once; the DDA one per line, skipping clipped corners
    assert sc["twice"] == sc["skipped"] == sc["outside"] == 0 and sc["reads"] == sc["pixels"] >= 20
    assert dda["twice"] == dda["outside"] == 0 and dda["reads"] == dda["pixels"] <= sc["reads"]
    # the counts are what the maps say, against an independent traversal of the same segment
    x, y = pixel
    crossed = crossed_pixels(sc["p0"], sc["end"], g.height, g.width)
    crossed[y, x] = False
    assert torch.equal(sc["visits"].bool(), crossed)
    # the linear march with the DDA's reads as equal view-space steps oversamples and skips (Fig. 11, left)
    assert lin["reads"] >= 0.9 * dda["reads"] and lin["twice"] > 0 and lin["skipped"] > 0
    F.plot(str(tmp_path / "fig11.png"), list(rays.values()), pixel)
    assert mimage.imread(str(tmp_path / "fig11.png")).shape[2] in (3, 4)


def test_pick_pixel_none_without_hits():
    import dataclasses

    from ssbench.passes.ssr.common import MAX_DISTANCE
    g = room(32, 24)
    res = ssr_dda(g, DDASSRParams(max_ray_distance=50.0))
    assert F.pick_pixel(g, res) is not None
    none = dataclasses.replace(res, termination=torch.full_like(res.termination, MAX_DISTANCE))
    assert F.pick_pixel(g, none) is None
