"""The shared picture conventions: grey AO, signed error on RdBu, magma magnitudes, class colours, sRGB colour."""
import numpy as np
import torch

from ssbench.pictures import ao_rgb, color_rgb, error_rgb, implicit_class_rgb, magma_rgb


def _px(*v):
    return torch.tensor(v, dtype=torch.float32).reshape(1, 1, 1, -1)


def test_ao_is_grey_levels_and_background_black():
    rgb = ao_rgb(_px(0.0, 0.5, 1.0, 2.0, 0.7), _px(1, 1, 1, 1, 0) > 0)
    assert rgb[0].tolist() == [[0] * 3, [128] * 3, [255] * 3, [255] * 3, [0] * 3]


def test_signed_error_is_red_below_white_at_zero_blue_above_and_saturates():
    rgb = error_rgb(_px(-0.5, 0.0, 0.5, 5.0), _px(1, 1, 1, 1) > 0, vmax=0.5).astype(int)[0]
    assert rgb[0, 0] > 100 and rgb[0, 2] < 60                  # too dark: red
    assert rgb[1].min() > 230                                   # exact: (near) white
    assert rgb[2, 2] > 60 and rgb[2, 0] < 20                    # too bright: blue
    assert rgb[3].tolist() == rgb[2].tolist()                   # beyond vmax: saturated


def test_magma_scales_by_vmax_and_nan_is_zero():
    rgb = magma_rgb(_px(0.0, 1.0, 2.0, float("nan")), _px(1, 1, 1, 1) > 0, vmax=1.0)[0]
    assert rgb[1].tolist() == rgb[2].tolist() and rgb[3].tolist() == rgb[0].tolist()
    assert rgb[1].sum() > rgb[0].sum()


def test_implicit_classes_take_their_declared_colours():
    from ssbench.metrics.implicit import CLASS_COLORS
    codes = sorted(CLASS_COLORS)
    rgb = implicit_class_rgb(torch.tensor(codes, dtype=torch.int8).reshape(1, 1, 1, -1))[0]
    want = (np.array([CLASS_COLORS[c] for c in codes]) * 255 + 0.5).astype(np.uint8)
    assert rgb.tolist() == want.tolist() and len({tuple(c) for c in want.tolist()}) == len(codes)


def test_colour_is_srgb_encoded_and_clamped():
    c = torch.tensor([0.0, 0.214, 1.0]).reshape(1, 3, 1, 1).expand(1, 3, 1, 2).clone()
    c[0, :, 0, 1] = torch.tensor([-1.0, 4.0, float("nan")])
    rgb = color_rgb(c, torch.tensor([[[[True, False]]]]))
    assert rgb[0, 1].tolist() == [0, 255, 0]                                      # clamped; NaN is 0
    assert rgb[0, 0, 0] == 0 and 120 < rgb[0, 0, 1] < 135 and rgb[0, 0, 2] == 255   # linear 0.214 ≈ sRGB 0.5
