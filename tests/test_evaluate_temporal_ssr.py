"""Frames of SSR methods, raw and accumulated: the resolve cuts flicker, and ghosting responds to a resolve that
keeps stale reflections under a turning camera and a moving reflected object."""
import math

import pytest
import torch

from ssbench.evaluate import ssr_frames
from ssbench.metrics import luminance
from ssbench.passes.temporal import AccumulationParams
from ssbench.scenes.motion import Motion

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
KW = dict(width=64, height=48, frames=6)
LOOSE = AccumulationParams(alpha=0.05, clamp="none", depth_tolerance=10.0)


@pytest.mark.parametrize("method", ["dda", "glossy_stochastic"])
def test_accumulation_cuts_the_flicker_of_reflections(method):
    run = ssr_frames("glossy_ramp", method, accumulation=AccumulationParams(), **KW)
    assert run.color.shape == run.accumulated.shape == (6, 1, 3, 48, 64)
    assert run.flicker > 0 and run.flicker_accumulated < 0.7 * run.flicker, (run.flicker, run.flicker_accumulated)
    assert bool(run.mask.any()) and not bool(run.history_valid[0].any())
    assert math.isnan(run.ghosting)                                   # no truth asked for


def test_ghosting_of_reflections_responds_to_stale_history():
    """A turning camera moves reflections with their own parallax, not the floor's: a loose resolve must add
    more error than the default, overall and near edges; so must it near a moving reflected sphere."""
    kw = {**KW, "truth_rays": 8}
    tight = ssr_frames("glossy_ramp", "dda", accumulation=AccumulationParams(), orbit_deg=1.5, **kw)
    loose = ssr_frames("glossy_ramp", "dda", accumulation=LOOSE, orbit_deg=1.5, **kw)
    assert loose.ghosting > tight.ghosting + 0.005 and loose.ghosting_edges > tight.ghosting_edges, \
        (tight.ghosting, loose.ghosting)
    m = Motion("metal_2", (0.0, 0.0, 0.06))
    tight = ssr_frames("glossy_ramp", "dda", accumulation=AccumulationParams(), moving=m, **kw)
    loose = ssr_frames("glossy_ramp", "dda", accumulation=LOOSE, moving=m, **kw)
    assert loose.ghosting_moving > tight.ghosting_moving + 0.002, (tight.ghosting_moving, loose.ghosting_moving)
    assert tight.truth.shape == tight.color.shape


def test_same_seed_same_bits_and_arguments_are_checked():
    a = ssr_frames("glossy_ramp", "glossy_stochastic", frames=2, width=32, height=24, seed=3)
    b = ssr_frames("glossy_ramp", "glossy_stochastic", frames=2, width=32, height=24, seed=3)
    assert torch.equal(a.color, b.color)
    assert luminance(torch.tensor([0.0, 1.0, 0.0]).view(1, 3, 1, 1)).item() == pytest.approx(0.7152)
    with pytest.raises(ValueError, match="truth_rays"):
        ssr_frames("glossy_ramp", "dda", truth_rays=4, **KW)
    with pytest.raises(ValueError, match="spp"):
        ssr_frames("glossy_ramp", "dda", spp=0, **KW)
    with pytest.raises(ValueError, match="frames"):
        ssr_frames("glossy_ramp", "dda", frames=1)
