"""Calibration of the halo metric on real scenes: the range check is the knob that paints a dark halo.

SSAO's ``max_distance`` (seed 002, the range check) is the largest depth difference a sample may count as an
occluder: raising it counts occluders ever farther in front, so false occlusion spreads behind foreground
edges. ``halo_dark`` must rise with it (non-decreasing, and clearly overall) on every scene the issue names,
while the old band MAE, which adds dark halo and missing occlusion, need not.
"""
import pytest

from ssbench.evaluate import run_ao

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]

KNOB = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05)


@pytest.mark.parametrize("scene", ["fence", "sphere_on_plane", "cornell_box"])
def test_dark_halo_rises_with_the_range_check(scene):
    refs, g, dark = {}, None, []
    for md in KNOB:
        ev = run_ao(scene, "ssao", {"max_distance": md}, width=96, height=72, rays=64, repeats=1, warmup=False,
                    references=refs, gbuffer=g, flip=False, oracle=False)
        g = ev.gbuffer
        dark.append(ev.row["halo_dark_flavour"])
        assert ev.row["halo_dark_flavour"] + ev.row["halo_missing_flavour"] == pytest.approx(
            ev.row["halo_band_flavour"], abs=1e-6)
    assert all(b >= a - 1e-9 for a, b in zip(dark, dark[1:])), dark
    assert dark[-1] >= 3 * max(dark[0], 1e-4), dark
