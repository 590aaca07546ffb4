"""Every artifact metric responds to its artifact: the calibration experiments of ssbench.analysis.calibration,
run on real scenes against Mitsuba ground truth, pinned."""
import pytest

from ssbench.analysis.calibration import (banding_response, flat_bias_response, flicker_response, ghosting_response,
                                          halo_response,
                                          noise_response, verdict)
from ssbench.analysis.calibration_hits import punch_through_response, ssr_response

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]


def test_banding_falls_with_the_kernel_size_and_the_rotation_breaks_it_up():
    off, on = banding_response("sphere_on_plane")       # 160x120, radius 1.5, vs the oracle, 256 draws pooled
    assert off.x == on.x == (4, 8, 16, 32, 64) and off.reps == 256
    for r in (off, on):
        assert verdict(r)["monotone"], (r.series, r.y)                    # strictly, not within an error bar
    v = verdict(off)
    assert v["ratio"] >= 3 and v["ratio_err"] < 0.15, (off.y, off.err)   # measured 3.17 ± 0.09
    assert verdict(on)["ratio"] >= 2.5, on.y
    assert all(b < a for a, b in zip(off.y, on.y)), (off.y, on.y)         # rotation on: lower at every K


@pytest.mark.parametrize("scene", ["fence", "sphere_on_plane", "cornell_box"])
def test_dark_halo_rises_with_the_range_check(scene):
    dark, missing = halo_response((scene,))
    assert verdict(dark, 1e-9)["monotone"], dark.y
    assert dark.y[-1] >= 3 * max(dark.y[0], 1e-4), dark.y
    assert missing.y[-1] < missing.y[0]                                   # the range check trades one for the other


def test_flicker_falls_with_the_sample_count_and_is_zero_when_nothing_moves():
    for r in flicker_response("sphere_on_plane"):                        # SSAO kernel size, GTAO quality
        v = verdict(r)
        assert v["monotone"] and v["ratio"] >= 2.5, (r.series, r.y)
        assert "noise frozen and no jitter 0," in r.note                   # exactly 0: nothing moves


def test_ghosting_falls_as_the_resolve_keeps_less_history():
    """On an orbiting camera, ghosting against each frame's truth falls as the blend weight α grows, with and
    without the clamp and depth rejection; the stale-history resolve ghosts more at every α."""
    stale, default = ghosting_response(width=48, height=36, frames=6, truth_rays=16)
    for r in (stale, default):
        assert verdict(r, 1e-9)["monotone"], (r.series, r.y)
        assert r.y[0] > 2 * abs(r.y[-1]), (r.series, r.y)
    assert all(a >= b for a, b in zip(stale.y, default.y)), (stale.y, default.y)


def test_ssr_classes_respond_to_thickness_and_stride():
    false_hits, missed, misplaced = ssr_response("fence")
    for r in (false_hits, missed, misplaced):
        assert verdict(r)["monotone"], (r.series, r.y)
    assert false_hits.y[-1] > 0.05 > 10 * false_hits.y[0]                # too thick invents hits
    assert missed.y[0] > 0.3 > 10 * missed.y[-1]                         # too thin misses them
    assert misplaced.y[-1] > 10 * misplaced.y[0]                         # coarse strides land pixels off


def test_punch_through_falls_with_the_step_count():
    (r,) = punch_through_response("thin_shell")
    assert verdict(r)["monotone"] and r.y[0] > 2 * r.y[-1], r.y


def test_flat_bias_falls_with_the_self_occlusion_bias_and_noise_with_the_samples():
    (flat,) = flat_bias_response("grazing_floor")
    assert verdict(flat)["monotone"] and flat.y[0] > 0.05 > 100 * flat.y[-1], flat.y
    (noise,) = noise_response("grazing_floor")
    assert verdict(noise)["monotone"] and verdict(noise)["ratio"] >= 3, noise.y
