"""Bent-normal angle error: closed-form angles, masks, undefined pixels and the truth's error bar beside it."""
import math

import pytest
import torch

from ssbench.metrics.ao_bent import bent_normal_angle, bent_normal_error


def _field(*vectors):
    return torch.tensor(vectors, dtype=torch.float64).T.reshape(1, 3, 1, len(vectors))


def test_angles_are_the_closed_forms_and_scale_free():
    a = _field((0, 0, 1), (0, 0, 1), (0, 0, 1), (1, 0, 0))
    b = _field((0, 0, 3), (0, 1, 1), (0, 0, -1), (1, 1, 0))
    assert bent_normal_angle(a, b)[0, 0, 0].tolist() == pytest.approx([0.0, 45.0, 180.0, 45.0])
    assert math.isnan(bent_normal_angle(a, _field((0, 0, 0), (0, 0, 1), (0, 0, 1), (1, 0, 0)))[0, 0, 0, 0])


def test_error_summary_over_the_mask_and_defined_pixels():
    a = _field((0, 0, 1), (0, 0, 1), (0, 0, 1), (0, 0, 1))
    b = _field((0, 0, 1), (0, 1, 1), (0, 1, 0), (0, 0, 1))
    mask = torch.tensor([True, True, True, False]).view(1, 1, 1, 4)
    se = torch.tensor([1.0, 2.0, math.inf, 4.0]).view(1, 1, 1, 4)
    e = bent_normal_error(a, b, mask, se)                                  # the inf pixel has no truth
    assert e["pixels"] == 2 and e["mean_deg"] == pytest.approx(22.5) and e["truth_stderr_deg"] == pytest.approx(1.5)
    assert bent_normal_error(a, b, mask)["pixels"] == 3 and math.isnan(bent_normal_error(a, b, mask)["truth_stderr_deg"])
    with pytest.raises(ValueError, match="mask"):
        bent_normal_error(a, b, torch.zeros_like(mask))
    with pytest.raises(ValueError, match="pred"):
        bent_normal_angle(a[:, :2], b[:, :2])
