"""What both point-sampling SSAO passes share (SSAO article §2): parameter checks, the view position and the
buffer ``getLinearDepth`` samples, the range-checked sample count and the count → AO step. Used by
:mod:`ssbench.passes.ao.crytek` (sphere kernel) and :mod:`ssbench.passes.ao.ssao` (hemisphere kernel).
"""
from __future__ import annotations

import torch

from ...camera import Camera
from typing import Callable

from ..common import AOResult, check_count, check_radius, fetch_texels, nan_to_zero, row_bands, texel_of
from ..compiled_samples import band_samples
from ..float_masks import count_between, replace_zeros

__all__ = ["check_ssao_params", "view_position", "real_depth_texture", "kernel_components", "range_check_count",
           "occlusion_to_ao", "band_result", "banded_ao", "ssao_result"]


def check_ssao_params(p) -> None:
    """Parameter checks shared by both SSAO variants; every error names the field."""
    check_count(p.kernel_size, "kernel_size")
    check_radius(p.kernel_radius, "kernel_radius")
    check_count(p.noise_size, "noise_size")
    for name in ("min_distance", "max_distance", "strength"):
        v = getattr(p, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < float("inf"):
            raise ValueError(f"{name}: must be a finite number >= 0, got {v!r}")
    if not p.min_distance < p.max_distance:
        raise ValueError(f"max_distance: must exceed min_distance={p.min_distance}, got {p.max_distance}")
    if isinstance(p.seed, bool) or not isinstance(p.seed, int) or p.seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {p.seed!r}")


def view_position(camera: Camera, view_z: torch.Tensor, position_from: str,
                  uv: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``(viewPosition, texture)``: :math:`(B, 3, H, W)` positions and the :math:`(B, 1, H, W)` buffer
    that ``getLinearDepth`` samples (the GL depth buffer for ``"depth"``, ``view_z`` otherwise), at ``uv``, the
    :math:`(2, H, W)` ``camera.uv_grid()`` the caller also reads the noise at (a compiled kernel stores each grid
    it builds)."""
    uv = uv.unsqueeze(0)                                                         # (1, 2, H, W) vUv
    if position_from == "depth":
        depth = camera.view_z_to_depth(view_z)                                   # getDepth(vUv)
        return camera.view_position_from_depth(uv.expand(view_z.shape[0], -1, -1, -1), depth), depth
    return camera.uv_to_view(uv, view_z), view_z


def real_depth_texture(camera: Camera, texture: torch.Tensor, from_depth: bool) -> torch.Tensor:
    """``realDepth`` of every texel of ``texture`` :math:`(B, 1, H, W)`: ``getLinearDepth`` (SSAO article §2.2) is
    ``viewZToOrthographicDepth`` of the texel's view z (``perspectiveDepthToViewZ`` of the GL depth buffer when
    ``from_depth``, else ``texture`` holds view z), a function of the texel alone. Computed once per texel, not once
    per sample that reads the texel: the same operations on the same value, so the same bits.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 1.0, 11.0)
        >>> real_depth_texture(cam, torch.full((1, 1, 3, 4), -6.0), False)[0, 0, 0, 0].item()    # halfway
        0.5
    """
    view_z = camera.depth_to_view_z(texture) if from_depth else texture          # perspectiveDepthToViewZ
    return camera.view_z_to_orthographic_depth(view_z)                           # realDepth


def kernel_components(kernel: torch.Tensor, axis: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``Kernel[i]`` :math:`(K, 3)` as its x, y, z components laid along the sample ``axis`` of a band's blocks
    (:func:`ssbench.passes.compiled_samples.sample_axis`): :math:`(1, 1, K, 1, 1)` for axis 2, :math:`(1, 1, 1, 1, K)`
    for the last.

    Example:
        >>> [c.shape[2] for c in kernel_components(torch.zeros(8, 3), 2)]
        [8, 8, 8]
    """
    shape = [1, 1, 1, 1, 1]
    shape[axis] = kernel.shape[0]
    return tuple(kernel[:, c].reshape(shape) for c in range(3))


