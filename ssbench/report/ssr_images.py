"""The SSR section's pictures: log-scale visit counts (colour, magma error maps and the error map that greys what
the pass cannot be blamed for live in :mod:`ssbench.pictures` and are re-exported here and by
:mod:`ssbench.report.ssr_section`).
"""
from __future__ import annotations


import numpy as np
import torch

from ..pictures import NOT_REFLECTIVE_GREY, UNSCORED_GREY, color_rgb, magma_rgb, scored_error_rgb

__all__ = ["color_rgb", "magma_rgb", "scored_error_rgb", "visits_rgb", "UNSCORED_GREY", "NOT_REFLECTIVE_GREY"]


def _hw(x: torch.Tensor) -> np.ndarray:
    return x.detach().float().cpu().reshape(x.shape[-2], x.shape[-1]).numpy()


def visits_rgb(visits: torch.Tensor) -> tuple[np.ndarray, int]:
    """``(H, W, 3)`` uint8 visit counts on viridis over ``log(1 + n)`` (0 visits black) and the max count."""
    import matplotlib
    v = np.nan_to_num(_hw(visits.float()))
    top = float(v.max()) if v.size else 0.0
    t = np.log1p(v) / np.log1p(top) if top > 0 else np.zeros_like(v)
    rgb = matplotlib.colormaps["viridis"](t)[..., :3]
    return (np.where((v > 0)[..., None], rgb, 0.0) * 255 + 0.5).astype(np.uint8), int(top)
