"""False-colour pictures of the passes' outputs as ``(H, W, 3)`` uint8 arrays, one convention each: grey AO, signed
AO error on ``RdBu``, linear colour → sRGB, magnitudes on ``magma``, the SSR error map that greys what a pass cannot
be blamed for, and the implicit casters' class map. The report's sections, the CLI and the sweeps' per-configuration
images (:mod:`ssbench.bench.pictures`) all draw with these, so a picture means the same wherever it appears.

Example:
    >>> import torch
    >>> ao_rgb(torch.full((1, 1, 2, 3), 0.5), torch.ones(1, 1, 2, 3, dtype=torch.bool)).shape
    (2, 3, 3)
"""
from __future__ import annotations

from typing import Optional

import numpy as np
import torch

__all__ = ["ao_rgb", "error_rgb", "color_rgb", "magma_rgb", "scored_error_rgb", "implicit_class_rgb",
           "implicit_color_rgb", "UNSCORED_GREY", "NOT_REFLECTIVE_GREY"]

#: grey of the SSR error maps' unscored pixels (no on-screen target, and the pass rightly returned nothing)
UNSCORED_GREY = 0.35
#: light grey of the SSR error maps' pixels that cast no mirror ray (not reflective)
NOT_REFLECTIVE_GREY = 0.85


def _hw(x: torch.Tensor) -> np.ndarray:
    return x.detach().float().cpu().reshape(x.shape[-2], x.shape[-1]).numpy()


def _bytes(rgb: np.ndarray) -> np.ndarray:
    return (rgb * 255 + 0.5).astype(np.uint8)


def ao_rgb(ao: torch.Tensor, mask: torch.Tensor) -> np.ndarray:
    """``(H, W, 3)`` uint8 grey AO (values as display levels), background black."""
    a, m = np.clip(_hw(ao), 0, 1), _hw(mask) > 0.5
    return _bytes(np.repeat(np.where(m, a, 0.0)[..., None], 3, -1))


def error_rgb(err: torch.Tensor, mask: torch.Tensor, vmax: float = 0.5) -> np.ndarray:
    """``(H, W, 3)`` uint8 signed error on ``RdBu`` (red < 0 = too dark, blue > 0 = too bright, saturating at
    ±``vmax``), background black."""
    import matplotlib
    e, m = _hw(err), _hw(mask) > 0.5
    rgb = matplotlib.colormaps["RdBu"](np.clip(0.5 + np.nan_to_num(e) / (2 * vmax), 0, 1))[..., :3]
    return _bytes(np.where(m[..., None], rgb, 0.0))


def color_rgb(color: torch.Tensor, mask: Optional[torch.Tensor] = None) -> np.ndarray:
    """``(H, W, 3)`` uint8 linear RGB → sRGB of the first image of a batch, clamped to [0, 1]; every pixel as it is
    (``mask`` goes to :func:`ssbench.io.preview_rgb`, which does not blank colour: a pass's colour is already 0
    where it returns nothing)."""
    from .io import preview_rgb
    return preview_rgb("color", color[0], mask=None if mask is None else mask[0])


def magma_rgb(x: torch.Tensor, mask: torch.Tensor, vmax: float) -> np.ndarray:
    """``(H, W, 3)`` uint8 ``x / vmax`` on magma, background black."""
    import matplotlib
    v, m = np.nan_to_num(_hw(x)), _hw(mask) > 0.5
    rgb = matplotlib.colormaps["magma"](np.clip(v / vmax, 0, 1))[..., :3]
    return _bytes(np.where(m[..., None], rgb, 0.0))


def scored_error_rgb(err: torch.Tensor, classes: torch.Tensor, mask: torch.Tensor, vmax: float) -> np.ndarray:
    """``(H, W, 3)`` uint8 SSR error map that shows only what a screen-space pass can be blamed for: ``err`` on
    magma where the target is on screen (hit or missed) or where the pass returned a colour anyway (false,
    misplaced, punch-through and unfixable-target hits); :data:`UNSCORED_GREY` where the target is sky, off
    screen, occluded or a back face and the pass returned nothing (a true miss is no error);
    :data:`NOT_REFLECTIVE_GREY` where no mirror ray is cast; background black."""
    from .metrics import ssr as M
    rgb = magma_rgb(err, mask, vmax)
    m = _hw(mask) > 0.5
    for codes, grey in (((M.TRUE_MISS, *M.UNFIXABLE), UNSCORED_GREY), ((M.NOT_REFLECTIVE,), NOT_REFLECTIVE_GREY)):
        sel = torch.zeros_like(classes, dtype=torch.bool)
        for c in codes:
            sel |= classes == c
        q = (_hw(sel.float()) > 0.5) & m
        rgb = np.where(q[..., None], np.uint8(grey * 255 + 0.5), rgb)
    return rgb


def implicit_class_rgb(classes: torch.Tensor) -> np.ndarray:
    """``(H, W, 3)`` uint8 implicit-caster class map in the colours of
    :data:`ssbench.metrics.implicit.CLASS_COLORS` (hit, punch-through, false hit, ...)."""
    from .metrics.implicit import CLASS_COLORS
    c = _hw(classes).astype(np.int64)
    lut = np.zeros((max(CLASS_COLORS) + 1, 3))
    for code, rgb in CLASS_COLORS.items():
        lut[code] = rgb
    return _bytes(lut[c])


def implicit_color_rgb(result, camera, scene) -> np.ndarray:
    """``(H, W, 3)`` uint8 shaded hits of an implicit caster's ``result`` (the ``to_gbuffer`` colour under the
    ``scene``'s materials and lights, linear → sRGB; background black)."""
    from .passes.implicit.gbuffer import to_gbuffer
    g = to_gbuffer(result, None, camera, scene.materials, scene.lights)
    return color_rgb(g.color, g.mask)
