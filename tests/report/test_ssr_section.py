"""The SSR section's error map blames a pass only where it can be blamed (the rest of the section is exercised by
tests/report/test_build.py on a real report)."""
import numpy as np
import torch

from ssbench.metrics import ssr as M
from ssbench.report.ssr_images import NOT_REFLECTIVE_GREY, UNSCORED_GREY, magma_rgb, scored_error_rgb


def test_unreachable_targets_with_no_output_are_grey_and_everything_else_keeps_its_error():
    codes = [M.CORRECT, M.MISSED, M.FALSE_HIT, M.UNFIXABLE_HIT, M.TRUE_MISS, M.OFF_SCREEN_TARGET,
             M.OCCLUDED_TARGET, M.BACK_FACE_TARGET, M.NOT_REFLECTIVE, M.NOT_REFLECTIVE]
    classes = torch.tensor(codes, dtype=torch.int8).reshape(1, 1, 1, -1)
    err = torch.full(classes.shape, 0.5)                        # a missed sky pixel used to read as full error
    mask = torch.ones(classes.shape, dtype=torch.bool)
    mask[..., -1] = False
    rgb = scored_error_rgb(err, classes, mask, vmax=0.5)
    full = magma_rgb(err, mask, 0.5)
    grey = np.uint8(UNSCORED_GREY * 255 + 0.5)
    for j, c in enumerate(codes):
        if c in (M.TRUE_MISS, *M.UNFIXABLE):
            assert (rgb[0, j] == grey).all(), c
        elif c == M.NOT_REFLECTIVE and j < len(codes) - 1:
            assert (rgb[0, j] == np.uint8(NOT_REFLECTIVE_GREY * 255 + 0.5)).all()
        elif j < len(codes) - 1:
            assert (rgb[0, j] == full[0, j]).all() and not (rgb[0, j] == grey).all(), c
    assert (rgb[0, -1] == 0).all()                              # background stays black
