"""Ground-Truth Ambient Occlusion (Jimenez et al. 2016) as XeGTAO's main pass (``XeGTAO_MainPass``) computes it.

Per pixel and slice (screen angle ``φ = (k + noise)/S·π``): project the normal into the slice (angle ``n`` from the
view vector ``v``), march ``K`` pixel-centre-rounded steps per side, keep the highest horizon cosine (each sample's
lerped toward ``cos(n ± π/2)`` by the falloff weight), integrate ``a(h)`` analytically, weight by ``|proj n|``;
then the slice mean, ``pow(vis, FinalValuePower)``, ``max(0.03, vis)``, saturate (XeGTAO's final denoise does).

**Differences from XeGTAO.** No depth MIP chain: every sample is a nearest fetch of the full-resolution ``view_z``
at the pixel-centre rounded offset (XeGTAO reads a 5-level pyramid at ``mip = log2|offset| − 3.3``). Samples
that fall off screen are ignored (XeGTAO's clamp sampler pairs the edge depth with the off-screen position, a
fake surface that darkens the image border). The bent normal uses the exact slice basis ``(ô, v)`` where XeGTAO
rotates ``(0, 0, −1)`` onto ``v`` (identical on the optical axis). Kept: the centre z ×0.99999 (FP32 bias), the
small-radius term ``sat((10 − r_px)/100)·0.5`` (added before the slice mean, as in XeGTAO).

**What it estimates.** With ``falloff_range = 0`` (hard cut) the slice integral is the cosine-weighted binary
visibility of the depth buffer as a height field (all behind the first surface solid) within
``R' = radius·radius_multiplier``: the ``"cosine"`` ground truth, in the limit of many steps and slices. With the
default falloff an occluder at distance ``d`` enters with its horizon *cosine* lerped toward the low horizon by
``w(d)``: full weight up to ``(1 − 0.615)·R' ≈ 0.28``, none beyond ``R' ≈ 0.73`` (radius 0.5), ``w ≈ 0.5`` at
``d = radius``. That is neither a hard-cut cosine AO nor obscurance (which weights each *ray* by ``ρ(d)``); XeGTAO
tuned 1.457 and 0.615 to best match (sRGB PSNR) its ray-traced reference, cosine-weighted binary visibility with
rays of length ``radius``, so compare against the ``"cosine"`` ground truth at ``radius``. ``pow(·, 2.2)`` then
darkens on purpose (tuned, not physical). Slice angles are uniform on *screen*, not around ``v``: off-axis pixels
get a bias (an unoccluded plane facing the camera reads ≈ 0.96 in the corners of a 60° view).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional, Sequence, Union

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import AOResult, check_count, check_radius, row_bands
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from .gtao_parts import NOISE_KINDS, check_noise, hilbert_index, unit3, noise_buffer, slice_visibility  # noqa: F401
from .gtao_slices import gtao_rows
from .slice_samples import sample_texture
from ..registry import Method, SpeedPanel

FLAVOUR = "cosine"  # the ground-truth weighting this pass estimates (ssbench.reference.ao)
REQUIRES = ("view_z", "normal", "mask")
QUALITY_PRESETS = {"low": (1, 2), "medium": (2, 2), "high": (3, 3), "ultra": (9, 3)}  # slices, steps per side
#: continuous parameters ``ssbench tune`` may fit: name -> (lo, hi, relative to the ground-truth radius)
TUNABLE = {"radius": (0.25, 3.0, True), "falloff_range": (0.05, 1.0, False),
           "final_value_power": (0.5, 4.0, False)}
#: the report's tuning section fits this method
TUNED_IN_REPORT = True
#: where the defaults come from (shown by the report next to the parameters)
DEFAULTS_SOURCE = ('XeGTAO (Intel, 2021, https://github.com/GameTechDev/XeGTAO): High quality, auto-tuned constants, '
                   'Hilbert R2 noise, 1 denoise pass')
#: the parameter that advances the noise from frame to frame (ssbench.evaluate.ao_frames)
FRAME_PARAM = "frame"
NoiseSpec = Union[str, torch.Tensor, Sequence]


def _number(value, name: str, low: float, low_open: bool, high: float) -> None:
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    if not ok or value < low or (low_open and value == low) or value > high:
        rng = f"{'(' if low_open else '['}{low}, {high}]"
        raise ValueError(f"{name}: must be a finite number in {rng}, got {value!r}")


@dataclass(frozen=True)
class GTAOParams:
    """Parameters of :func:`gtao`, XeGTAO's ``GTAOSettings`` snake-cased. Defaults are what XeGTAO ships
    (Intel, XeGTAO, 2021, https://github.com/GameTechDev/XeGTAO, ``XeGTAO.h``): quality High, the auto-tuned
    constants, Hilbert-curve R2 noise and one denoise pass.

    Attributes:
        quality: ``"low"`` 1×2, ``"medium"`` 2×2, ``"high"`` 3×3, ``"ultra"`` 9×3 (slices × steps per side).
        slice_count, steps_per_slice: override the preset's counts when given.
        radius: ``Radius`` in scene units; the effect radius is ``radius·radius_multiplier``.
        falloff_range: fraction of the effect radius over which samples fade out (0 = hard cut at ``R'``).
        sample_distribution_power: ``s^p`` packs steps toward the centre.
        thin_occluder_compensation: scales sample Δz by ``1 + c`` in the falloff distance (0 = off).
        final_value_power: ``vis^p`` after averaging the slices.
        min_offset_pixels: ``pixelTooCloseThreshold``, added to every step as ``1.3/r_px``.
        noise: ``"hilbert"`` (XeGTAO's R2 sequence along a 64² Hilbert curve, advanced by ``frame``; the default),
            ``"hash"`` (per-pixel uniform pairs from ``seed``/the generator), ``"none"`` (0.5, the R2 value at index 0), or a tile
            ``(2, 4, 4)`` (slice, step noise) or ``(4, 4)`` (both) in [0, 1) read at ``[row % 4, col % 4]``.
        seed: seeds ``"hash"`` noise when no generator is passed.
        frame: temporal index of the ``"hilbert"`` noise: XeGTAO adds ``288·(frame mod 64)`` to the Hilbert
            index (``SpatioTemporalNoise``), so consecutive frames see other rotations for TAA to average.
        denoise_passes: XeGTAO's 3×3 edge-aware denoise passes (``gtao_denoise``) applied *before* the final
            clip to [0.03, 1], so values that overshoot 1 average out (XeGTAO's ``DenoisePasses`` default 1;
            0 = raw, what the article-style comparisons of per-pixel noise use).
    """

    quality: str = "high"
    slice_count: Optional[int] = None
    steps_per_slice: Optional[int] = None
    radius: float = 0.5
    radius_multiplier: float = 1.457
    falloff_range: float = 0.615
    sample_distribution_power: float = 2.0
    thin_occluder_compensation: float = 0.0
    final_value_power: float = 2.2
    min_offset_pixels: float = 1.3
    noise: NoiseSpec = "hilbert"
    seed: int = 0
    frame: int = 0
    denoise_passes: int = 1

    def __post_init__(self) -> None:
        if self.quality not in QUALITY_PRESETS:
            raise ValueError(f"quality: expected one of {list(QUALITY_PRESETS)}, got {self.quality!r}")
        for name in ("slice_count", "steps_per_slice"):
            if getattr(self, name) is not None:
                check_count(getattr(self, name), name)
        check_radius(self.radius, "radius")
        for name, low_open, high in (("radius_multiplier", True, math.inf), ("falloff_range", False, 1.0),
                                     ("sample_distribution_power", True, math.inf),
                                     ("thin_occluder_compensation", False, math.inf),
                                     ("final_value_power", True, math.inf), ("min_offset_pixels", False, math.inf)):
            _number(getattr(self, name), name, 0.0, low_open, high)
        check_noise(self.noise, self.seed, self.frame)
        if isinstance(self.denoise_passes, bool) or not isinstance(self.denoise_passes, int) \
                or self.denoise_passes < 0:
            raise ValueError(f"denoise_passes: must be an integer >= 0, got {self.denoise_passes!r}")

    @property
    def slices(self) -> int:
        """Slice count in use (``slice_count`` or the preset's)."""
        return self.slice_count if self.slice_count is not None else QUALITY_PRESETS[self.quality][0]

    @property
    def steps(self) -> int:
        """Steps per side of a slice in use (``steps_per_slice`` or the preset's)."""
        return self.steps_per_slice if self.steps_per_slice is not None else QUALITY_PRESETS[self.quality][1]


def check_inputs(gbuffer: GBuffer, params: GTAOParams) -> None:
    """Type checks of ``params`` and the shared G-buffer contract (:func:`~ssbench.passes.gbuffer_checks.check_gbuffer`)."""
    if not isinstance(params, GTAOParams):
        raise TypeError(f"params: expected GTAOParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES)


@autograd_free
@half_in_float32
def gtao(gbuffer: GBuffer, params: GTAOParams = GTAOParams(), *, generator: Optional[torch.Generator] = None,
         debug: bool = False, bent_normals: bool = False) -> AOResult:
    """GTAO of a G-buffer, XeGTAO's main pass vectorised over pixels (loops over slices and steps only).

    .. math::
        V = \\max\\Big(0.03,\\ \\Big[\\frac{1}{S}\\sum_{k=1}^{S} |\\mathrm{proj}\\,n_k|
        \\big(a(h_{0,k}) + a(h_{1,k})\\big)\\Big]^{p}\\Big), \\qquad
        a(h) = \\tfrac14\\big(\\cos n + 2h\\sin n - \\cos(2h - n)\\big)

    Args:
        gbuffer: needs ``view_z`` :math:`(B, 1, H, W)` (< 0 on geometry), ``normal`` :math:`(B, 3, H, W)` unit
            view-space normals and ``mask`` :math:`(B, 1, H, W)` bool.
        params: :class:`GTAOParams`.
        generator: draws ``"hash"`` noise (default: a CPU generator seeded with ``params.seed``).
        debug: also return ``horizon_cos`` :math:`(B, S, 2, H, W)` (final ``hc0``, ``hc1`` per slice),
            ``normal_angle`` :math:`(B, S, H, W)` (``n``), ``slice_visibility`` :math:`(B, S, H, W)` and
            ``screen_radius`` :math:`(B, 1, H, W)` (effect radius in pixels).
        bent_normals: also return unit view-space bent normals (XeGTAO Algorithm 2; 0 on background).

    Returns:
        :class:`AOResult` with ``ao`` :math:`(B, 1, H, W)` in [0, 1], 1 on background.

    Raises:
        ValueError: missing channels, bad shapes, dtypes or values (the message names the argument).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 30.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> m = torch.ones(1, 1, 6, 8, dtype=torch.bool)
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n, mask=m)
        >>> r = gtao(g)
        >>> r.ao.shape, bool((r.ao > 0.99).all())       # a wall facing the camera is unoccluded
        (torch.Size([1, 1, 6, 8]), True)
    """
    check_inputs(gbuffer, params)
    cam, mask = gbuffer.camera, gbuffer.mask
    B, _, H, W = gbuffer.view_z.shape
    dtype, dev = gbuffer.view_z.dtype, gbuffer.view_z.device
    S, K = params.slices, params.steps
    noise = noise_buffer(params, B, H, W, generator).to(dtype=dtype, device=dev)   # (B, 2, H, W)

    z = torch.where(mask, gbuffer.view_z, torch.full_like(gbuffer.view_z, -cam.far))  # sanitised depth texture
    rows = torch.arange(H, dtype=dtype, device=dev)
    tex = sample_texture(cam, z)      # (B, 3, H, W) texel view positions; z if compiled or with gradients
    parts = [gtao_rows(cam, tex, rows[rs], gbuffer.normal[:, :, rs], mask[:, :, rs], noise[:, :, rs], params, debug,
                       bent_normals) for rs in row_bands(H, W, 2 * K, z.element_size(), batch=B)]   # bounded set
    vis = torch.cat([p[0] for p in parts], 2)
    bent = None if not bent_normals else [torch.cat([p[1][i] for p in parts], 2) for i in range(3)]
    dbg_h, dbg_n, dbg_v, r_px = (torch.cat([p[2][i] for p in parts], -2) for i in range(4)) if debug else \
        (None,) * 4

    # ---- Final value ----
    vis = (vis / S).clamp_min(0.0) ** params.final_value_power
    if params.denoise_passes:                     # before the clip, as XeGTAO: overshoot above 1 averages out
        from .gtao_denoise import gtao_denoise
        vis = gtao_denoise(torch.where(mask, vis, torch.ones_like(vis)), gbuffer.view_z, mask,
                           passes=params.denoise_passes)
    vis = vis.clamp(0.03, 1.0)
    ao = torch.where(mask, vis, torch.ones_like(vis))
    out_bent = (None if bent is None else
                torch.where(mask, torch.cat(unit3(tuple(bent)), 1), torch.zeros_like(gbuffer.normal)))
    extra = {"horizon_cos": dbg_h, "normal_angle": dbg_n, "slice_visibility": dbg_v,
             "screen_radius": r_px} if debug else {}
    return AOResult(ao=ao, bent_normal=out_bent, debug=extra)


class GTAO(nn.Module):
    """:func:`gtao` as a module; ``GTAO(quality="ultra")`` overrides fields of ``params``.

    Example:
        >>> GTAO(quality="low").params.slices
        1
    """

    def __init__(self, params: GTAOParams = GTAOParams(), **overrides) -> None:
        super().__init__()
        self.params = replace(params, **overrides) if overrides else params

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None, debug: bool = False,
                bent_normals: bool = False) -> AOResult:
        return gtao(gbuffer, self.params, generator=generator, debug=debug, bent_normals=bent_normals)


def samples_per_pixel(params) -> int:
    """Depth texels the main loop reads per pixel (one depth texel per step on both sides of every slice): the floor's gather count
    (:func:`ssbench.bench.effects.ao_samples`)."""
    return int(2 * params.slices * params.steps)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("gtao", gtao, GTAOParams, GTAO, order=40, title="ground-truth AO, GTAO (Jimenez et al. 2016; XeGTAO)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"radius": 0.5, "quality": ["low", "medium", "high", "ultra"]},
                        {"radius": 0.5, "quality": "high", "noise": ["hash", "none"]}],
               "blur": [{"radius": 0.5, "quality": "high"}]}
SPEED_PANELS = (SpeedPanel("banding", "quality", (("blur", None), ("noise", "hilbert"))),
                SpeedPanel("banding", "noise", (("blur", None), ("quality", "high"))),
                SpeedPanel("halos", "blur", (("quality", "high"), ("noise", "hilbert"))))
