"""Visibility-bitmask ambient occlusion (Therrien, Levesque and Gilet, "Screen Space Indirect Lighting with
Visibility Bitmask", The Visual Computer, 2023, https://arxiv.org/abs/2301.11376).

GTAO keeps one horizon per side of a slice: everything below it is occluded, so a thin object (a fence slat, a
chair leg) hides the whole sky behind it and horizon methods over-occlude. The visibility bitmask instead gives
every depth sample a *thickness*: the sample occludes only the arc between its front face and a back face
``thickness`` farther from the camera. The slice's half circle around the projected normal is cut into
``sector_count`` sectors (32, one ``uint``); each sample sets the bits of the sectors its arc touches
(``UpdateSectors``); the slice's visibility is the share of bits left clear, ``1 − countbits/N``, and the AO the
mean over slices. There is no falloff: the thickness bounds what a sample can hide (as a ray tracer's own
binary visibility does).

Per pixel and slice, as GTAO (:mod:`ssbench.passes.ao.gtao`): slice angle ``φ = (k + noise)/S·π``, the normal
projected into the slice and its angle ``n`` from the view vector ``V``, ``steps`` pixel-centre-rounded samples
per side within ``radius`` (projected to pixels). Each sample's front and back directions from the pixel give
angles from ``V``, shifted to the normal-centred half circle and clamped: ``x = (θ − n + π/2)/π ∈ [0, 1]``.

**What it estimates.** The paper counts sectors uniformly in slice angle ("we do not take the cosine weight into
account", the authors' notes), which matches no ground-truth flavour exactly; it is scored against cosine AO, the
quantity GTAO and the paper's comparisons target. ``weighting="cosine"`` weights each clear sector by its share
of GTAO's cosine slice integral (``|proj n|·∫ cos(θ − n)|sin θ| dθ`` over the sector), which is exact cosine AO
of a scene of slabs ``thickness`` deep seen in the limit of many slices and samples.

**A bias on flat surfaces (the paper's rounding, kept).** A sector is marked when an arc merely *touches* it
(``ceil``, as the paper and Blender's EEVEE do). Samples on the pixel's own plane lie on its tangent, the edge of
the half circle; float round-off puts some a hair inside, and a whole edge sector is marked. Measured on an open
plane (24×18, defaults): mean AO 0.944 (uniform), 0.990 (cosine), no slice darker than one sector per side
(``tests/passes/ao/test_vbao.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import AOResult, check_count, check_positive, check_radius, row_bands
from ..compiled_samples import band_samples
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from .gtao import NoiseSpec
from .gtao_parts import check_noise, noise_buffer, unit3
from .slice_samples import sample_texture
from .vbao_slices import vbao_rows
from ..registry import Method, SpeedPanel

FLAVOUR = "cosine"  # the ground-truth weighting it is scored against (see the module docstring)
REQUIRES = ("view_z", "normal", "mask")
WEIGHTINGS = ("uniform", "cosine")
#: where the defaults come from (shown by the report next to the parameters)
DEFAULTS_SOURCE = ("Therrien et al. 2023 and the authors' HLSL notes (32 sectors, a sample touching a sector occludes "
                   "it, no falloff); slices, steps and thickness chosen here for the catalog's metre-scale scenes")
#: the tuner's ranges: name -> (low, high, log scale)
TUNABLE = {"radius": (0.25, 3.0, True), "thickness": (0.02, 2.0, True)}


@dataclass(frozen=True)
class VBAOParams:
    """Parameters of :func:`vbao`.

    Attributes:
        slices: slice directions per pixel (the paper's ``sliceCount``).
        steps: samples per side of a slice (``sampleCount``).
        radius: view-space length the samples reach (projected to pixels at the pixel's depth).
        thickness: the constant depth behind every front face that a sample occludes (view-space units).
        sector_count: sectors of a slice's half circle, at most 32 (one ``uint``).
        weighting: ``"uniform"`` (the paper: visibility = share of clear sectors) or ``"cosine"`` (each clear
            sector weighted by its cosine share, GTAO's slice integral).
        sample_distribution_power: ``s^p`` packs samples toward the pixel (1: evenly spaced).
        min_offset_pixels: added to every sample's distance (in pixels), so none reads the pixel itself.
        noise, seed, frame: the slice and step noise, as :class:`~ssbench.passes.ao.gtao.GTAOParams`.
    """

    slices: int = 4
    steps: int = 8
    radius: float = 0.5
    thickness: float = 0.25
    sector_count: int = 32
    weighting: str = "uniform"
    sample_distribution_power: float = 1.0
    min_offset_pixels: float = 1.0
    noise: NoiseSpec = "hilbert"
    seed: int = 0
    frame: int = 0

    def __post_init__(self) -> None:
        for name in ("slices", "steps", "sector_count"):
            check_count(getattr(self, name), name)
        if self.sector_count > 32:
            raise ValueError(f"sector_count: at most 32 (one uint bitfield), got {self.sector_count}")
        check_radius(self.radius, "radius")
        check_radius(self.thickness, "thickness")
        if self.weighting not in WEIGHTINGS:
            raise ValueError(f"weighting: expected one of {WEIGHTINGS}, got {self.weighting!r}")
        check_positive(self.sample_distribution_power, "sample_distribution_power")
        check_positive(self.min_offset_pixels, "min_offset_pixels", allow_zero=True)
        check_noise(self.noise, self.seed, self.frame)


def check_inputs(gbuffer: GBuffer, params: VBAOParams) -> None:
    """Type checks of ``params`` and the shared G-buffer contract (:func:`~ssbench.passes.gbuffer_checks.check_gbuffer`)."""
    if not isinstance(params, VBAOParams):
        raise TypeError(f"params: expected VBAOParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES)


@autograd_free
@half_in_float32
def vbao(gbuffer: GBuffer, params: VBAOParams = VBAOParams(), *, generator: Optional[torch.Generator] = None,
         debug: bool = False, bent_normals: bool = False) -> AOResult:
    """Visibility-bitmask AO of a G-buffer, vectorised over pixels (loops over slices, samples and sectors).

    .. math::
        V = \\frac{1}{S}\\sum_{k=1}^{S}\\Big(1 - \\frac{\\mathrm{popcount}(b_k)}{N}\\Big), \\qquad
        b_k = \\bigvee_{\\text{samples}} \\mathrm{sectors}\\big[\\min(x_f, x_b),\\ \\max(x_f, x_b)\\big]

    Args:
        gbuffer: ``view_z`` :math:`(B, 1, H, W)` (< 0 on geometry), ``normal`` :math:`(B, 3, H, W)` unit
            view-space normals and ``mask`` :math:`(B, 1, H, W)` bool.
        params: :class:`VBAOParams`.
        generator: draws ``"hash"`` noise (default: a CPU generator seeded with ``params.seed``).
        debug: also return ``bits`` :math:`(B, S, H, W)` int64 (each slice's occluded sectors) and
            ``slice_visibility`` :math:`(B, S, H, W)`.
        bent_normals: also return unit view-space bent normals (0 on background): the clear sectors' centre
            directions weighted by their cosine shares and ``|proj n|``, as GTAO's Algorithm 2 weights its arc.

    Returns:
        :class:`AOResult` with ``ao`` :math:`(B, 1, H, W)` in [0, 1], 1 on background.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 30.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n, mask=torch.ones(1, 1, 6, 8, dtype=torch.bool))
        >>> round(float(vbao(g).ao.min()), 2)       # a wall facing the camera: the tangent sectors (module docstring)
        0.93
    """
    check_inputs(gbuffer, params)
    cam, mask = gbuffer.camera, gbuffer.mask
    B, _, H, W = gbuffer.view_z.shape
    dtype, dev = gbuffer.view_z.dtype, gbuffer.view_z.device
    noise = noise_buffer(params, B, H, W, generator).to(dtype=dtype, device=dev)   # (B, 2, H, W)
    z = torch.where(mask, gbuffer.view_z, torch.full_like(gbuffer.view_z, -cam.far))  # the depth texture
    rows = torch.arange(H, dtype=dtype, device=dev)
    tex = sample_texture(cam, z)      # (B, 3, H, W) texel view positions; z if compiled or with gradients
    parts = [vbao_rows(cam, tex, rows[rs], gbuffer.normal[:, :, rs], mask[:, :, rs], noise[:, :, rs], params, debug,
                       bent_normals) for rs in row_bands(H, W, band_samples(4 * params.steps), z.element_size(), batch=B)]
    vis = torch.cat([p[0] for p in parts], 2).clamp(0.0, 1.0)
    ao = torch.where(mask, vis, torch.ones_like(vis))
    extra = {"bits": torch.cat([p[1][0] for p in parts], 2),
             "slice_visibility": torch.cat([p[1][1] for p in parts], 2)} if debug else {}
    bent = None
    if bent_normals:
        b = unit3(tuple(torch.cat([p[2][j] for p in parts], 2) for j in range(3)))
        bent = torch.where(mask, torch.cat(b, 1), torch.zeros_like(gbuffer.normal))
    return AOResult(ao=ao, bent_normal=bent, debug=extra)


class VBAO(nn.Module):
    """:func:`vbao` as a module; ``VBAO(thickness=0.1)`` overrides fields of ``params``.

    Example:
        >>> VBAO(thickness=0.1).params.thickness
        0.1
    """

    def __init__(self, params: VBAOParams = VBAOParams(), **overrides) -> None:
        super().__init__()
        self.params = replace(params, **overrides) if overrides else params

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None, debug: bool = False,
                bent_normals: bool = False) -> AOResult:
        return vbao(gbuffer, self.params, generator=generator, debug=debug, bent_normals=bent_normals)


def samples_per_pixel(params) -> int:
    """Depth texels read per pixel (one per sample, both sides of every slice): the floor's gather count
    (:func:`ssbench.bench.effects.ao_samples`)."""
    return int(2 * params.slices * params.steps)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("vbao", vbao, VBAOParams, VBAO, order=50,
                title="visibility-bitmask AO, VBAO (Therrien et al. 2023)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"radius": 0.5, "slices": [2, 4], "steps": [4, 8]},
                        {"radius": 0.5, "thickness": [0.05, 1.0]}],
               "blur": [{"radius": 0.5}]}
SPEED_PANELS = (SpeedPanel("halos", "thickness", (("blur", None), ("slices", 4), ("steps", 8))),)
