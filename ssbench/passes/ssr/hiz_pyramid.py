"""The hierarchical depth buffer (Hi-Z) the Hi-Z SSR march (:mod:`.hiz`) climbs: a closest-depth pyramid.

**Depth as infinite reversed Z.** Each texel stores ``rz = near / (−z)`` (1 at the near plane, → 0 at infinity,
0 on the background). ``rz`` is ``near · k`` with McGuire & Mara's ``k = 1/w``, which is linear in screen space
along a projected ray (SSR article, appendix A), so a ray in ``(px, py, rz)`` is a straight line — the property
the traversal needs, exactly as FidelityFX SSSR relies on for hyperbolic depth. Reversed Z keeps float32
precision far away (one reason HDRP stores it). The closest surface is then the *largest* ``rz``: the pyramid is
a max pyramid (FidelityFX's min pyramid of standard depth, mirrored).

**Cells align with texels at every size.** Level ``m`` cell ``(cx, cy)`` holds the largest ``rz`` of the texels
``[cx·2^m, (cx + 1)·2^m) × [cy·2^m, (cy + 1)·2^m)`` that exist (``max_pool2d`` with ``ceil_mode``: a partial
cell on the right or bottom edge reads only real texels). FidelityFX addresses mip ``m`` in uv at resolution
``screen_size >> m``, which puts cell borders between texels when a side is not a power of two (the complaint
"only works for power-of-two resolutions" about Uludag's GPU Pro 5 method); traversing in pixels avoids it.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

__all__ = ["DepthPyramid", "reversed_depth", "depth_pyramid", "padded_levels"]


@dataclass(frozen=True)
class DepthPyramid:
    """A max pyramid of reversed depth, every level flattened into one buffer per image.

    Attributes:
        levels: level ``m`` as :math:`(B, 1, \\lceil H/2^m \\rceil, \\lceil W/2^m \\rceil)`, level 0 the
            full-resolution ``rz``; the last level is 1×1.
        flat: :math:`(B, T)` all levels concatenated, each row-major (what the march gathers from).
        offsets, widths: :math:`(L,)` long: where level ``m`` starts in ``flat`` and its width in cells.
    """

    levels: tuple
    flat: torch.Tensor
    offsets: torch.Tensor
    widths: torch.Tensor

    @property
    def count(self) -> int:
        """``L``, the number of levels."""
        return len(self.levels)

    def cell(self, b: torch.Tensor, level: torch.Tensor, cx: torch.Tensor, cy: torch.Tensor) -> torch.Tensor:
        """The values of cells ``(cx, cy)`` of per-element ``level`` in images ``b`` (all long, one shape)."""
        return self.flat[b, self.offsets[level] + cy * self.widths[level] + cx]


def reversed_depth(view_z: torch.Tensor, mask: torch.Tensor, near: float) -> torch.Tensor:
    """``rz = near / (−z)`` on ``mask``, 0 elsewhere (background never occludes), :math:`(B, 1, H, W)`.

    Example:
        >>> z = torch.tensor([[[[-0.5, -2.0, -100.0]]]])
        >>> reversed_depth(z, z > -100.0, 0.5).flatten().tolist()
        [1.0, 0.25, 0.0]
    """
    if view_z.dim() != 4 or view_z.shape[1] != 1:
        raise ValueError(f"view_z: expected shape (B, 1, H, W), got {tuple(view_z.shape)}")
    safe = torch.where(mask, -view_z, torch.ones_like(view_z)).clamp_min(torch.finfo(view_z.dtype).tiny)
    return torch.where(mask, near / safe, torch.zeros_like(view_z))


def depth_pyramid(rz: torch.Tensor) -> DepthPyramid:
    """The max pyramid of ``rz`` :math:`(B, 1, H, W)`, halved (rounding up) until 1×1.

    Example:
        >>> p = depth_pyramid(torch.tensor([[[[0.1, 0.5, 0.2], [0.3, 0.0, 0.9]]]]))
        >>> [tuple(level.shape[-2:]) for level in p.levels], p.levels[1].flatten().tolist()
        ([(2, 3), (1, 2), (1, 1)], [0.5, 0.8999999761581421])
    """
    if rz.dim() != 4 or rz.shape[1] != 1:
        raise ValueError(f"rz: expected shape (B, 1, H, W), got {tuple(rz.shape)}")
    levels = [rz]
    while levels[-1].shape[-1] > 1 or levels[-1].shape[-2] > 1:
        levels.append(F.max_pool2d(levels[-1], 2, 2, ceil_mode=True))
    B = rz.shape[0]
    sizes = [lv.shape[-1] * lv.shape[-2] for lv in levels]
    offsets = torch.tensor([0] + sizes[:-1], device=rz.device).cumsum(0)
    widths = torch.tensor([lv.shape[-1] for lv in levels], device=rz.device)
    return DepthPyramid(levels=tuple(levels), flat=torch.cat([lv.reshape(B, -1) for lv in levels], 1),
                        offsets=offsets, widths=widths)


def padded_levels(pyr: DepthPyramid, count: int) -> torch.Tensor:
    """Levels ``0 … count − 1`` of ``pyr`` flat, each cell at an index computed without a table: level 0 as
    :math:`(B, H, W)`, then levels ``1 … count − 1`` as :math:`(B, count − 1, ⌈H/2⌉, ⌈W/2⌉)`, level ``m`` in the
    top-left corner of block ``m − 1`` (zeros, background, around it): ``(2.5 + …)·HW`` values, where a full-size
    layer per level would take ``count·HW``. Level ``m``'s cell ``(cx, cy)`` of image ``b`` is at ``(b·H + cy)·W
    + cx`` for ``m = 0``, else ``B·H·W + ((b·(count − 1) + m − 1)·⌈H/2⌉ + cy)·⌈W/2⌉ + cx``.

    Example:
        >>> p = depth_pyramid(torch.tensor([[[[0.1, 0.5, 0.2], [0.3, 0.0, 0.9]]]]))
        >>> [round(v, 1) for v in padded_levels(p, 2).tolist()]   # level 0 (2×3), then level 1 (1×2): a 1×2 block
        [0.1, 0.5, 0.2, 0.3, 0.0, 0.9, 0.5, 0.9]
    """
    if not 1 <= count <= pyr.count:
        raise ValueError(f"count: expected 1 to {pyr.count} levels, got {count}")
    base = pyr.levels[0]
    B, _, H, W = base.shape
    blocks = base.new_zeros(B, count - 1, (H + 1) // 2, (W + 1) // 2)
    for m, level in enumerate(pyr.levels[1:count]):
        blocks[:, m, :level.shape[-2], :level.shape[-1]] = level[:, 0]
    return torch.cat([base.reshape(-1), blocks.reshape(-1)])
