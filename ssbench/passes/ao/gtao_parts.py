"""Pieces of the GTAO pass (:mod:`ssbench.passes.ao.gtao`): the slice integral, the noise buffers, the slice frame
and 3-vector helpers.

``slice_visibility`` is the analytic cosine-weighted arc of a slice (Jimenez et al. 2016); ``noise_buffer`` draws
the per-pixel slice and step noise: XeGTAO's Hilbert index × R2 sequence, a hash, a constant or a 4×4 tile.
"""
from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Optional

import torch

from ..common import make_generator

if TYPE_CHECKING:
    from .gtao import GTAOParams

#: the R2 sequence's two steps (XeGTAO's Hilbert-index noise: slice, then step noise)
R2 = (0.75487766624669276005, 0.5698402909980532659114)


def slice_visibility(h0: torch.Tensor, h1: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
    """Cosine-weighted visible arc of a slice, ``a(h0) + a(h1)``, ``a(h) = (cos n + 2h sin n − cos(2h − n))/4``.

    Equals ``∫_{h0}^{h1} cos(θ − n)·|sin θ| dθ`` for ``h0 ≤ 0 ≤ h1`` (angles from the view vector, ``n`` the
    projected normal's angle); ``|sin θ|`` is the slice parametrisation's Jacobian. Unoccluded
    (``h = n ± π/2``) it is ``cos n + n sin n``, whose ``|proj n|``-weighted slice average is 1.

    Example:
        >>> import math
        >>> z = torch.zeros(1, dtype=torch.float64)
        >>> slice_visibility(z - math.pi / 2, z + math.pi / 2, z).item()
        1.0
    """
    def arc(h: torch.Tensor) -> torch.Tensor:
        return (torch.cos(n) + 2.0 * h * torch.sin(n) - torch.cos(2.0 * h - n)) / 4.0
    return arc(h0) + arc(h1)


#: the slice/step noise kinds by name (a tile is given as values)
NOISE_KINDS = ("hash", "hilbert", "none")


def check_noise(noise, seed: int, frame: int) -> None:
    """The noise fields of a horizon pass's parameters (GTAO, VBAO): ``noise`` a kind of :data:`NOISE_KINDS` or a
    ``(4, 4)`` / ``(2, 4, 4)`` tile in [0, 1), ``seed`` a valid generator seed, ``frame`` an integer >= 0; each
    error names its field."""
    if isinstance(noise, str):
        if noise not in NOISE_KINDS:
            raise ValueError(f"noise: expected one of {NOISE_KINDS} or a 4x4 tile, got {noise!r}")
    else:
        t = torch.as_tensor(noise, dtype=torch.float64)
        if tuple(t.shape) not in ((4, 4), (2, 4, 4)) or not bool(((t >= 0) & (t < 1)).all()):
            raise ValueError(f"noise: a tile must have shape (4, 4) or (2, 4, 4) with values in [0, 1), "
                             f"got shape {tuple(t.shape)}")
    make_generator(seed, None)                               # validates seed
    if isinstance(frame, bool) or not isinstance(frame, int) or frame < 0:
        raise ValueError(f"frame: must be an integer >= 0, got {frame!r}")


def hilbert_index(x: torch.Tensor, y: torch.Tensor, width: int = 64) -> torch.Tensor:
    """XeGTAO's ``HilbertIndex`` of integer pixel coordinates (taken modulo ``width``)."""
    x, y, index, level = x % width, y % width, torch.zeros_like(x), width // 2
    while level > 0:
        rx, ry = ((x & level) > 0).long(), ((y & level) > 0).long()
        index = index + level * level * ((3 * rx) ^ ry)
        flip = (ry == 0) & (rx == 1)
        x, y = torch.where(flip, width - 1 - x, x), torch.where(flip, width - 1 - y, y)
        x, y = torch.where(ry == 0, y, x), torch.where(ry == 0, x, y)
        level //= 2
    return index


@functools.lru_cache(maxsize=64)
def hilbert_tile(frame: int) -> torch.Tensor:
    """:math:`(2, 64, 64)` float64 XeGTAO noise of one frame (``frame`` in [0, 64)) over one 64×64 tile: the R2
    sequence at the pixel's Hilbert index, ``frac(0.5 + (HilbertIndex + 288·frame)·R2)``."""
    with torch.inference_mode(False):                  # kept across calls: a normal tensor whatever the caller's mode
        col = torch.arange(64).view(1, 64).expand(64, 64)
        idx = hilbert_index(col, col.t()).to(torch.float64) + 288 * frame             # (64, 64), XeGTAO
        r2 = torch.tensor(R2, dtype=torch.float64).view(2, 1, 1)
        return torch.frac(0.5 + idx * r2)


def noise_buffer(params: GTAOParams, batch: int, height: int, width: int,
                 generator: Optional[torch.Generator] = None) -> torch.Tensor:
    """:math:`(B, 2, H, W)` float64 ``(slice noise, step noise)`` in [0, 1) as chosen by ``params.noise``."""
    shape, kind = (batch, 2, height, width), params.noise if isinstance(params.noise, str) else "tile"
    if kind == "hash":
        g = make_generator(params.seed, generator)
        return torch.rand(shape, generator=g, dtype=torch.float64, device=g.device).cpu()
    if kind == "none":
        return torch.full(shape, 0.5, dtype=torch.float64)
    if kind == "hilbert":                      # the index repeats every 64 pixels: one tile
        tile = hilbert_tile(params.frame % 64)
    else:
        tile = torch.as_tensor(params.noise, dtype=torch.float64).expand(2, 4, 4)     # (2, 4, 4)
    n = tile.shape[-1]                        # the tile repeated over the image
    return tile.repeat(1, -(-height // n), -(-width // n))[:, :height, :width].expand(shape)


def dot3(a: tuple, b: tuple) -> torch.Tensor:                 # 3-vectors are (x, y, z) tuples of tensors
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross3(a: tuple, b: tuple) -> tuple:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit3(a: tuple) -> tuple:
    inv = 1.0 / dot3(a, a).sqrt().clamp_min(torch.finfo(a[0].dtype).tiny)
    return tuple(c * inv for c in a)


def slice_frame(cos_phi: torch.Tensor, sin_phi: torch.Tensor, v: tuple, N: tuple) -> tuple:
    """The slice through the view vector ``v`` along the screen direction ``(cos φ, sin φ)``: ``(o, |proj n|, n)``
    — its tangent ``o`` (XeGTAO's ``orthoDirectionVec``), the length of the normal ``N`` projected into the slice
    and that projection's signed angle ``n`` from ``v`` (Jimenez et al. 2016, Algorithm 1, lines 5–15). Shared
    by GTAO and the visibility-bitmask AO."""
    tiny = torch.finfo(cos_phi.dtype).tiny
    dv = cos_phi * v[0] + sin_phi * v[1]
    o = (cos_phi - dv * v[0], sin_phi - dv * v[1], -dv * v[2])                  # orthoDirectionVec
    axis = unit3(cross3(o, v))
    na = dot3(N, axis)
    proj_n = tuple(N[i] - axis[i] * na for i in range(3))
    proj_len = dot3(proj_n, proj_n).sqrt()
    cos_n = (dot3(proj_n, v) / proj_len.clamp_min(tiny)).clamp(0.0, 1.0)
    return o, proj_len, torch.sign(dot3(o, proj_n)) * torch.acos(cos_n)
