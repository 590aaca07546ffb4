"""The depth samples of a GTAO slice, shared by GTAO (:mod:`ssbench.passes.ao.gtao_slices`) and the visibility
bitmask (:mod:`ssbench.passes.ao.vbao_slices`): the view-space position of every texel of the depth texture, and
the offset from a pixel to the texels its slice steps land on (Jimenez et al. 2016, "Practical Realtime Strategies
for Accurate Indirect Occlusion", Algorithm 1, lines 17–22; Intel's XeGTAO, ``XeGTAO_ComputeViewspacePosition``).

A sample's view-space position is a function of its texel alone (the pixel centre's ray times the texel's depth), so
eager, :func:`position_texture` computes it once per texel, before the march, and a sample reads its three
coordinates where XeGTAO reads a depth and rebuilds the position from the sample's screen coordinates: the same
operations on the same values, so the same bits, for less arithmetic per sample (three texel reads instead of one
and eight operations). Compiled, the samples read the depth alone (:func:`sample_texture`): inductor fuses the
rebuilt position into its loop for less than the two more texel reads (VBAO took 1.24× the time reading positions).
"""
from __future__ import annotations

import torch

from ..common import fetch_texels
from ..compiled import enabled
from ..float_masks import float_masks, inside_image

__all__ = ["pixel_rays", "position_texture", "sample_texture", "slice_offsets"]


def pixel_rays(cam, col: torch.Tensor, row: torch.Tensor, height: int, width: int) -> tuple[torch.Tensor, torch.Tensor]:
    """View x and y at ``z = −1`` of the rays through the centres of pixels ``col``, ``row`` (integer-valued floats,
    row 0 at the top; the camera's ``uv_to_view`` with ``v`` up): ``((2(c + ½)/W − 1)·aspect/focal,
    (1 − 2(r + ½)/H)/focal)``."""
    return ((2.0 * (col + 0.5) / width - 1.0) * cam.aspect / cam.focal,
            (1.0 - 2.0 * (row + 0.5) / height) / cam.focal)


def position_texture(cam, z: torch.Tensor) -> torch.Tensor:
    """The view-space position of every texel of the depth texture ``z`` :math:`(B, 1, H, W)` (view z, negative in
    front of the camera): :math:`(B, 3, H, W)` ``(x·−z, y·−z, z)`` with ``(x, y)`` the texel centre's
    :func:`pixel_rays`.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, 2, 2, 0.1, 10.0)
        >>> position_texture(cam, torch.full((1, 1, 2, 2), -2.0))[0, :, 0, 0].tolist()   # top left: x < 0, y > 0
        [-1.0, 1.0, -2.0]
    """
    B, _, H, W = z.shape
    col = torch.arange(W, dtype=z.dtype, device=z.device).view(1, 1, 1, W)
    row = torch.arange(H, dtype=z.dtype, device=z.device).view(1, 1, H, 1)
    x, y = pixel_rays(cam, col, row, H, W)
    return torch.cat([x * -z, y * -z, z], 1)


def sample_texture(cam, z: torch.Tensor) -> torch.Tensor:
    """What :func:`slice_offsets` reads from: the :func:`position_texture` of ``z`` :math:`(B, 1, H, W)`, or ``z``
    itself while the passes run compiled (:func:`ssbench.passes.compiled.enabled`) or gradients are on (a pass that
    a parameter's gradient runs through keeps the rebuilt position's path: a rounded offset's gradient is 0, not
    absent, so ``ssbench tune`` still calls such a parameter piecewise constant). Its last channel is ``z``."""
    return z if enabled() or torch.is_grad_enabled() else position_texture(cam, z)


def slice_offsets(cam, tex: torch.Tensor, col: torch.Tensor, row: torch.Tensor, off_x: torch.Tensor,
                  off_y: torch.Tensor, P: tuple) -> tuple[tuple, torch.Tensor]:
    """``(S − P, on)`` of the samples at pixel offsets ``±(off_x, off_y)`` from each pixel of a band: both sides of a
    slice, ``K`` steps each.

    Args:
        cam: the camera (its rays, for a depth-only ``tex``).
        tex: :math:`(B, 3, H, W)` the :func:`position_texture` of the whole depth texture, or :math:`(B, 1, H, W)`
            the depth texture itself (:func:`sample_texture`); the same offsets from either.
        col, row: the band's pixel columns :math:`(1, 1, 1, W)` and rows :math:`(1, 1, h, 1)` (integer-valued floats).
        off_x, off_y: :math:`(B, K, h, W)` the steps' rounded screen offsets (pixels, ``y`` down).
        P: ``(x, y, z)`` of :math:`(B, 1, h, W)`, the pixel's own view-space position.

    Returns:
        ``((dx, dy, dz), on)``: the offsets from ``P`` to the sampled texels' positions, :math:`(B, 2K, h, W)` each
        (the ``+`` side first), and ``on`` :math:`(B, 2K, h, W)`, false where a sample left the screen: bool, or 0/1
        in the offsets' dtype in :mod:`~ssbench.passes.float_masks`' form (on the CPU several times faster). Such a
        sample reads the pixel's own texel (its callers weight it 0); so does one whose offset overflowed or is NaN.
    """
    H, W = tex.shape[-2], tex.shape[-1]
    if float_masks(off_x):              # a non-finite offset as a finite one off screen: `on` below reads it as such
        big = float(H + W)
        off_x, off_y = (torch.nan_to_num(o, nan=big, posinf=big, neginf=-big) for o in (off_x, off_y))
    off_x, off_y = torch.cat([off_x, -off_x], 1), torch.cat([off_y, -off_y], 1)        # (B, 2K, h, W)
    cx, cy = col + off_x, row + off_y
    on = inside_image(cx, cy, W, H)
    # integer-valued and inside the image where `on`, the pixel's own texel elsewhere: no clamp needed
    if on.dtype == torch.bool:
        cx, cy = torch.where(on, cx, col), torch.where(on, cy, row)
    else:                                # col + 1·off (exact: integers) or col + 0·off (finite off: col itself)
        cx, cy = torch.addcmul(col, on, off_x), torch.addcmul(row, on, off_y)
    S = fetch_texels(tex, cx, cy)                                                      # (B, C, 2K, h, W)
    if tex.shape[1] == 3:
        return (S[:, 0] - P[0], S[:, 1] - P[1], S[:, 2] - P[2]), on
    zs = S[:, 0]
    ray_x, ray_y = pixel_rays(cam, cx, cy, H, W)
    return (ray_x * -zs - P[0], ray_y * -zs - P[1], zs - P[2]), on
