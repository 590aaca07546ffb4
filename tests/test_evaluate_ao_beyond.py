"""Bent normals and multi-bounce AO scored per method against their truths: GTAO's bent normal beats the shading
normal, the fit beats ignoring interreflection, methods without bent normals say so with NaN."""
import math

import pytest

from ssbench.evaluate import ao_beyond, has_bent_normals
from ssbench.passes import ao_method

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
KW = dict(width=80, height=60, rays=128)


def test_gtao_bent_normal_and_multibounce_fit_beat_their_baselines():
    r = ao_beyond("stairs", "gtao", **KW)
    assert r["has_bent_normals"] and r["bent_mean_deg"] < 0.85 * r["shading_normal_mean_deg"], r
    assert r["bent_p95_deg"] >= r["bent_median_deg"] > 0 and r["bent_truth_stderr_deg"] > 0
    assert r["fit_exact_rmse"] < 0.5 * r["single_bounce_rmse"], r
    assert r["multibounce_rmse"] < r["single_bounce_rmse"], r
    assert 0 < r["multibounce_truth_stderr"] < r["multibounce_rmse"]


def test_a_method_without_bent_normals_reports_nan_and_the_same_baselines():
    a, b = ao_beyond("stairs", "ssao", **KW), ao_beyond("stairs", "gtao", **KW)
    assert not a["has_bent_normals"] and math.isnan(a["bent_mean_deg"])
    assert a["shading_normal_mean_deg"] == b["shading_normal_mean_deg"]
    assert a["single_bounce_rmse"] == b["single_bounce_rmse"] and a["multibounce_rmse"] != b["multibounce_rmse"]
    assert has_bent_normals(ao_method("vbao")[0]) and not has_bent_normals(ao_method("hbao")[0])


def test_arguments_are_checked():
    with pytest.raises(ValueError, match="rays"):
        ao_beyond("stairs", "gtao", rays=1)
    with pytest.raises(ValueError, match="radius"):
        ao_beyond("stairs", "gtao", radius=-1.0)
