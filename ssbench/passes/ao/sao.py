r"""Scalable Ambient Obscurance, SAO (McGuire, Mara, Luebke, "Scalable Ambient Obscurance", High-Performance
Graphics 2012, https://research.nvidia.com/publication/2012-06_scalable-ambient-obscurance), as the paper's
listing writes it: the Alchemy AO estimator (McGuire et al., "The Alchemy Screen-Space Ambient Obscurance
Algorithm", HPG 2011) with a depth MIP pyramid, so a wide radius reads nearby texels of a coarser level
instead of scattered texels of the full image — the cost per pixel stays flat as the radius grows.

Per pixel ``ssC`` (integer, ``y`` up as ``gl_FragCoord``; the pieces are in :mod:`.sao_parts`):

1. ``C`` = the camera-space position from depth; ``n_C`` the face normal from the 2×2 quad's depth derivatives
   (``normals="depth"``, the paper) or the G-buffer normal (``normals="gbuffer"``, as three.js ``SAOPass`` and
   G3D's deep-G-buffer variant read it);
2. ``ssDiskRadius = −projScale·radius / C.z`` pixels, with ``projScale`` the pixels per unit at ``z = −1``;
3. for ``i < NUM_SAMPLES`` taps on a spiral of ``NUM_SPIRAL_TURNS`` turns rotated by the per-pixel hash angle:
   ``ssR = α_i·ssDiskRadius``, the tap ``ssP = ssC + int(ssR·unitOffset)`` read at MIP level
   ``clamp(⌊log₂ ssR⌋ − LOG_MAX_OFFSET, 0, MAX_MIP_LEVEL)`` (texel ``ssP >> level``), ``Q`` its position, and
   with ``v = Q − C``:

   .. math:: \mathrm{sum} \mathrel{+}= \max(r^2 - v\cdot v, 0)^3 \cdot \max\Big(\frac{v\cdot n_C - \beta}{v\cdot v + \epsilon}, 0\Big)

4. ``A = max(0, 1 − sum · intensity / r⁶ · 5 / NUM_SAMPLES)``, then the listing's free 2×2 quad filter.

**What it estimates.** Alchemy AO is an estimator of *obscurance* with a falloff: each tap's ``v·n/|v|²`` is
a cosine over distance (cosine-weighted occluder coverage, projected to the tap's distance), and ``(r² −
|v|²)³/r⁶`` fades it to 0 at the radius; ``intensity`` scales the sum, and nothing normalises it to a visibility
fraction. It is scored against the cosine flavour (``FLAVOUR``) and is expected to sit off it by a scale the
tuner can fit (``intensity``). Background pixels are 1. Taps off screen read the clamped edge texel at their own
(unclamped) position, as the shader does.

**Which defaults.** The paper's listing: 11 samples, 7 spiral turns, ``LOG_MAX_OFFSET`` 3, ``MAX_MIP_LEVEL`` 5,
``ε = 0.01``, the bias comment's 0.01 units, intensity 1; the radius is the report's equal 0.5 (the listing's
example is 1 m).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import AOResult, check_count, check_positive, check_radius, cross, index_dtype, row_bands, vector_norm
from ..compiled import kernel
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from ..registry import Method, SpeedPanel
from .sao_parts import (depth_mips, gl_rows, mip_level, pixels_per_meter, quad_filter, spin_angle,
                        tap_location)

FLAVOUR = "cosine"  # the ground-truth weighting it is scored against (see the module docstring)
REQUIRES = ("view_z", "normal", "mask")
NORMALS = ("depth", "gbuffer")
#: continuous parameters ``ssbench tune`` may fit: name -> (lo, hi, relative to the ground-truth radius)
TUNABLE = {"radius": (0.25, 3.0, True), "intensity": (0.25, 4.0, False), "bias": (0.0, 0.1, False)}
DEFAULTS_SOURCE = ('McGuire, Mara & Luebke, "Scalable Ambient Obscurance", HPG 2012, the paper\'s listing: 11 samples, '
                   "7 spiral turns, LOG_MAX_OFFSET 3, MAX_MIP_LEVEL 5, bias 0.01, intensity 1; radius 0.5 (report's equal setting)")
EPSILON = 0.01           #: the listing's ``epsilon`` in the tap's denominator
#: the bands' rows: one :math:`(B, 3, h, W)` vector of a band fills ``ssbench.passes.common.BLOCK_BYTES`` (eager, a
#: tap's dozen integer and float planes of the whole image left the cache at 1080p: 2× the ns per pixel of 320×240)
BAND_VECTORS = 1


@dataclass(frozen=True)
class SAOParams:
    """Parameters of :func:`sao`, named after the listing's constants and uniforms.

    Attributes:
        num_samples: ``NUM_SAMPLES``, taps per pixel.
        num_spiral_turns: ``NUM_SPIRAL_TURNS`` (prime, so taps do not line up).
        radius: ``radius`` (view-space units).
        bias: ``bias`` (β), subtracted from ``v·n`` against self-occlusion on smooth surfaces.
        intensity: ``intensity`` (``intensityDivR6 = intensity / r⁶``).
        log_max_offset: ``LOG_MAX_OFFSET``; max_mip_level: ``MAX_MIP_LEVEL``.
        use_mips: read coarser levels for far taps (``False``: every tap at level 0, the ablation that shows
            what the pyramid changes).
        normals: ``"depth"`` (quad derivatives, the paper) or ``"gbuffer"``.
        quad_filter: apply the listing's 2×2 quad filter.
    """

    num_samples: int = 11
    num_spiral_turns: int = 7
    radius: float = 0.5
    bias: float = 0.01
    intensity: float = 1.0
    log_max_offset: int = 3
    max_mip_level: int = 5
    use_mips: bool = True
    normals: str = "depth"
    quad_filter: bool = True

    def __post_init__(self) -> None:
        for name in ("num_samples", "num_spiral_turns"):
            check_count(getattr(self, name), name)
        for name in ("log_max_offset", "max_mip_level"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 16:
                raise ValueError(f"{name}: must be an integer in [0, 16], got {v!r}")
        check_radius(self.radius, "radius")
        check_positive(self.bias, "bias", allow_zero=True)
        check_positive(self.intensity, "intensity")
        if self.normals not in NORMALS:
            raise ValueError(f"normals: expected one of {NORMALS}, got {self.normals!r}")
        for name in ("use_mips", "quad_filter"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name}: expected a bool, got {getattr(self, name)!r}")


def _quad_diff(c: torch.Tensor, dim: int) -> torch.Tensor:
    """``dFdx``-style difference within pixel pairs ``(2k, 2k + 1)`` along ``dim`` (the same for both; an odd
    last pixel takes its backward difference)."""
    n = c.shape[dim]
    idx = torch.arange(n, device=c.device)
    even = idx - (idx & 1)
    odd = torch.where(even + 1 < n, even + 1, idx)
    even = torch.where(even + 1 < n, even, (idx - 1).clamp(min=0))
    return c.index_select(dim, odd) - c.index_select(dim, even)


@kernel
def quad_derivatives(position: torch.Tensor) -> tuple:
    """``(dFdx(C), dFdy(C))`` of :math:`(B, 3, H, W)` positions (exact differences: compiled, the same bits)."""
    return _quad_diff(position, 3), _quad_diff(position, 2)


@kernel
def unit_or_zero(n: torch.Tensor) -> torch.Tensor:
    """``n / |n|`` over dim 1, 0 where ``|n|`` is 0 or not finite (compiled: inductor's norm and division are
    ATen's bit for bit)."""
    norm = vector_norm(n)
    ok = torch.isfinite(norm) & (norm > 0)
    return torch.where(ok, n / torch.where(ok, norm, torch.ones_like(norm)), torch.zeros_like(n))


def face_normals(position: torch.Tensor) -> torch.Tensor:
    """``reconstructCSFaceNormal``: unit ``cross(dFdx(C), dFdy(C))`` of :math:`(B, 3, H, W)` camera-space
    positions in GL rows (``y`` up), so a surface facing the camera gets ``+z``; 0 where degenerate or
    overflowed. The cross product stays eager: ATen computes each component as one FMA, which inductor's C++
    does not, and the quad's nearly parallel differences would magnify that ulp."""
    dx, dy = quad_derivatives(position)
    return unit_or_zero(cross(dx, dy, dim=1))


#: the largest screen-space disk radius (pixels) for which the tap loop's integer work runs in int32 when eager: a
#: tap's pixel ``trunc(ssR·cos) + x`` then stays far inside int32's range
INT32_TAP_RADIUS = 2.0 ** 30


@kernel
def sao_taps(c: tuple, n: tuple, spin: torch.Tensor, ss_disk: torch.Tensor, xy: tuple, mips: torch.Tensor,
             uv_to_view: tuple, size: tuple, p: "SAOParams", debug: bool) -> tuple:
    """The listing's tap loop (``sampleAO`` summed over ``NUM_SAMPLES``) on a band of ``h`` rows, one tap at a
    time, per component (the pass's compilable kernel, :mod:`ssbench.passes.compiled`).

    Args:
        c: ``C``'s x, y, z :math:`(B, 1, h, W)` (GL rows); n: ``n_C``'s :math:`(B, 1, h, W)` components.
        spin: :math:`(1, 1, h, W)` pattern angle; ss_disk: :math:`(B, 1, h, W)` ``ssDiskRadius`` in pixels.
        xy: integer pixel ``x`` and ``y`` :math:`(1, 1, h, W)` (full size: one loop nest when compiled).
        mips: the pyramid :math:`(B, L·H·W)`: level ``l`` in the top-left corner of the ``l``-th ``H × W`` layer
            (so a tap needs no table of level sizes and starts).
        uv_to_view: ``(A₀, A₁, B₀, B₁)`` of :meth:`~ssbench.camera.Camera.uv_to_view_params`.
        size: the image's ``(H, W)``.

    Returns:
        ``(sum, levels)``: :math:`(B, 1, h, W)` the taps' sum and, with ``debug``, :math:`(B, N, h, W)` int8 the
        level each tap read (else ``None``).
    """
    (cx, cy, cz), (nx, ny, nz), (x, y) = c, n, xy
    flat, (H, W), B = mips, size, cz.shape[0]
    a0, a1, b0, b1 = uv_to_view
    r2 = p.radius * p.radius
    total = torch.zeros_like(cz)
    levels = []
    # eager, the integer work runs in int32 where no tap can leave its range (int64 arithmetic and conversions ran
    # 2-4x slower here, and ``gather`` takes int64 only): the same integers, the same bits; compiled, int64
    narrow = (not torch.compiler.is_compiling() and cz.device.type != "meta"
              and index_dtype(flat.numel()) == torch.int32
              and bool((ss_disk.abs() < INT32_TAP_RADIUS).all()))                 # NaN or ±inf: int64
    it = torch.int32 if narrow else torch.long
    x, y = x.to(it), y.to(it)
    image = None                                                                  # each image's layer offset
    if narrow and B > 1:
        image = (torch.arange(B, dtype=it, device=cz.device) * flat.shape[1]).view(B, 1, 1, 1)
    for i in range(p.num_samples):
        ux, uy, alpha = tap_location(i, p.num_samples, p.num_spiral_turns, spin)
        ss_r = alpha * ss_disk
        lv = mip_level(ss_r, p.log_max_offset, p.max_mip_level, it) if p.use_mips else torch.zeros_like(cz, dtype=it)
        px = torch.trunc(ss_r * ux).to(it) + x
        py = torch.trunc(ss_r * uy).to(it) + y
        w_l = torch.bitwise_right_shift(W, lv).clamp(min=1)                       # level lv's size
        h_l = torch.bitwise_right_shift(H, lv).clamp(min=1)
        tx = torch.minimum(torch.bitwise_right_shift(px, lv).clamp(min=0), w_l - 1)
        ty = torch.minimum(torch.bitwise_right_shift(py, lv).clamp(min=0), h_l - 1)
        texel = (lv * H + ty) * W + tx                                            # in level lv's layer
        if narrow:
            zq = flat.reshape(-1).index_select(0, (texel if image is None else texel + image).reshape(-1)).view_as(cz)
        else:
            zq = torch.gather(flat, 1, texel.reshape(B, -1)).view_as(cz)
        vx = (a0 * ((px.to(cz.dtype) + 0.5) / W) + b0) * zq - cx                       # v = Q − C
        vy = (a1 * ((py.to(cz.dtype) + 0.5) / H) + b1) * zq - cy
        vz = zq - cz
        vv = vx * vx + vy * vy + vz * vz
        vn = vx * nx + vy * ny + vz * nz
        f = (r2 - vv).clamp(min=0.0)
        tap = f * f * f * ((vn - p.bias) / (EPSILON + vv)).clamp(min=0.0)
        total = total + torch.where(f > 0, tap, 0.0)      # out of reach (or overflowed): 0
        if debug:
            levels.append(lv.to(torch.int8))
    return total, (torch.cat(levels, 1) if debug else None)


@autograd_free
@half_in_float32
def sao(gbuffer: GBuffer, params: SAOParams = SAOParams(), *, generator: Optional[torch.Generator] = None,
        debug: bool = False) -> AOResult:
    """Scalable Ambient Obscurance of a G-buffer (module docstring), vectorised over pixels, one tap at a time.

    Args:
        gbuffer: ``view_z`` :math:`(B, 1, H, W)`, ``normal`` :math:`(B, 3, H, W)` (read when
            ``normals="gbuffer"``) and ``mask`` :math:`(B, 1, H, W)` bool.
        params: :class:`SAOParams`.
        generator: unused (the pattern is the paper's per-pixel hash); accepted like every pass's.
        debug: also return ``mip_level`` :math:`(B, N, H, W)` int8 (the level each tap read) and ``normal``
            :math:`(B, 3, H, W)` (the ``n_C`` used, view space, image rows).

    Returns:
        :class:`AOResult` with ``ao`` :math:`(B, 1, H, W)` in [0, 1], 1 on background.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 30.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n, mask=torch.ones(1, 1, 6, 8, dtype=torch.bool))
        >>> float(sao(g).ao.min())                                   # a flat wall: no tap above its plane
        1.0
    """
    if not isinstance(params, SAOParams):
        raise TypeError(f"params: expected SAOParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES)
    cam, p = gbuffer.camera, params
    B, _, H, W = gbuffer.view_z.shape
    dtype, dev = gbuffer.view_z.dtype, gbuffer.view_z.device
    z = gl_rows(torch.where(gbuffer.mask, gbuffer.view_z, torch.full_like(gbuffer.view_z, -cam.far)))
    x = torch.arange(W, device=dev).view(1, 1, 1, W)
    y = torch.arange(H, device=dev).view(1, 1, H, 1)
    a0, a1, b0, b1 = cam.uv_to_view_params()
    u, v = (x.to(dtype) + 0.5) / W, (y.to(dtype) + 0.5) / H
    c = ((a0 * u + b0) * z, (a1 * v + b1) * z, z)                                   # reconstructCSPosition
    if p.normals == "depth":
        n = face_normals(torch.cat(torch.broadcast_tensors(*c), 1))
    else:
        n = gl_rows(gbuffer.normal)
    spin = spin_angle(x, y).to(dtype)
    ss_disk = -pixels_per_meter(cam) * p.radius / z
    mips = depth_mips(z, p.max_mip_level if p.use_mips else 0)
    pyramid = z.new_zeros(B, len(mips), H, W)                # level l in the corner of layer l: no size tables
    for level, m in enumerate(mips):
        pyramid[:, level, :m.shape[-2], :m.shape[-1]] = m[:, 0]
    texels = pyramid.reshape(B, -1)
    planes = (*c, *(n[:, k:k + 1] for k in range(3)), spin, ss_disk,
              x.expand(1, 1, H, W).contiguous(), y.expand(1, 1, H, W).contiguous())   # one loop nest compiled
    total, levels = torch.empty_like(z), []
    for rs in row_bands(H, W, BAND_VECTORS, z.element_size(), batch=B):      # a bounded working set
        band = [t[..., rs, :] for t in planes]
        total[..., rs, :], lv = sao_taps(tuple(band[0:3]), tuple(band[3:6]), band[6], band[7], tuple(band[8:10]),
                                         texels, (a0, a1, b0, b1), (H, W), p, debug)
        levels.append(lv)
    levels = torch.cat(levels, 2) if debug else None
    r2 = p.radius * p.radius
    a = (1.0 - total * (p.intensity / r2 ** 3) * (5.0 / p.num_samples)).clamp(min=0.0)
    if p.quad_filter:
        a = quad_filter(a, z)
    a = gl_rows(a)
    ao = torch.where(gbuffer.mask, a.clamp(max=1.0), torch.ones_like(a))
    extra = {"mip_level": gl_rows(levels), "normal": gl_rows(n)} if debug else {}
    return AOResult(ao=ao, debug=extra)


class SAO(nn.Module):
    """:func:`sao` as a module; ``SAO(radius=1.0)`` overrides fields of ``params``.

    Example:
        >>> SAO(num_samples=7).params.num_samples
        7
    """

    def __init__(self, params: SAOParams = SAOParams(), **overrides) -> None:
        super().__init__()
        self.params = replace(params, **overrides) if overrides else params

    def forward(self, gbuffer: GBuffer, generator: Optional[torch.Generator] = None,
                debug: bool = False) -> AOResult:
        return sao(gbuffer, self.params, generator=generator, debug=debug)


def samples_per_pixel(params) -> int:
    """Depth texels read per pixel (one per tap): the floor's gather count (:func:`ssbench.bench.effects.ao_samples`)."""
    return int(params.num_samples)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("sao", sao, SAOParams, SAO, order=45,
                title="scalable ambient obscurance, SAO (McGuire, Mara & Luebke 2012)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"radius": 0.5, "num_samples": [7, 11, 21]},
                        {"radius": [0.5, 2.0], "use_mips": [True, False]}],
               "blur": [{"radius": 0.5}]}
SPEED_PANELS = (SpeedPanel("banding", "num_samples", (("blur", None),)),)
