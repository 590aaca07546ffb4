"""Horizon-Based Ambient Occlusion (Bavoil & Sainz 2008), transcribed from the SSAO article (§3).

The pass follows the article's shader (§3.3) function by function: ``viewPos``/``uvToView`` with
``UvToViewParams``, ``diskRadiusInUV = 0.5·R·FocalLength/−P.z``, ``dPdu``/``dPdv`` by ``minDiff``,
``calculateNumSteps`` (with ``MaxRadiusPixels`` and the dithered step count), ``rotateDirections``,
``snapUVOffset``, ``getBiasedTangent`` (``TanAngleBias``), ``integrateOcclusion`` for the first sample and
``calculateHorizonOcclusion``'s horizon march, ``W(r) = 1 − r²/R²`` (§3.1), ``TanToSin`` and
``ao = 1 − ao/NUM_DIRECTIONS·AOStrength``. The 2-pass cross-bilateral blur of §3.2 is a separate pass.

**What it estimates.** Per image-plane direction φ the march finds the horizon elevation ``h(φ)`` of the depth
buffer, treated as a height field (everything behind the first surface is solid), above the pixel's
depth-derived tangent ``t(φ)``. Elevations are measured from the view-space xy plane (the hemisphere axis is
view +z, not the pixel's ray or normal). Each rise of the horizon from ``h_{i−1}`` to ``h_i`` adds
``W(r_i)·(sin h_i − sin h_{i−1})``, with ``r_i`` the distance to the sample that raised it. With ``W ≡ 1``,
``(1/2π)∫(sin h − sin t) dφ`` is the solid-angle fraction of the hemisphere above the tangent plane hidden by
the height field within ``R``: **uniform** (not cosine) weighting. The closest ground truth is therefore
``ssbench.reference.ambient_occlusion(..., weighting="obscurance")`` (uniform solid angle, ``1 − ρ(t)`` with
``ρ = 1 − (t/R)²``), with these known differences: ``W`` is taken at the horizon sample's distance, not at each
ray's hit distance; hidden geometry is assumed solid; the bias drops occluders whose slope is within
``TanAngleBias`` of the tangent's slope (and counts the rest only above that); directions are ``D`` evenly
spaced image-plane angles with a per-pixel random rotation; ``AOStrength`` rescales the result, which is
clamped to [0, 1].

Follows the article's code literally, including two details that differ from NVIDIA's sample:
``round(x)`` is ``floor(x + 0.5)``, and after the first sample the loop runs while ``j < numSteps − 1``,
so an integer ``numSteps = N`` marches ``N − 1`` samples per direction (``debug["samples"]``); ``MAX_STEPS``
is ``num_steps``. Texture reads are ``NEAREST``/``CLAMP_TO_EDGE`` as in the shader, so rays leaving the image
see a fake wall at the edge depth (pixels within ``radiusInPixels`` of an edge can darken). The bias does
not remove all planar self-occlusion: ``snapUVOffset(randstep·dUv)`` starts the march off the image direction
of ``T``, which leaves ~1 % on a few pixels of a floor seen at a steep slope.
The noise is a tiled ``noise_size²`` texture of ``(cos α, sin α, jitter)``, ``α = 2π·U/NUM_DIRECTIONS``
(NVIDIA's random texture), read at ``[row % N, col % N]``; the jitter dithers the step count and offsets the
start of every ray.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import AOResult, check_count, check_radius, make_generator, row_bands
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from ..sampling import noise_lookup
from .hbao_horizons import hbao_band, texel_view_z
from ..registry import Method, SpeedPanel

FLAVOUR = "obscurance"  # the ground-truth weighting this pass estimates (ssbench.reference.ao)
#: continuous parameters ``ssbench tune`` may fit: name -> (lo, hi, relative to the ground-truth radius)
TUNABLE = {"radius": (0.25, 3.0, True), "tan_angle_bias": (0.0, 1.0, False),
           "ao_strength": (0.5, 2.5, False)}
#: the report's tuning section fits this method
TUNED_IN_REPORT = True
#: where the defaults come from (shown by the report next to the parameters)
DEFAULTS_SOURCE = ("NVIDIA's HBAO sample as ported by scanberg/hbao (6 directions × 6 steps, R 0.3, tangent bias 30°; "
                   'Bavoil & Sainz, "Image-Space Horizon-Based Ambient Occlusion", SIGGRAPH 2008)')
REQUIRES = ("view_z", "mask")
POSITION_FROM = ("depth", "view_z")


@dataclass(frozen=True)
class HBAOParams:
    """Parameters of :func:`hbao`, the article's names snake-cased (defaults: scanberg/hbao, NVIDIA's sample).

    Attributes:
        radius: ``R``, the view-space radius of the sampled disk (scene units).
        max_radius_pixels: ``MaxRadiusPixels``, the largest screen footprint of a ray, in pixels.
        num_directions: ``NUM_DIRECTIONS``.
        num_steps: ``NUM_STEPS``, the most samples per direction.
        tan_angle_bias: ``TanAngleBias``, added to the tangent's slope (default ``tan 30°``).
        ao_strength: ``AOStrength`` in ``1 − ao·AOStrength``.
        noise_size: side of the tiled noise texture (4 in the article).
        seed: seeds the noise texture when no generator is passed.
        position_from: ``"depth"`` (``perspectiveDepthToViewZ`` of the GL depth buffer, as the article) or
            ``"view_z"`` (the G-buffer's view z, no depth round trip).
    """

    radius: float = 0.3
    max_radius_pixels: float = 100.0
    num_directions: int = 6
    num_steps: int = 6
    tan_angle_bias: float = math.tan(math.radians(30.0))
    ao_strength: float = 1.0
    noise_size: int = 4
    seed: int = 0
    position_from: str = "depth"

    def __post_init__(self) -> None:
        check_radius(self.radius, "radius")
        check_radius(self.max_radius_pixels, "max_radius_pixels")
        for name in ("num_directions", "num_steps", "noise_size"):
            check_count(getattr(self, name), name)
        for name in ("tan_angle_bias", "ao_strength"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name}: must be a finite number, got {v!r}")
        if self.ao_strength < 0:
            raise ValueError(f"ao_strength: must be >= 0, got {self.ao_strength!r}")
        if self.position_from not in POSITION_FROM:
            raise ValueError(f"position_from: expected one of {POSITION_FROM}, got {self.position_from!r}")


def noise_texture(params: HBAOParams, generator: torch.Generator) -> torch.Tensor:
    """:math:`(3, N, N)` float64 ``(cos α, sin α, jitter)`` with ``α = 2π·U/NUM_DIRECTIONS``, jitter ``U[0, 1)``.

    One ``torch.rand`` call on ``generator``; the teaching twin calls this too, so both see the same noise.
    """
    n = params.noise_size
    r = torch.rand(2, n, n, generator=generator, dtype=torch.float64)        # (2, N, N)
    angle = 2.0 * math.pi * r[0] / params.num_directions
    return torch.stack([torch.cos(angle), torch.sin(angle), r[1]], 0)


def check_inputs(gbuffer: GBuffer, params: HBAOParams) -> None:
    """Type checks of ``params`` and the shared G-buffer contract (:func:`~ssbench.passes.gbuffer_checks.check_gbuffer`)."""
    if not isinstance(params, HBAOParams):
        raise TypeError(f"params: expected HBAOParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES)


@autograd_free
@half_in_float32
def hbao(gbuffer: GBuffer, params: HBAOParams = HBAOParams(), *, generator: Optional[torch.Generator] = None,
         debug: bool = False) -> AOResult:
    """Horizon-based ambient occlusion of a G-buffer (SSAO article §3.3, vectorised over pixels and directions).

    .. math::
        AO = 1 - \\frac{s}{D}\\sum_{d=1}^{D} \\sum_i W(r_i)\\,(\\sin h_i - \\sin h_{i-1}),
        \\qquad W(r) = 1 - r^2/R^2, \\quad \\tan h_0 = \\tan t + \\text{TanAngleBias}

    Args:
        gbuffer: needs ``view_z`` :math:`(B, 1, H, W)` and ``mask`` :math:`(B, 1, H, W)` bool.
        params: :class:`HBAOParams`.
        generator: draws the noise texture (default: a CPU generator seeded with ``params.seed``).
        debug: also return ``num_steps`` :math:`(B, 1, H, W)` (``calculateNumSteps``), ``samples``
            :math:`(B, 1, H, W)` (depth samples per direction), ``horizons`` :math:`(B, D, H, W)` (final horizon
            elevation ``atan(tanH)`` in radians, 0 where skipped) and ``radius_pixels`` :math:`(B, 1, H, W)`.

    Returns:
        :class:`AOResult` with ``ao`` :math:`(B, 1, H, W)` in [0, 1]; 1 on background and where
        ``radiusInPixels ≤ 1``.

    Raises:
        ValueError: missing channels, bad shapes, dtypes or values (the message names the argument).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), mask=torch.ones(1, 1, 6, 8, dtype=torch.bool))
        >>> r = hbao(g, HBAOParams(radius=1.0))
        >>> r.ao.shape, bool((r.ao == 1).all())         # a wall facing the camera is unoccluded
        (torch.Size([1, 1, 6, 8]), True)
    """
    check_inputs(gbuffer, params)
    cam, view_z, mask = gbuffer.camera, gbuffer.view_z, gbuffer.mask
    B, _, H, W = view_z.shape
    D, dtype, dev = params.num_directions, view_z.dtype, view_z.device
    g = make_generator(params.seed, generator)
    noise = noise_texture(params, g).to(dtype=dtype, device=dev)                 # (3, N, N)

    z_tex = texel_view_z(cam, view_z, params.position_from)                     # DepthSampler, read back
    rows_n = torch.arange(H, device=dev) % params.noise_size
    cols_n = torch.arange(W, device=dev) % params.noise_size
    uv_grid = cam.uv_grid(dtype, dev)

    # ---- the image in bands of rows: intermediates stay O(block), not O(D·H·W) ----
    parts = [hbao_band(cam, uv_grid[:, rs].unsqueeze(0).expand(B, -1, -1, -1), mask[:, :, rs],
                       noise_lookup(noise, rows_n[rs, None], cols_n).unsqueeze(0), z_tex, params, debug)
             for rs in row_bands(H, W, D, view_z.element_size(), batch=B)]
    out = torch.cat([o for o, _ in parts], 2)
    dbg = {k: torch.cat([d[k] for _, d in parts], -2) for k in parts[0][1]}
    return AOResult(ao=out, debug=dbg)


class HBAO(nn.Module):
    """``nn.Module`` wrapper of :func:`hbao`; ``forward(gbuffer)`` returns its :class:`AOResult`."""

    def __init__(self, params: HBAOParams = HBAOParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> AOResult:
        return hbao(gbuffer, self.params, generator=generator, debug=self.debug)


def samples_per_pixel(params) -> int:
    """Depth texels the main loop reads per pixel (one depth texel per step of every direction): the floor's gather count
    (:func:`ssbench.bench.effects.ao_samples`)."""
    return int(params.num_directions * params.num_steps)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("hbao", hbao, HBAOParams, HBAO, order=30, title="horizon-based AO, HBAO (Bavoil et al. 2008)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"radius": 0.5, "num_directions": [4, 8], "num_steps": [3, 6]}],
               "blur": [{"radius": 0.5, "num_directions": 8, "num_steps": 6}]}
SPEED_PANELS = (SpeedPanel("banding", "num_directions", (("blur", None),)),
                SpeedPanel("halos", "blur", (("num_directions", 8), ("num_steps", 6))))
