"""Per-pixel ꟻLIP maps of the report."""
import numpy as np
import torch


def test_the_flip_map_is_the_map_whose_mean_is_the_rows_flip():
    """The report's per-pixel ꟻLIP image is ssbench.metrics.flip's map on magma: black where the images agree,
    bright where they differ, black background."""
    import matplotlib
    from ssbench.metrics import flip
    from ssbench.report.flip_maps import flip_rgb
    t = torch.full((1, 1, 12, 16), 0.8)
    p = t.clone()
    p[..., :, 8:] = 0.2                                                     # the right half is far too dark
    m = torch.ones_like(t, dtype=torch.bool)
    m[..., 0, 0] = False
    rgb = flip_rgb(p, t, m)
    _, fmap = flip(p, t, m, return_map=True)
    want = (matplotlib.colormaps["magma"](np.clip(fmap[0, 0].numpy(), 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)
    assert (rgb[1:, :] == want[1:, :]).all() and (rgb[0, 0] == 0).all()
    assert rgb[6, 2].sum() < rgb[6, 13].sum()                                # the difference is where it is