def range_check_count(camera: Camera, sample_point: tuple, real_depth: torch.Tensor,
                      min_distance: float, max_distance: float, axis: int) -> torch.Tensor:
    """The shader's sample loop body for all samples at once: project, fetch, compare, count.

    Args:
        sample_point: view-space ``samplePoint`` as its ``(x, y, z)`` components, each :math:`(B, 1, K, h, W)`, or
            :math:`(B, 1, h, W, K)` with ``axis=-1`` (kept apart, never stacked, so that a compiled kernel fuses
            the whole loop body into one pass).
        real_depth: :math:`(B, 1, H, W)` the ``realDepth`` of every texel (:func:`real_depth_texture`).
        axis: the samples' axis (:func:`ssbench.passes.compiled_samples.sample_axis`).

    Returns:
        :math:`(B, 1, h, W)` integer count of samples with ``min_distance < delta < max_distance``.
    """
    x, y, z = sample_point
    # NOTE: w = -z = 0 would divide by zero; the GPU result is undefined, ours reads as "just in front"
    z_proj = replace_zeros(z, -torch.finfo(z.dtype).tiny)
    # NaN reads as 0 (texel_of clamps infinities as nan_to_num would clamp ±max)
    u, v = (nan_to_zero(c) for c in camera.scaled_uv_xy(x, y, z_proj, camera.ndc_scale()))    # samplePointUv
    col, row = texel_of(u, v, real_depth.shape[-2], real_depth.shape[-1], nan_free=True, dtype=u.dtype)
    real = fetch_texels(real_depth, col.squeeze(1), row.squeeze(1)).reshape(z.shape)  # realDepth: NEAREST, clamp
    sample_depth = camera.view_z_to_orthographic_depth(z)                        # sampleDepth
    delta = sample_depth - real
    return count_between(delta, min_distance, max_distance, axis)                # (B, 1, h, W)


def occlusion_to_ao(count: torch.Tensor, kernel_size: int, strength: float, mask: torch.Tensor,
                    dtype: torch.dtype) -> torch.Tensor:
    """``1 − clamp(count / K, 0, 1) · Strength``, clamped to [0, 1]; 1 off ``mask``."""
    occlusion = (count.to(dtype) / float(kernel_size)).clamp(0.0, 1.0)
    ao = (1.0 - occlusion * strength).clamp(0.0, 1.0)
    return torch.where(mask, ao, torch.ones_like(ao))


def band_result(count: torch.Tensor, p, mask: torch.Tensor, dtype: torch.dtype, debug: bool) -> tuple:
    """What a band kernel of either SSAO pass returns: ``(ao, count)``, the band's AO
    (:func:`occlusion_to_ao`, inside the kernel, where it fuses with the sample loop) and, with ``debug``, the
    range-checked sample count (else ``None``)."""
    return occlusion_to_ao(count, p.kernel_size, p.strength, mask, dtype), (count if debug else None)


def banded_ao(run: Callable[[slice], tuple], shape: tuple, dtype: torch.dtype, device, samples: int,
              debug: bool, multiple: int = 1) -> tuple[torch.Tensor, torch.Tensor | None]:
    """``(ao, count)`` of :math:`(B, 1, H, W)` ``shape``: a pass's band kernel, ``run(rows)`` → the band's
    :func:`band_result`, called on each band of rows (:func:`~ssbench.passes.common.row_bands` for
    :func:`~ssbench.passes.compiled_samples.band_samples` of its ``samples`` per pixel, in whole ``multiple`` of
    rows), its outputs gathered; ``count`` is ``None`` without ``debug``. ``samples=0``: the kernel stores no block of
    its samples (compiled hemisphere SSAO, :func:`~ssbench.passes.compiled_samples.sample_blocks`), and the whole
    image is one band (each call costs tens of µs of guards and wrappers). Bands of any size give the same bits."""
    height, width = shape[-2:]
    ao = torch.empty(shape, dtype=dtype, device=device)
    count = torch.empty(shape, dtype=torch.int64, device=device) if debug else None
    bands = row_bands(height, width, band_samples(samples), dtype.itemsize, multiple=multiple) if samples else \
        [slice(0, height)]                                                       # cache-sized
    for rs in bands:
        band_ao, band_count = run(rs)
        ao[..., rs, :] = band_ao
        if count is not None:
            count[..., rs, :] = band_count
    return ao, count


def ssao_result(ao: torch.Tensor, count: torch.Tensor | None, p, mask: torch.Tensor, *, row: torch.Tensor,
                col: torch.Tensor, kernel: torch.Tensor, noise: torch.Tensor) -> AOResult:
    """The pass's result from the bands' ``ao`` and, when ``count`` is given (``debug``), the per-pixel sample count,
    noise index, kernel and noise (shared by both SSAO passes)."""
    extra = {}
    if count is not None:
        extra = {"samples": torch.where(mask, count, torch.zeros_like(count)),
                 "noise_index": (row * p.noise_size + col).expand(mask.shape),
                 "kernel": kernel, "noise": noise}
    return AOResult(ao=ao, debug=extra)
