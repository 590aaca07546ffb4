"""The SSR section's pictures as ``(H, W, 3)`` uint8 arrays: colour (linear → sRGB), magma error maps, the error
map that greys what the pass cannot be blamed for, and log-scale visit counts. Re-exported by
:mod:`ssbench.report.ssr_section`.
"""
from __future__ import annotations

from typing import Optional

import numpy as np
import torch

__all__ = ["color_rgb", "magma_rgb", "scored_error_rgb", "visits_rgb", "UNSCORED_GREY", "NOT_REFLECTIVE_GREY"]


def _hw(x: torch.Tensor) -> np.ndarray:
    return x.detach().float().cpu().reshape(x.shape[-2], x.shape[-1]).numpy()


def color_rgb(color: torch.Tensor, mask: Optional[torch.Tensor] = None) -> np.ndarray:
    """``(H, W, 3)`` uint8 linear RGB → sRGB (background black when ``mask`` is given)."""
    from ..io import preview_rgb
    return preview_rgb("color", color[0], mask=None if mask is None else mask[0])


def magma_rgb(x: torch.Tensor, mask: torch.Tensor, vmax: float) -> np.ndarray:
    """``(H, W, 3)`` uint8 ``x / vmax`` on magma, background black."""
    import matplotlib
    v, m = np.nan_to_num(_hw(x)), _hw(mask) > 0.5
    rgb = matplotlib.colormaps["magma"](np.clip(v / vmax, 0, 1))[..., :3]
    return (np.where(m[..., None], rgb, 0.0) * 255 + 0.5).astype(np.uint8)


#: grey of the error maps' unscored pixels (no on-screen target, and the pass rightly returned nothing)
UNSCORED_GREY = 0.35
#: light grey of the error maps' pixels that cast no mirror ray (not reflective)
NOT_REFLECTIVE_GREY = 0.85


def scored_error_rgb(err: torch.Tensor, classes: torch.Tensor, mask: torch.Tensor, vmax: float) -> np.ndarray:
    """``(H, W, 3)`` uint8 error map that shows only what a screen-space pass can be blamed for: ``err`` on magma
    where the target is on screen (hit or missed) or where the pass returned a colour anyway (false, misplaced,
    punch-through and unfixable-target hits); :data:`UNSCORED_GREY` where the target is sky, off screen,
    occluded or a back face and the pass returned nothing (a true miss is no error); :data:`NOT_REFLECTIVE_GREY`
    where no mirror ray is cast; background black."""
    from ..metrics import ssr as M
    rgb = magma_rgb(err, mask, vmax)
    m = _hw(mask) > 0.5
    for codes, grey in (((M.TRUE_MISS, *M.UNFIXABLE), UNSCORED_GREY), ((M.NOT_REFLECTIVE,), NOT_REFLECTIVE_GREY)):
        sel = torch.zeros_like(classes, dtype=torch.bool)
        for c in codes:
            sel |= classes == c
        q = (_hw(sel.float()) > 0.5) & m
        rgb = np.where(q[..., None], np.uint8(grey * 255 + 0.5), rgb)
    return rgb


def visits_rgb(visits: torch.Tensor) -> tuple[np.ndarray, int]:
    """``(H, W, 3)`` uint8 visit counts on viridis over ``log(1 + n)`` (0 visits black) and the max count."""
    import matplotlib
    v = np.nan_to_num(_hw(visits.float()))
    top = float(v.max()) if v.size else 0.0
    t = np.log1p(v) / np.log1p(top) if top > 0 else np.zeros_like(v)
    rgb = matplotlib.colormaps["viridis"](t)[..., :3]
    return (np.where((v > 0)[..., None], rgb, 0.0) * 255 + 0.5).astype(np.uint8), int(top)
