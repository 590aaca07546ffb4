"""Per-pixel ꟻLIP maps for the report (Andersson et al., "ꟻLIP: A Difference Evaluator for Alternating Images",
HPG 2020, https://research.nvidia.com/publication/2020-07_flip): where a viewer flipping between a method's image
and the truth sees a difference, on ꟻLIP's own magma scale 0–1 — the scalar ``flip_*`` of a row is this map's
mean over the valid pixels."""
from __future__ import annotations

import numpy as np
import torch

__all__ = ["flip_rgb"]


def flip_rgb(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> np.ndarray:
    """``(H, W, 3)`` uint8 LDR-ꟻLIP map of ``pred`` against ``target`` (both :math:`(1, C, H, W)`, display
    values, as :func:`ssbench.metrics.flip`) on magma over [0, 1]; background (``mask`` False) black.

    Example:
        >>> t = torch.full((1, 1, 6, 8), 0.5)
        >>> m = torch.ones(1, 1, 6, 8, dtype=torch.bool)
        >>> int(flip_rgb(t, t, m)[2, 3].sum()) < 30 < int(flip_rgb(1 - t * 2, t, m)[2, 3].sum())   # no difference: black
        True
    """
    import matplotlib
    from ..metrics import flip
    _, fmap = flip(pred.float(), target.float(), mask, return_map=True)
    f = np.nan_to_num(fmap[0, 0].detach().cpu().numpy())
    m = mask[0, 0].detach().cpu().numpy().astype(bool)
    rgb = matplotlib.colormaps["magma"](np.clip(f, 0, 1))[..., :3]
    return (np.where(m[..., None], rgb, 0.0) * 255 + 0.5).astype(np.uint8)
