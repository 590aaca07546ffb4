"""Step 2 of stochastic glossy SSR (:mod:`.glossy_stochastic`), the resolve: each ray's hits summed into the pixels
that reuse them, weighted as Stachowiak's ray reuse says.

T. Stachowiak, "Stochastic Screen-Space Reflections", SIGGRAPH 2015 course *Advances in Real-Time Rendering*
(https://www.ea.com/frostbite/news/stochastic-screen-space-reflections), "ray reuse": pixel ``i`` takes the hit of
each neighbour ``j`` within ``reuse_radius`` with weight ``w = p_i(l_ij) / p_j(l_j)``, where ``l_ij`` is the
direction from ``i`` to ``j``'s hit point and ``p`` the density of reflected directions
(:func:`~ssbench.passes.ssr.ggx.reflection_pdf`); the resolved colour is ``Σ w·C / Σ w``. With ``reuse_radius``
0 (``reuse="none"``) every pixel keeps its own rays with weight 1.

:func:`reuse_ray` adds one ray's contributions over the whole window; it is the pass's compilable kernel
(:mod:`ssbench.passes.compiled`): eager, the same operations in the same order as the pass always ran;
compiled, one loop over the pixels.
"""
from __future__ import annotations

from typing import NamedTuple

import torch
import torch.nn.functional as F

from ..common import component_dot, component_norm
from ..compiled import kernel
from .ggx import reflection_pdf

__all__ = ["MAX_WEIGHT", "ReuseFrame", "RaySample", "ReuseSums", "padded", "neighbour", "reuse_weight", "reuse_ray"]

#: the largest reuse weight ``p_i / p_j``: at grazing views both densities overflow (``G1·D / 4 cos θ_v``)
MAX_WEIGHT = 1e8


class ReuseFrame(NamedTuple):
    """What the weights need of each pixel ``i``: ``pos`` and ``v`` (unit, toward the eye) :math:`(B, 3, H, W)`
    in view space, ``cos_v`` :math:`(B, H, W)` (``v``'s local z), ``n`` :math:`(B, 3, H, W)`, ``alpha``
    :math:`(B, H, W)` and ``mask`` :math:`(B, 1, H, W)` bool."""

    pos: torch.Tensor
    v: torch.Tensor
    cos_v: torch.Tensor
    n: torch.Tensor
    alpha: torch.Tensor
    mask: torch.Tensor


class RaySample(NamedTuple):
    """One ray per pixel ``j``: ``ok`` :math:`(B, 1, H, W)` (it hit, and left above the surface), ``raw`` and
    ``faded`` :math:`(B, 3, H, W)` its hit colour without and with the fades (0 where not ``ok``), ``hit_view``
    :math:`(B, 3, H, W)`, ``l_dir`` :math:`(B, 3, H, W)` its direction and ``pdf`` :math:`(B, 1, H, W)` its density."""

    ok: torch.Tensor
    raw: torch.Tensor
    faded: torch.Tensor
    hit_view: torch.Tensor
    l_dir: torch.Tensor
    pdf: torch.Tensor


class ReuseSums(NamedTuple):
    """The running sums ``Σ w·C`` (``num_raw``, ``num_fade``: :math:`(B, 3, H, W)`) and ``Σ w`` (``den``:
    :math:`(B, 1, H, W)`)."""

    num_raw: torch.Tensor
    num_fade: torch.Tensor
    den: torch.Tensor


def padded(ray: RaySample, mask: torch.Tensor, radius: int) -> tuple[RaySample, torch.Tensor]:
    """``ray`` and ``mask`` with a ``radius``-wide border of what lies past the image (no hit, zero colour and
    direction, density 1, no geometry), so that a neighbour's value is a slice (:func:`neighbour`).

    Example:
        >>> ray = RaySample(*(torch.ones(1, c, 2, 2) for c in (1, 3, 3, 3, 3, 1)))
        >>> p, m = padded(ray, torch.ones(1, 1, 2, 2, dtype=torch.bool), 1)
        >>> p.raw.shape, p.pdf[0, 0, 0].tolist(), m[0, 0, 0].tolist()
        (torch.Size([1, 3, 4, 4]), [1.0, 1.0, 1.0, 1.0], [False, False, False, False])
    """
    def pad(x, fill):
        return F.pad(x, (radius,) * 4, value=fill)
    fills = RaySample(False, 0.0, 0.0, 0.0, 0.0, 1.0)
    return RaySample(*(pad(x, fill) for x, fill in zip(ray, fills))), pad(mask, False)


