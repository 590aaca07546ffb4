"""TXAA for the implicit casters: jittered frames resolved over time converge toward the supersampled image at
the silhouettes, and a depth test in the resolve (which the jitter trips at every silhouette) undoes it."""
import math

import pytest
import torch

from ssbench.evaluate import implicit_frames
from ssbench.evaluate._temporal_implicit import TXAA, supersampled_truth
from ssbench.passes.temporal import AccumulationParams

pytestmark = [pytest.mark.slow]
KW = dict(frames=16, width=48, height=36)


@pytest.mark.parametrize("method", ["sphere", "progressive"])
def test_txaa_converges_toward_the_supersampled_image(method):
    run = implicit_frames("torus", method, **KW)
    raw = sum(run.error_raw) / len(run.error_raw)
    late = sum(run.error_accumulated[-4:]) / 4
    assert late < 0.6 * raw, (raw, late)
    assert run.flicker_accumulated < 0.6 * run.flicker, (run.flicker, run.flicker_accumulated)
    assert run.color.shape == run.accumulated.shape == (16, 1, 3, 36, 48)
    assert len(set(run.offsets)) == 16 and all(-0.5 <= d < 0.5 for o in run.offsets for d in o)
    assert bool(run.silhouettes.any()) and float(run.silhouettes.float().mean()) < 0.3


def test_a_depth_test_in_the_resolve_drops_the_history_where_txaa_works():
    txaa = implicit_frames("torus", "sphere", **KW)
    rejecting = implicit_frames("torus", "sphere", accumulation=AccumulationParams(background=True), **KW)
    assert sum(rejecting.error_accumulated[-4:]) > 1.5 * sum(txaa.error_accumulated[-4:])


def test_the_truth_is_the_box_filter_of_the_reference():
    """Coverage is the hit share of the factor² sub-samples: 0 or 1 inside and outside, fractions on edges; the
    colour at factor 1 is the reference shaded at the pixel centres."""
    from ssbench.implicit.scene import load
    sc = load("torus")
    cam = sc.camera_at(0).with_resolution(24, 18)
    c4, cov4 = supersampled_truth(sc, cam, 4)
    c1, cov1 = supersampled_truth(sc, cam, 1)
    assert set(torch.unique(cov1).tolist()) <= {0.0, 1.0}
    frac = cov4[(cov4 > 0) & (cov4 < 1)]
    assert frac.numel() > 0 and bool(((frac * 16) - (frac * 16).round()).abs().max() < 1e-6)
    assert float((c4 - c1).abs().mean()) < 0.05 and c4.shape == (1, 3, 18, 24)


def test_arguments_are_checked():
    with pytest.raises(ValueError, match="frames"):
        implicit_frames("torus", "sphere", frames=1)
    with pytest.raises(ValueError, match="truth_factor"):
        implicit_frames("torus", "sphere", truth_factor=0)
    with pytest.raises(TypeError, match="accumulation"):
        implicit_frames("torus", "sphere", accumulation={"alpha": 0.1})
    with pytest.raises(ValueError, match="depth_tolerance"):
        AccumulationParams(depth_tolerance=-1.0)
    assert math.isinf(TXAA.depth_tolerance) and TXAA.background
