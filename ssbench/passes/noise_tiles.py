"""Per-pixel quantities that repeat with the noise texture: computed for one period of noise rows, not every pixel.

A pass that rotates (or reflects) its samples by a small tiled noise texture (``REPEAT``, 4×4 in the SSAO article
§1–2) and does nothing else per pixel to them — Crytek's sphere SSAO, whose ``reflect(Kernel[i], random)`` depends
on the sample and the noise texel alone — computes the same offsets for every pixel that reads the same texel.
Computed for one period of rows and broadcast down the band through a strided *view* (no copy), the sample points are
the same sums of the same values, so the same bits, and the offsets cost next to nothing per pixel.

:func:`rows_repeat` says whether the pixels' noise repeats every ``size`` rows (it does at pixel centres:
:func:`ssbench.passes.sampling.noise_texel`); :func:`tiled_add` adds the offsets of one period of rows to the
positions of a band as if they were repeated down it. Whole rows, not ``size``-wide tiles: a broadcast whose innermost
run is 4 columns long loops 4 values at a time (measured, eager Crytek at 640×360 side by side with per-pixel
offsets: 0.87× the time with 4×4 tiles, 0.78× with rows).
"""
from __future__ import annotations

import torch

__all__ = ["rows_repeat", "band_tile_rows", "tiled_add"]


def rows_repeat(noise: torch.Tensor, size: int) -> bool:
    """Whether the per-pixel noise :math:`(*, C, H, W)` repeats every ``size`` rows (checked on the values themselves,
    so any texel mapping that repeats qualifies). ``False`` for tensors without values (the ``meta`` device, on which
    a pass checks its shapes): every band then uses its own rows.

    Example:
        >>> tile = torch.arange(4.0).reshape(1, 1, 2, 2)
        >>> rows_repeat(tile.repeat(1, 1, 3, 1), 2), rows_repeat(tile.repeat(1, 1, 3, 1), 3)
        (True, False)
    """
    height = noise.shape[-2]
    if noise.device.type == "meta":
        return False
    return height <= size or torch.equal(noise[..., size:, :], noise[..., :height - size, :])


def band_tile_rows(rows: slice, size: int, periodic: bool) -> slice:
    """The rows of the noise that stand for a band of image ``rows`` in :func:`tiled_add`: the first period
    ``0:size`` when the noise repeats along rows (``periodic``) and the band starts on and spans whole periods,
    else the band's own rows (the tile is then the band).

    Example:
        >>> band_tile_rows(slice(8, 16), 4, True), band_tile_rows(slice(8, 10), 4, True)
        (slice(0, 4, None), slice(8, 10, None))
    """
    if periodic and rows.start % size == 0 and (rows.stop - rows.start) % size == 0:
        return slice(0, size)
    return rows


def tiled_add(position: torch.Tensor, offset: torch.Tensor, axis: int) -> torch.Tensor:
    """``position + offset`` for every sample, the rows of ``offset`` repeated down the band.

    Args:
        position: :math:`(B, 1, h, W)`, one component of the band's positions.
        offset: :math:`(K, t, W)`, that component of each sample's offset on ``t`` rows; ``t`` divides ``h``.
        axis: where the samples go (:func:`ssbench.passes.compiled_samples.sample_axis`): 2 gives
            :math:`(B, 1, K, h, W)`, -1 gives :math:`(B, 1, h, W, K)`.

    Example:
        >>> pos = torch.arange(4.0).reshape(1, 1, 4, 1)
        >>> tiled_add(pos, torch.tensor([[[0.0], [10.0]], [[100.0], [100.0]]]), 2)[0, 0, :, :, 0].tolist()
        [[0.0, 11.0, 2.0, 13.0], [100.0, 101.0, 102.0, 103.0]]
    """
    batch, _, height, width = position.shape
    samples, tile = offset.shape[:2]
    if height % tile or offset.shape[2] != width:
        raise ValueError(f"offset: {tuple(offset.shape)} rows do not tile a ({height}, {width}) band")
    if axis == 2:
        tiled = position.view(batch, 1, 1, height // tile, tile, width) + offset.view(1, 1, samples, 1, tile, width)
        return tiled.view(batch, 1, samples, height, width)
    offset = offset.permute(1, 2, 0).contiguous().view(1, 1, 1, tile, width, samples)
    return (position.view(batch, 1, height // tile, tile, width, 1) + offset).reshape(batch, 1, height, width, samples)
