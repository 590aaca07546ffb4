"""XeGTAO's edge-aware spatial denoiser (``XeGTAO_CalculateEdges`` + ``XeGTAO_Denoise``), vectorised.

**Edges.** For a pixel at linear depth ``z = −view_z`` with neighbour differences ``Δ = (z_L, z_R, z_T, z_B) − z``,
the slopes ``s_LR = (Δ_R − Δ_L)/2`` and ``s_TB = (Δ_B − Δ_T)/2`` give slope-adjusted differences
``Δ' = Δ + (s_LR, −s_LR, s_TB, −s_TB)``, and

.. math::
    e = \\mathrm{sat}\\Big(1.25 - \\frac{\\min(|\\Delta|, |\\Delta'|)}{0.011\\,z}\\Big),

quantised to 2 bits as XeGTAO packs them (``round(sat(e)·2.9)/3`` ∈ {0, ⅓, ⅔, 1}). A plane (any slope) gives
``Δ' = 0`` → weight 1; a depth step of more than 1.25 % of ``z`` gives 0.

**Denoise.** Per pass, the centre's edges are made symmetric (``e_C *= (e_L.R, e_R.L, e_T.B, e_B.T)``), a pixel
with ≥ 1.5 edges cut (``Σe < 2.5``) leaks a little (``e += 0.5·sat(1.5 − Σe)/1.5``, XeGTAO's "small amount of AO
leaking"), and the 3×3 weighted mean is taken: cross weights ``e``, diagonal weights
``0.425·(e_C.L·e_L.T + e_C.T·e_T.L)`` (top-left; likewise the others, each from the two adjacent edge paths),
centre weight ``β`` on the last pass and ``β/5`` on earlier ones (XeGTAO ``DenoiseBlurBeta`` 1.2, ``DenoisePasses``
1). All weights are ≥ 0 and the centre's is > 0, so the output is a convex combination of the 3×3 inputs.

**Differences from XeGTAO.** (1) Background and off-screen neighbours get weight 0 (also after the leak), and the
slope adjustment on an axis is skipped when either neighbour on it is invalid (XeGTAO's far background makes
``|Δ'|`` huge there, so ``min`` picks ``|Δ|`` anyway; its clamp sampler would instead re-read the edge texel).
Background pixels stay 1. (2) This denoises the AO :func:`ssbench.passes.ao.gtao.gtao` *returns*, i.e. after
``pow(·, final_value_power)``, ``max(0.03, ·)`` and the saturate to [0, 1]. XeGTAO HEAD also applies the power in
the main pass, but stores the working term as ``sat(vis/1.5)`` so per-pixel overshoot above 1 survives into the
denoiser and averages out; here values above 1 have already been clipped, so the denoised mean of an unoccluded
surface is slightly below 1 wherever a neighbour read low.
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from ..compiled import kernel

_EDGE_BIAS = 1.25
_EDGE_SCALE = 0.011
_DIAG_WEIGHT = 0.85 * 0.5
_LEAK_THRESHOLD = 2.5
_LEAK_STRENGTH = 0.5


def _check_plane(t, name: str, ref=None) -> None:
    if not isinstance(t, torch.Tensor):
        raise ValueError(f"{name}: expected a torch.Tensor, got {type(t).__name__}")
    if t.dim() != 4 or t.shape[1] != 1:
        raise ValueError(f"{name}: expected shape (B, 1, H, W), got {tuple(t.shape)}")
    if ref is not None and (t.shape[0], *t.shape[2:]) != (ref.shape[0], *ref.shape[2:]):
        raise ValueError(f"{name}: shape {tuple(t.shape)} does not match view_z's {tuple(ref.shape)}")


def _check_inputs(view_z, mask) -> None:
    _check_plane(view_z, "view_z")
    if not view_z.is_floating_point():
        raise ValueError(f"view_z: expected a floating-point dtype, got {view_z.dtype}")
    _check_plane(mask, "mask", view_z)
    if mask.dtype != torch.bool:
        raise ValueError(f"mask: expected dtype torch.bool, got {mask.dtype}")


def _pad(x: torch.Tensor, fill=0) -> torch.Tensor:
    """``x`` with a border of one texel of ``fill`` (what a neighbour off screen reads)."""
    if x.dtype == torch.bool:
        return F.pad(x.to(torch.uint8), (1, 1, 1, 1), value=int(fill)).bool()
    return F.pad(x, (1, 1, 1, 1), value=fill)


def _at(xp: torch.Tensor, dx: int, dy: int) -> torch.Tensor:
    """``out[..., i, j] = x[..., i + dy, j + dx]`` of a :func:`_pad`-ded ``xp``: a slice, no copy."""
    H, W = xp.shape[-2] - 2, xp.shape[-1] - 2
    return xp[..., 1 + dy:1 + dy + H, 1 + dx:1 + dx + W]


_DIRS = ((-1, 0), (1, 0), (0, -1), (0, 1))      # left, right, top, bottom (screen rows go down)


def gtao_edges(view_z: torch.Tensor, mask: torch.Tensor, quantize: bool = True) -> torch.Tensor:
    """XeGTAO edge weights to the left/right/top/bottom neighbours, :math:`(B, 4, H, W)` in [0, 1].

    ``e = sat(1.25 − min(|Δz|, |Δz_slope-adj|)/(0.011·z))`` with ``z = −view_z`` (see the module docstring),
    quantised to {0, ⅓, ⅔, 1} unless ``quantize=False``. Background or off-screen neighbours, and every edge of
    a background pixel, get 0. Piecewise constant in ``view_z`` (no useful gradient).

    Example:
        >>> z = torch.full((1, 1, 3, 4), -2.0); z[..., 2:] = -5.0     # depth step between columns 1 and 2
        >>> e = gtao_edges(z, torch.ones_like(z, dtype=torch.bool))
        >>> e[0, :, 1, 1].tolist()                                       # L, R, T, B of pixel (1, 1)
        [1.0, 0.0, 1.0, 1.0]
    """
    _check_inputs(view_z, mask)
    return torch.cat(edge_planes.eager(*_padded_depth(view_z, mask), quantize), 1)


def _padded_depth(view_z: torch.Tensor, mask: torch.Tensor) -> tuple:
    """Padded ``z = −view_z`` (1 on background and off screen) and padded ``mask`` (False off screen)."""
    z = torch.where(mask, -view_z, torch.ones_like(view_z))           # finite stand-in on background
    return _pad(z, 1.0), _pad(mask, False)


@kernel
def edge_planes(zp: torch.Tensor, maskp: torch.Tensor, quantize: bool = True) -> tuple:
    """The four edge planes :math:`(B, 1, H, W)` (left, right, top, bottom) of :func:`gtao_edges` from
    :func:`_padded_depth`."""
    z, mask = _at(zp, 0, 0), _at(maskp, 0, 0)
    zn = [_at(zp, dx, dy) for dx, dy in _DIRS]
    ok = [_at(maskp, dx, dy) & mask for dx, dy in _DIRS]
    d = [n - z for n in zn]
    slope_lr = torch.where(ok[0] & ok[1], (d[1] - d[0]) * 0.5, torch.zeros_like(z))
    slope_tb = torch.where(ok[2] & ok[3], (d[3] - d[2]) * 0.5, torch.zeros_like(z))
    adj = (d[0] + slope_lr, d[1] - slope_lr, d[2] + slope_tb, d[3] - slope_tb)
    scale = _EDGE_SCALE * z.clamp_min(torch.finfo(z.dtype).tiny)
    out = []
    for a, b, k in zip(d, adj, ok):
        e = (_EDGE_BIAS - torch.minimum(a.abs(), b.abs()) / scale).clamp(0.0, 1.0)
        if quantize:
            e = torch.round(e * 2.9) / 3.0
        out.append(e * k.to(e.dtype))
    return tuple(out)


def gtao_denoise(ao: torch.Tensor, view_z: torch.Tensor, mask: torch.Tensor, passes: int = 1,
                 beta: float = 1.2) -> torch.Tensor:
    """XeGTAO's 3×3 edge-aware denoise of a GTAO buffer, ``passes`` times; :math:`(B, 1, H, W)`.

    Args:
        ao: :math:`(B, 1, H, W)` floating AO, e.g. ``gtao(g).ao`` (after the final power; see module docstring).
        view_z: :math:`(B, 1, H, W)` view-space depth, < 0 on geometry.
        mask: :math:`(B, 1, H, W)` bool geometry mask.
        passes: number of passes (XeGTAO ``DenoisePasses``, default 1; 0 returns ``ao`` with background = 1).
        beta: centre weight of the last pass (``DenoiseBlurBeta``); earlier passes use ``beta/5``.

    Returns:
        The denoised AO, 1 on background; differentiable in ``ao``.

    Raises:
        ValueError: bad shapes, dtypes or values (the message names the argument).

    Example:
        >>> z = torch.full((1, 1, 4, 4), -2.0); m = torch.ones_like(z, dtype=torch.bool)
        >>> bool(torch.allclose(gtao_denoise(torch.full_like(z, 0.7), z, m), torch.full_like(z, 0.7)))
        True
    """
    _check_plane(ao, "ao")
    if not ao.is_floating_point():
        raise ValueError(f"ao: expected a floating-point dtype, got {ao.dtype}")
    _check_plane(view_z, "view_z", ao)
    _check_inputs(view_z, mask)
    if isinstance(passes, bool) or not isinstance(passes, int) or passes < 0:
        raise ValueError(f"passes: expected an int >= 0, got {passes!r}")
    if isinstance(beta, bool) or not isinstance(beta, (int, float)) or not math.isfinite(beta) or beta <= 0:
        raise ValueError(f"beta: expected a finite number > 0, got {beta!r}")
    zp, maskp = _padded_depth(view_z, mask)
    edges = tuple(_pad(e.to(ao.dtype)) for e in edge_planes(zp, maskp))    # padded with 0: no edge off screen
    taps = tap_weights(edges, maskp)
    out = torch.where(mask, ao, torch.ones_like(ao))                       # sanitise background
    for p in range(passes):
        out = denoise_pass(_pad(out), taps, mask, beta if p == passes - 1 else beta / 5.0)
    return out


# The denoise's kernels (ssbench.passes.compiled: edge_planes, tap_weights, denoise_pass) take planes (B, 1, H, W),
# which inductor fuses without transposes, and are kept apart so that it stores the edges and weights instead of
# recomputing them for every neighbour that reads them.
# They use only exact operations and divisions: compiled, the same bits.
@kernel
def tap_weights(edges: tuple, maskp: torch.Tensor) -> tuple:
    """The 8 neighbour weights of the 3×3 mean (cross, then diagonals: the order of ``_TAPS``) from the pixels'
    padded :func:`edge_planes` (L, R, T, B) and padded mask."""
    mask, dtype = _at(maskp, 0, 0), edges[0].dtype
    eL, eR, eT, eB = ([_at(e, dx, dy) for e in edges] for dx, dy in _DIRS)   # neighbours' edges (0 off screen)
    edges = [_at(e, 0, 0) for e in edges]
    c = [e * n for e, n in zip(edges, (eL[1], eR[0], eT[3], eB[2]))]      # symmetric
    leak = ((4.0 - _LEAK_THRESHOLD - (c[0] + c[1] + c[2] + c[3])).clamp(0.0, 1.0) / (4.0 - _LEAK_THRESHOLD)
            * _LEAK_STRENGTH)
    c = [(ci + leak).clamp(0.0, 1.0) * (_at(maskp, dx, dy) & mask).to(dtype)   # never from
         for ci, (dx, dy) in zip(c, _DIRS)]                                 # background/off screen
    cl, cr, ct, cb = c
    w_diag = {(-1, -1): cl * eL[2] + ct * eT[0],                          # top-left
              (1, -1): ct * eT[1] + cr * eR[2],                           # top-right
              (-1, 1): cb * eB[0] + cl * eL[3],                           # bottom-left
              (1, 1): cr * eR[3] + cb * eB[1]}                            # bottom-right
    return tuple(c) + tuple(_DIAG_WEIGHT * w for w in w_diag.values())


_TAPS = _DIRS + ((-1, -1), (1, -1), (-1, 1), (1, 1))       # the neighbours of tap_weights' planes, in order


@kernel
def denoise_pass(outp: torch.Tensor, taps: tuple, mask: torch.Tensor, centre: float) -> torch.Tensor:
    """One pass: the weighted 3×3 mean of the padded ``outp`` with centre weight ``centre``, 1 on background."""
    out = _at(outp, 0, 0)
    total, wsum = out * centre, torch.full_like(out, centre)
    for (dx, dy), w in zip(_TAPS, taps):
        total = total + w * _at(outp, dx, dy)
        wsum = wsum + w
    return torch.where(mask, total / wsum, torch.ones_like(out))


class GTAODenoise(nn.Module):
    """:func:`gtao_denoise` as a module.

    Example:
        >>> GTAODenoise(passes=2).passes
        2
    """

    def __init__(self, passes: int = 1, beta: float = 1.2) -> None:
        super().__init__()
        self.passes, self.beta = passes, beta

    def forward(self, ao: torch.Tensor, view_z: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        return gtao_denoise(ao, view_z, mask, self.passes, self.beta)
