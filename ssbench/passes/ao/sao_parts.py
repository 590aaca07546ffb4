"""The pieces of Scalable Ambient Obscurance (McGuire, Mara, Luebke, "Scalable Ambient Obscurance", HPG 2012,
https://research.nvidia.com/publication/2012-06_scalable-ambient-obscurance), in the paper's coordinates: integer
pixel ``ssC = (x, y)`` with ``y`` up from the bottom row (``gl_FragCoord``), camera-space ``z < 0``.

* :func:`gl_rows` turns an image's rows into that orientation (and back);
* :func:`depth_mips` — §3 "hierarchical z": each level keeps one texel of every 2×2 block of the level below,
  chosen on a rotated grid, ``z_{m+1}(p) = z_m(2p + (p_y & 1, p_x & 1))`` (the paper's minify pass);
* :func:`spin_angle` — the per-pixel pattern rotation ``(3x ^ y + xy)·10`` (the paper's hash, with GLSL's
  precedence: ``(3x) ^ (y + xy)``);
* :func:`tap_location` — the spiral ``α = (i + ½)/N``, angle ``α·(turns·6.28) + φ`` (the paper's 6.28), radius
  ``α``;
* :func:`mip_level` — ``clamp(⌊log₂ ssR⌋ − LOG_MAX_OFFSET, 0, MAX_MIP_LEVEL)``;
* :func:`quad_filter` — the "bilateral 2×2 box for free" of the listing: within each 2×2 pixel quad, ``A`` is
  averaged along x, then along y, where the quad's depth derivative stays below 0.02.
"""
from __future__ import annotations

import math

import torch

__all__ = ["gl_rows", "depth_mips", "spin_angle", "tap_location", "mip_level", "quad_filter",
           "pixels_per_meter", "QUAD_DEPTH_STEP"]

#: the listing's ``abs(dFdx(C.z)) < 0.02`` threshold of the quad filter (camera-space units)
QUAD_DEPTH_STEP = 0.02


def gl_rows(x: torch.Tensor) -> torch.Tensor:
    """Rows flipped: image rows (top first) ↔ ``gl_FragCoord`` rows (bottom first). Its own inverse."""
    return x.flip(-2)


def depth_mips(z: torch.Tensor, levels: int) -> list[torch.Tensor]:
    """``[z_0, …, z_levels]``: the rotated-grid depth pyramid of :math:`(B, 1, H, W)` ``z`` (GL rows), each level
    ``max(1, size >> 1)`` on a side, its texel ``p`` read from ``2p + (p_y & 1, p_x & 1)`` of the level below
    (clamped to its edge).

    Example:
        >>> z = torch.arange(16.0).view(1, 1, 4, 4)
        >>> depth_mips(z, 1)[1][0, 0].tolist()                  # (0,0)←(0,0), (1,0)←(2,1), (0,1)←(1,2), (1,1)←(3,3)
        [[0.0, 6.0], [9.0, 15.0]]
    """
    out = [z]
    for _ in range(levels):
        prev = out[-1]
        h, w = prev.shape[-2:]
        H, W = max(1, h >> 1), max(1, w >> 1)
        py = torch.arange(H, device=z.device).view(H, 1)
        px = torch.arange(W, device=z.device).view(1, W)
        sx = (2 * px + (py & 1)).clamp(max=w - 1)
        sy = (2 * py + (px & 1)).clamp(max=h - 1)
        out.append(prev[..., sy, sx])
    return out


def spin_angle(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """``randomPatternRotationAngle = (3·x ^ y + x·y)·10`` of integer pixel coordinates (GLSL precedence: ``*``
    and ``+`` before ``^``), as float.

    Example:
        >>> spin_angle(torch.tensor([1, 2]), torch.tensor([1, 3])).tolist()
        [10.0, 150.0]
    """
    return ((3 * x) ^ (y + x * y)).to(torch.float64) * 10.0


def tap_location(i: int, num_samples: int, num_spiral_turns: int, spin: torch.Tensor):
    """``(unit_x, unit_y, alpha)`` of tap ``i``: the direction on the spiral and its radius as a share of the
    disk (``tapLocation``; the paper writes 2π as 6.28)."""
    alpha = (i + 0.5) * (1.0 / num_samples)
    angle = alpha * (num_spiral_turns * 6.28) + spin
    return torch.cos(angle), torch.sin(angle), alpha


def mip_level(ss_r: torch.Tensor, log_max_offset: int, max_mip_level: int, dtype: torch.dtype = torch.long
              ) -> torch.Tensor:
    """Integer mip level (``dtype``) of a tap ``ss_r`` pixels away: ``clamp(⌊log₂ ssR⌋ − LOG_MAX_OFFSET, 0,
    MAX_MIP_LEVEL)`` (0 where ``ssR ≤ 0``).

    Example:
        >>> mip_level(torch.tensor([0.0, 7.9, 8.0, 40.0, 1e6]), 3, 5).tolist()
        [0, 0, 0, 2, 5]
    """
    safe = torch.where(ss_r > 0, ss_r, 1.0)
    lv = torch.floor(torch.log2(safe)).to(dtype) - log_max_offset
    return torch.where(ss_r > 0, lv, 0).clamp(0, max_mip_level)


def _quad_pass(a: torch.Tensor, z: torch.Tensor, dim: int) -> torch.Tensor:
    n = a.shape[dim]
    pairs = n // 2 * 2
    if pairs == 0:
        return a
    lo, hi = a.narrow(dim, 0, pairs), z.narrow(dim, 0, pairs)
    shape = list(lo.shape)
    shape[dim:dim + 1] = [pairs // 2, 2]
    av, zv = lo.reshape(shape), hi.reshape(shape)
    d_a = av.select(dim + 1, 1) - av.select(dim + 1, 0)                   # dFdx(A): odd − even of the pair
    d_z = zv.select(dim + 1, 1) - zv.select(dim + 1, 0)
    keep = (d_z.abs() < QUAD_DEPTH_STEP).unsqueeze(dim + 1)
    sign = torch.tensor([-0.5, 0.5], dtype=a.dtype, device=a.device).view(
        [2 if k == dim + 1 else 1 for k in range(len(shape))])
    filtered = torch.where(keep, av - d_a.unsqueeze(dim + 1) * sign, av).reshape(lo.shape)
    return torch.cat([filtered, a.narrow(dim, pairs, n - pairs)], dim)


def quad_filter(a: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    """The listing's free 2×2 filter on :math:`(B, 1, H, W)` ``a`` and camera-space ``z`` (GL rows): ``A −=
    dFdx(A)·((x & 1) − ½)`` where ``|dFdx(z)| < 0.02``, then the same along y on the result. A quad is the
    pixel pair ``(2k, 2k + 1)``; an odd last column or row has no partner and is left alone (a GPU would pair it
    with a helper pixel outside the image).

    Example:
        >>> a = torch.tensor([[[[0.0, 1.0], [1.0, 1.0]]]])
        >>> quad_filter(a, torch.zeros_like(a))[0, 0].tolist()
        [[0.75, 0.75], [0.75, 0.75]]
    """
    return _quad_pass(_quad_pass(a, z, 3), z, 2)


def pixels_per_meter(camera) -> float:
    """``projScale``: pixels per camera-space unit at ``z = −1`` (``H / (2 tan(fovy/2))``)."""
    return camera.height / (2.0 * math.tan(math.radians(camera.fovy_deg) / 2.0))
