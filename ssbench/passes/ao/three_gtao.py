"""three.js ``GTAOPass``'s AO shader (``GTAOShader``, three.js ``examples/jsm/shaders/GTAOShader.js``),
transliterated: the view-space GTAO variant three.js users ship, scored like the other AO passes, and proven equal
to the shader itself, run in headless Chromium (``ssbench/PARITY.md``).

Unlike :mod:`.gtao` (Jimenez et al.'s screen-space slices, XeGTAO), it marches in *view space*. Per pixel:

1. ``viewPos`` from the depth buffer (``P⁻¹ · (2(uv, d) − 1, 1)``, divided by ``w``); ``viewNormal``; the noise
   texel (a ``5 × 5`` magic-square tile of angles, ``REPEAT``) turns a frame ``(t, b, (0, 0, 1))`` about view z.
2. ``DIRECTIONS = 3`` (5 from 30 samples) directions at angles ``iπ/DIRECTIONS`` in that frame; for each, the
   slice through the view direction, the normal projected into it, and the two horizon cosines starting at the
   normal's tangent (``cosHorizons``).
3. ``STEPS = ⌈SAMPLES / DIRECTIONS⌉`` view-space offsets ``radius · w · ((j + 1)/STEPS)^distanceExponent`` on each
   side; each is projected, its depth fetched (``NEAREST``) and unprojected; a sample within ``thickness`` in view
   z raises its horizon by ``max(0, (cos − cosH) · mix(1, 2/(j + 2), distanceFallOff))``.
4. The slice's visibility, the cosine-weighted arc integral of Jimenez et al. (2016) with the projected normal:
   ``nx·½(acos h₂ − acos h₁ + sin h₁ cos h₁ − sin h₂ cos h₂) + ny·½(2 − cos²h₁ − cos²h₂)``; averaged, clamped to
   [0, 1], raised to ``scale``.

Where the shader is undefined, ours is not: a sample on the pixel's own texel (``normalize(0)``) raises nothing
(GLSL ``max(0, NaN)`` returns 0 on the GPU we test on), and the arc terms use cosines clamped to [−1, 1].
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import AOResult, check_positive, row_bands
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from ..registry import Method, SpeedPanel
from ..sampling import noise_lookup
from .three_gtao_band import band_frame, slice_visibility

FLAVOUR = "cosine"  # the ground-truth weighting it estimates (ssbench.reference.ao)
REQUIRES = ("view_z", "normal", "mask")
DEFAULTS_SOURCE = "three.js GTAOShader / GTAOPass defaults (radius 0.25, 16 samples, thickness 1, 5×5 magic-square noise)"
TUNABLE = {"radius": (0.1, 3.0, True), "thickness": (0.05, 2.0, True)}
#: the bands' rows: one (B, 3, h, W) vector of a band fills ``ssbench.passes.common.BLOCK_BYTES`` (eager, each of
#: the ~50 operations per sample is its own pass over the band: 1/8 of that made it 1.6× slower, measured at 640×360)
BAND_VECTORS = 1


@dataclass(frozen=True)
class ThreeGTAOParams:
    """Settings of :func:`three_gtao`, named after the shader's uniforms and defines.

    Args:
        radius: ``radius`` (view units). samples: ``SAMPLES`` (< 30: 3 directions, else 5).
        distance_exponent: ``distanceExponent`` (step spacing). thickness: ``thickness`` (view-z window).
        distance_fall_off: ``distanceFallOff`` (0: a sample sets the horizon; 1: later samples weigh less).
        scale: ``scale`` (``ao = ao^scale``). noise_size: the magic-square tile side (odd; ``GTAOPass`` uses 5).
    """

    radius: float = 0.25
    samples: int = 16
    distance_exponent: float = 1.0
    thickness: float = 1.0
    distance_fall_off: float = 1.0
    scale: float = 1.0
    noise_size: int = 5

    def __post_init__(self) -> None:
        for name in ("radius", "distance_exponent", "thickness", "scale"):
            check_positive(getattr(self, name), name)
        check_positive(self.distance_fall_off, "distance_fall_off", allow_zero=True)
        if self.distance_fall_off > 1:
            raise ValueError(f"distance_fall_off: must lie in [0, 1], got {self.distance_fall_off!r}")
        for name in ("samples", "noise_size"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name}: must be an integer >= 1, got {v!r}")

    @property
    def directions(self) -> int:
        """``DIRECTIONS``: 3, or 5 from 30 samples."""
        return 3 if self.samples < 30 else 5

    @property
    def steps(self) -> int:
        """``STEPS = ⌈SAMPLES / DIRECTIONS⌉`` per side of each direction."""
        return (self.samples + self.directions - 1) // self.directions


def magic_square(size: int) -> list[int]:
    """The odd-order magic square ``GTAOPass`` builds its noise from (an even ``size`` becomes ``size + 1``): the
    Siamese construction started in the middle row of the last column, moving one column right and one row up,
    one column left instead when the cell is taken; row-major values ``1 … size²``.

    Example:
        >>> magic_square(3)
        [2, 7, 6, 9, 5, 1, 4, 3, 8]
    """
    n = size + 1 if size % 2 == 0 else size
    square = [0] * (n * n)
    i, j, num = n // 2, n - 1, 1
    while num <= n * n:
        if i == -1 and j == n:
            i, j = 0, n - 2
        else:
            j = 0 if j == n else j
            i = n - 1 if i < 0 else i
        if square[i * n + j]:
            i, j = i + 1, j - 2
            continue
        square[i * n + j] = num
        num, i, j = num + 1, i - 1, j + 1
    return square


def noise_tile(size: int = 5) -> torch.Tensor:
    """``GTAOPass``'s noise tile as the shader reads it: :math:`(4, n, n)` in [0, 1], row 0 at the *bottom* (as
    uploaded), from 8-bit texels ``(cos a · ½ + ½)·255``, ``(sin a · ½ + ½)·255``, 127, 255 with ``a = 2π·m/n²``."""
    sq = magic_square(size)
    n = int(math.isqrt(len(sq)))
    out = torch.empty(4, n * n, dtype=torch.float64)
    for k, m in enumerate(sq):
        a = 2 * math.pi * m / (n * n)
        c, s = math.cos(a), math.sin(a)
        norm = math.hypot(c, s)
        out[:, k] = torch.tensor([math.trunc((c / norm * 0.5 + 0.5) * 255), math.trunc((s / norm * 0.5 + 0.5) * 255),
                                  127, 255], dtype=torch.float64) / 255.0
    return out.reshape(4, n, n)


@autograd_free
@half_in_float32
def three_gtao(gbuffer: GBuffer, params: ThreeGTAOParams = ThreeGTAOParams(), *,
               generator: Optional[torch.Generator] = None, debug: bool = False) -> AOResult:
    """three.js ``GTAOShader`` on a G-buffer (see the module docstring); ``generator`` is unused (fixed noise).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 100.0)
        >>> z, n = torch.full((1, 1, 6, 8), -2.0), torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> out = three_gtao(GBuffer(cam, view_z=z, normal=n, mask=z < 0))
        >>> round(float(out.ao.min()), 4)                         # a flat wall facing the eye: unoccluded
        1.0
    """
    if not isinstance(params, ThreeGTAOParams):
        raise TypeError(f"params: expected ThreeGTAOParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES)
    cam, p = gbuffer.camera, params
    z = gbuffer.view_z
    B, _, H, W = z.shape
    dt, dev = z.dtype, z.device
    proj = cam.projection_matrix(dtype=dt, device=dev)
    minv = cam.inverse_projection_matrix(dtype=dt, device=dev)
    depth = cam.view_z_to_depth(z)                                                  # (B, 1, H, W)
    uv = cam.uv_grid(dt, dev).unsqueeze(0).expand(B, -1, -1, -1)                  # vUv (v up)
    normal = gbuffer.normal.to(dt)
    tile = noise_tile(p.noise_size).to(dt).to(dev)                                # (4, n, n), GL rows
    n_tile = tile.shape[-1]
    nu = torch.floor(torch.frac(uv[:, 0] * W / n_tile) * n_tile).long().clamp(0, n_tile - 1)
    nv = torch.floor(torch.frac(uv[:, 1] * H / n_tile) * n_tile).long().clamp(0, n_tile - 1)
    noise = noise_lookup(tile, nv, nu).permute(1, 0, 2, 3)                       # (B, 4, H, W)
    # ---- the image in bands of rows: intermediates stay O(band), not O(image) ----
    directions = p.directions
    rotations = [torch.tensor([math.cos(i / directions * math.pi), math.sin(i / directions * math.pi)], dtype=dt,
                              device=dev) for i in range(directions)]
    bands = []
    for rs in row_bands(H, W, BAND_VECTORS, z.element_size(), batch=B):
        frame = band_frame(minv, uv[:, :, rs], depth[:, :, rs], normal[:, :, rs], noise[:, :, rs])
        ao = torch.zeros_like(frame.w)                                            # (B, h, W)
        for rotation in rotations:
            ao = ao + slice_visibility(frame, depth, proj, minv, rotation, p)
        bands.append(ao)
    ao = (torch.cat(bands, 1) / directions).clamp(0.0, 1.0).nan_to_num(1.0) ** p.scale
    ao = torch.where(gbuffer.mask, ao.unsqueeze(1), torch.ones_like(ao).unsqueeze(1))
    return AOResult(ao=ao, debug={"noise": tile} if debug else {})


class ThreeGTAO(nn.Module):
    """``nn.Module`` wrapper of :func:`three_gtao`."""

    def __init__(self, params: ThreeGTAOParams = ThreeGTAOParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None) -> AOResult:
        return three_gtao(gbuffer, self.params, generator=generator, debug=self.debug)


def samples_per_pixel(params) -> int:
    """Depth texels the main loop reads per pixel (both sides of every step of every direction)."""
    return int(2 * params.directions * params.steps)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("three_gtao", three_gtao, ThreeGTAOParams, ThreeGTAO, order=60,
                title="three.js GTAOPass shader (view-space GTAO)")
SPEED_GRIDS = {"cost": [{"radius": 0.5, "samples": [8, 16, 32]}]}
SPEED_PANELS = (SpeedPanel("halos", "samples", (("blur", None), ("radius", 0.5))),)
