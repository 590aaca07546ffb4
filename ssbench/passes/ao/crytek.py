"""Crytek SSAO (Crysis, 2007; SSAO article §1, Fig. 1–2): sphere samples around the pixel, no normal.

Per pixel:

1. ``viewPosition`` from ``view_z`` (``uvToView``: only the depth buffer is needed, as in Crysis).
2. ``random`` from the 4×4 noise texture (``NEAREST``, ``REPEAT``). The kernel is **reflected** in the
   plane whose normal is ``random`` — ``reflect(Kernel[i], random) = k − 2 (k·r) r`` — as the Crysis shader
   rotated its samples by reflection on a random plane. A reflection maps the ball onto itself, so the sphere
   distribution survives; a rotation would too, but reflection needs no matrix.
3. ``samplePoint = viewPosition + reflect(Kernel[i], random) · KernelRadius``; it is projected, the depth
   texel fetched and compared in linear depth exactly like the hemisphere pass
   (:func:`ssbench.passes.ao.ssao.range_check_count`): it occludes if ``MinDistance < delta < MaxDistance``.
   ``reflect(Kernel[i], random) · KernelRadius`` depends on the noise texel alone, so it is computed for one period
   of noise rows and repeated down each band of rows (:mod:`ssbench.passes.noise_tiles`): the same bits.
4. ``AO = 1 − Strength · count / K``.

**Which AO it estimates, and the grey bias.** The count is the fraction of a *ball* around the point that
lies inside geometry: a sphere-volume estimate. On an open plane half the ball is under the surface, so
``AO ≈ 0.5`` everywhere — the "everything is grey" look the article shows in Fig. 2 and the reason §1 moves to
the normal-oriented hemisphere. Crease interiors go darker than 0.5, convex edges lighter. It is not a visibility
integral over directions: the count converges to the fraction of the ball *outside* geometry, the
``"volume_sphere"`` flavour of :mod:`ssbench.reference.ao_volume` (0.5 on an open plane), which this pass is
scored against. Because the kernel comes in opposite pairs (:func:`~ssbench.passes.sampling.sphere_kernel`),
a plane gives 0.5 up to depth-texel quantisation.

The grey level drifts up on a distant floor seen at a grazing angle: the depth gap under the floor
exceeds ``max_distance`` and those samples stop counting (0.58 at 12–20 units on the catalog floor camera).
``min_distance`` defaults to 0 (no self-occlusion bias): a bias would hide samples just *below* the plane
and push the open-plane level above 0.5. Off-screen samples read the edge texel, samples behind the camera
never count (see :mod:`ssbench.passes.ao.ssao`), and background pixels get AO 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import AOResult, make_generator
from ..compiled import kernel
from ..compiled_samples import sample_axis
from ..sampling import noise_lookup, noise_texel, noise_texture, sphere_kernel
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..noise_tiles import band_tile_rows, rows_repeat, tiled_add
from ..inference import autograd_free
from .ssao_common import (band_result, banded_ao, check_ssao_params, range_check_count, real_depth_texture,
                          ssao_result, view_position)
from ..registry import Method, SpeedPanel

FLAVOUR = "volume_sphere"  # the ground truth this pass estimates (ssbench.reference.ao_volume)
#: continuous parameters ``ssbench tune`` may fit (as hemisphere SSAO's: the same range check and strength)
TUNABLE = {"kernel_radius": (0.25, 4.0, True), "min_distance": (0.0, 0.005, False),
           "max_distance": (0.002, 0.1, False), "strength": (0.5, 2.0, False)}
#: where the defaults come from (shown by the report next to the parameters)
DEFAULTS_SOURCE = ('Mittring, "Finding Next Gen — CryEngine 2", SIGGRAPH 2007 (16 sphere samples, 4×4 rotation, no '
                   'bias); distances scaled to the catalog scenes')
REQUIRES = ("view_z", "mask")


@dataclass(frozen=True)
class CrytekSSAOParams:
    """Settings of :func:`crytek_ssao`.

    Defaults follow Crysis as Mittring describes it (M. Mittring, "Finding Next Gen — CryEngine 2", SIGGRAPH
    2007 course notes, https://doi.org/10.1145/1281500.1281671): 16 samples per pixel in a sphere, rotated per
    pixel by a 4×4 random texture; no bias. The radius and the range check are scene-scaled (the catalog's).

    Args:
        kernel_size: samples per pixel.
        kernel_radius: radius of the sample ball in view-space units.
        min_distance: smallest counted ``delta`` in linear depth (0: no bias, see the module docstring).
        max_distance: largest counted ``delta`` in linear depth (range check against halos).
        strength: ``AO = 1 − occlusion · strength``.
        noise_size: side of the reflection-noise texture.
        seed: seeds the kernel and the noise when no generator is passed.
    """

    kernel_size: int = 16
    kernel_radius: float = 0.5
    min_distance: float = 0.0
    max_distance: float = 0.02
    strength: float = 1.0
    noise_size: int = 4
    seed: int = 0

    def __post_init__(self) -> None:
        check_ssao_params(self)


def reflected_offsets(kernel: torch.Tensor, rnd: torch.Tensor, kernel_radius: float) -> tuple:
    """``reflect(Kernel[i], random) · KernelRadius`` for every kernel vector :math:`(K, 3)` and every noise vector of
    ``rnd`` :math:`(1, 3, t, W)`: three :math:`(K, t, W)` components, the offsets of ``t`` rows of pixels from their
    view positions (:func:`ssbench.passes.noise_tiles.tiled_add`). They depend on the noise texel alone, so one period
    of noise rows (4 by default) serves every band of the image.

    Example:
        >>> plane_normal = torch.tensor([1.0, 0.0, 0.0]).view(1, 3, 1, 1)
        >>> off = reflected_offsets(torch.tensor([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]), plane_normal, 2.0)
        >>> [c.flatten().tolist() for c in off]       # in the plane: kept; along its normal: flipped
        [[0.0, -2.0], [0.0, 0.0], [2.0, 0.0]]
    """
    kc = [kernel[:, c].view(-1, 1, 1) for c in range(3)]                             # (K, 1, 1)
    rc = [rnd[0, c] for c in range(3)]                                                # (t_h, t_w)
    dot = kc[0] * rc[0] + kc[1] * rc[1] + kc[2] * rc[2]                              # (K, t_h, t_w)
    return tuple((kc[c] - 2.0 * dot * rc[c]) * kernel_radius for c in range(3))


@kernel
def sphere_band(cam, position: torch.Tensor, offset: tuple, mask: torch.Tensor, real_depth: torch.Tensor,
                p: "CrytekSSAOParams", debug: bool) -> tuple:
    """Mittring's sample loop on a band of rows: ``samplePoint = position + reflect(Kernel[i], random) · radius``
    (the reflected offsets of :func:`reflected_offsets` on ``t`` rows, repeated down the band by
    :func:`~ssbench.passes.noise_tiles.tiled_add`), then the range-checked count (:func:`.ssao.range_check_count`).

    ``position`` :math:`(B, 3, h, W)`, ``offset`` three :math:`(K, t, W)`, ``mask`` :math:`(B, 1, h, W)`; returns
    the band's :math:`(B, 1, h, W)` AO and, with ``debug``, its count (:func:`.ssao_common.band_result`; the pass's
    compilable kernel, :mod:`ssbench.passes.compiled`; its samples lie along
    :func:`~ssbench.passes.compiled_samples.sample_axis`).
    """
    axis = sample_axis()
    sample_point = tuple(tiled_add(position[:, c:c + 1], offset[c], axis) for c in range(3))  # 3 × (B, 1, K, h, W)
    count = range_check_count(cam, sample_point, real_depth, p.min_distance, p.max_distance, axis)
    return band_result(count, p, mask, position.dtype, debug)


@kernel
def sphere_frame(cam, view_z: torch.Tensor, noise: torch.Tensor, p: "CrytekSSAOParams") -> tuple:
    """Per pixel, before the sample loop (a compilable kernel, :mod:`ssbench.passes.compiled`): the view position
    :math:`(B, 3, H, W)` and the linear depth of every texel (:func:`.ssao_common.real_depth_texture`) from
    ``view_z`` :math:`(B, 1, H, W)`, and the random reflection
    plane :math:`(1, 3, H, W)` read from ``noise`` :math:`(3, S, S)` at texel ``(row, col)`` :math:`(H, W)`."""
    uv = cam.uv_grid(view_z.dtype, view_z.device)                                  # (2, H, W) vUv
    position, texture = view_position(cam, view_z, "view_z", uv)                   # (B, 3, H, W)
    col, row = noise_texel(uv, cam.width, cam.height, p.noise_size)
    random = noise_lookup(noise, row, col).unsqueeze(0)                            # (1, 3, H, W)
    return position, real_depth_texture(cam, texture, False), random, row, col


@autograd_free
@half_in_float32
def crytek_ssao(gbuffer: GBuffer, params: CrytekSSAOParams = CrytekSSAOParams(), *,
                generator: torch.Generator | None = None, debug: bool = False) -> AOResult:
    r"""Crytek's sphere SSAO (see the module docstring).

    .. math::
        \mathrm{AO} = 1 - \mathrm{Strength}\cdot\frac{1}{K}\sum_{i<K}
        [\mathrm{MinDistance} < \ell(s_i) - \ell_{\mathrm{buf}}(\mathrm{uv}(s_i)) < \mathrm{MaxDistance}],
        \qquad s_i = P + R\,\mathrm{reflect}(k_i, r)

    Args:
        gbuffer: needs ``view_z`` :math:`(B, 1, H, W)` and ``mask`` :math:`(B, 1, H, W)` (bool).
        params: :class:`CrytekSSAOParams`.
        generator: draws the kernel, then the noise; default: a CPU generator seeded with ``params.seed``.
        debug: also return ``debug["samples"]`` (:math:`(B, 1, H, W)` counted samples),
            ``debug["noise_index"]``, ``debug["kernel"]`` and ``debug["noise"]``.

    Returns:
        :class:`~ssbench.passes.common.AOResult` with ``ao`` :math:`(B, 1, H, W)` in [0, 1].

    Raises:
        ValueError: naming the argument, for missing channels, wrong shapes or dtypes.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 100.0)
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), mask=torch.ones(1, 1, 6, 8, dtype=torch.bool))
        >>> crytek_ssao(g).ao.mean().item()          # a wall facing the camera: Crytek's grey
        0.5
    """
    if not isinstance(params, CrytekSSAOParams):
        raise TypeError(f"params: expected CrytekSSAOParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES)
    cam, p, mask = gbuffer.camera, params, gbuffer.mask
    dtype, device = gbuffer.view_z.dtype, gbuffer.view_z.device
    g = make_generator(p.seed, generator)
    kernel = sphere_kernel(p.kernel_size, g).to(dtype=dtype, device=device)        # (K, 3)
    noise = noise_texture(p.noise_size, g).to(dtype=dtype, device=device)          # (3, S, S) unit, z = 0

    position, real_depth, random, row, col = sphere_frame(cam, gbuffer.view_z, noise, p)
    periodic = rows_repeat(random, p.noise_size)
    tiles: dict = {}                                  # the offsets of each set of noise rows, computed once

    def band(rs: slice) -> tuple:
        tile = band_tile_rows(rs, p.noise_size, periodic)
        if (tile.start, tile.stop) not in tiles:
            tiles[tile.start, tile.stop] = reflected_offsets(kernel, random[..., tile, :], p.kernel_radius)
        return sphere_band(cam, position[..., rs, :], tiles[tile.start, tile.stop], mask[..., rs, :], real_depth,
                           p, debug)

    ao, count = banded_ao(band, mask.shape, dtype, device, p.kernel_size, debug, p.noise_size if periodic else 1)
    return ssao_result(ao, count, p, mask, row=row, col=col, kernel=kernel, noise=noise)


class CrytekSSAO(nn.Module):
    """Module form of :func:`crytek_ssao`; ``forward(gbuffer)`` returns an :class:`AOResult`.

    Shape:
        - Input: a :class:`~ssbench.gbuffer.GBuffer` with ``view_z`` and ``mask``.
        - Output: ``ao`` :math:`(B, 1, H, W)`.

    Example:
        >>> CrytekSSAO().params.kernel_size
        16
    """

    def __init__(self, params: CrytekSSAOParams = CrytekSSAOParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: torch.Generator | None = None) -> AOResult:
        return crytek_ssao(gbuffer, self.params, generator=generator, debug=self.debug)


def samples_per_pixel(params) -> int:
    """Depth texels the main loop reads per pixel (one depth texel per kernel point): the floor's gather count
    (:func:`ssbench.bench.effects.ao_samples`)."""
    return int(params.kernel_size)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("crytek", crytek_ssao, CrytekSSAOParams, CrytekSSAO, order=10,
                title="Crytek sphere SSAO (Mittring 2007)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"kernel_radius": 0.5, "kernel_size": [8, 32]}]}
SPEED_PANELS = (SpeedPanel("banding", "kernel_size", (("blur", None),)),)