def neighbour(x: torch.Tensor, radius: int, dy: int, dx: int) -> torch.Tensor:
    """The value of pixel ``(y + dy, x + dx)`` at every ``(y, x)``, from ``x`` padded by ``radius`` (a view).

    Example:
        >>> x = F.pad(torch.arange(4.0).view(1, 1, 1, 4), (1, 1, 1, 1))      # one row of 4 pixels, padded by 1
        >>> neighbour(x, 1, 0, 1).flatten().tolist()                       # each pixel's right-hand neighbour
        [1.0, 2.0, 3.0, 0.0]
    """
    H, W = x.shape[-2] - 2 * radius, x.shape[-1] - 2 * radius
    return x[..., radius + dy:radius + dy + H, radius + dx:radius + dx + W]


def reuse_weight(ray: RaySample, frame: ReuseFrame, mask: torch.Tensor, radius: int, dy: int, dx: int
                 ) -> torch.Tensor:
    """``w = p_i(l_ij) / p_j(l_j)`` :math:`(B, 1, H, W)` of neighbour ``j = (y + dy, x + dx)``'s ray at every pixel
    ``i``: ``l_ij`` toward ``j``'s hit (``j``'s own direction where it missed), 0 where ``l_ij`` leaves below ``i``'s
    surface or ``i`` or ``j`` holds no geometry; overflowing densities (grazing views) clamp to :data:`MAX_WEIGHT`.
    ``ray`` and ``mask`` are :func:`padded` by ``radius``. Written on components (no sum over a channel dimension):
    compiled, a reduction was a stored buffer per neighbour, 270 MiB more at 1920×1080."""
    def at_j(x):
        return neighbour(x, radius, dy, dx)
    tiny = torch.finfo(frame.pos.dtype).tiny
    pos, v, n = frame.pos.unbind(1), frame.v.unbind(1), frame.n.unbind(1)
    to_hit = [a - b for a, b in zip(at_j(ray.hit_view).unbind(1), pos)]
    far = component_norm(*to_hit).clamp_min(tiny)
    hit_j = at_j(ray.ok)[:, 0]
    l_ij = [torch.where(hit_j, t / far, d) for t, d in zip(to_hit, at_j(ray.l_dir).unbind(1))]
    h = [a + b for a, b in zip(v, l_ij)]
    h_len = component_norm(*h).clamp_min(tiny)
    p_i = reflection_pdf(frame.cos_v, component_dot([c / h_len for c in h], n), frame.alpha)
    p_i = torch.where(component_dot(l_ij, n) > 0, p_i, 0.0)
    w = torch.where((at_j(mask) & frame.mask)[:, 0], p_i / at_j(ray.pdf)[:, 0].clamp_min(1e-12), 0.0)
    return torch.nan_to_num(w, nan=0.0, posinf=MAX_WEIGHT).clamp(0.0, MAX_WEIGHT)[:, None]


@kernel
def reuse_ray(sums: ReuseSums, ray: RaySample, frame: ReuseFrame, mask: torch.Tensor, radius: int) -> ReuseSums:
    """``sums`` plus one ray's contributions to every pixel within ``radius`` of it (:func:`reuse_weight`; weight
    1 on geometry with ``radius`` 0); ``ray`` and ``mask`` are :func:`padded` by ``radius``."""
    num_raw, num_fade, den = sums
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            w = frame.mask.to(frame.pos.dtype) if radius == 0 else reuse_weight(ray, frame, mask, radius, dy, dx)
            num_raw = num_raw + w * neighbour(ray.raw, radius, dy, dx)
            num_fade = num_fade + w * neighbour(ray.faded, radius, dy, dx)
            den = den + w
    return ReuseSums(num_raw, num_fade, den)
