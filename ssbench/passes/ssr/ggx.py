"""The GGX (Trowbridge–Reitz) lobe of a glossy reflection, in torch: visible-normal sampling and its densities.

A rough surface reflects into a lobe around the mirror direction. Its microfacet normals follow GGX with
``α = roughness²`` (the Disney / Mitsuba ``principled`` convention); glossy SSR traces rays along reflections
about *sampled* normals. Sampling the normals **visible** from the viewer (Heitz, "Sampling the GGX Distribution of
Visible Normals", JCGT 7(4), 2018) wastes no ray on back-facing microfacets:

* :func:`sample_vndf` — Heitz 2018, listing 1, in a local frame with the normal on +z;
* :func:`ggx_d`, :func:`smith_g1` — the isotropic distribution and Smith's masking;
* :func:`reflection_pdf` — the density of the reflected direction ``l = reflect(−v, m)``:
  ``G1(v)·D(m) / (4·v.z)``;
* :func:`frame` — an orthonormal basis around each normal (Duff et al., "Building an Orthonormal Basis,
  Revisited", JCGT 6(1), 2017), so that view-space vectors go to the local frame and back.

All functions broadcast; a component axis ``dim`` holds x, y, z. ``α = 0`` is the mirror: ``m = n`` exactly.
"""
from __future__ import annotations

import math

import torch

from ..common import cross, vector_norm

__all__ = ["alpha_of", "frame", "to_local", "from_local", "sample_vndf", "ggx_d", "smith_g1", "reflection_pdf",
           "MIN_ALPHA"]

#: the smallest α used in densities (Mitsuba's ``principled`` clamps α the same way); sampling keeps α = 0 exact
MIN_ALPHA = 1e-3


def alpha_of(roughness: torch.Tensor) -> torch.Tensor:
    """GGX ``α = roughness²`` (perceptual roughness in [0, 1])."""
    return roughness.clamp(0.0, 1.0) ** 2


def frame(n: torch.Tensor, dim: int = 1) -> tuple[torch.Tensor, torch.Tensor]:
    """Tangent and bitangent ``(t, b)`` with ``(t, b, n)`` orthonormal (Duff et al. 2017), for unit ``n``.

    Example:
        >>> t, b = frame(torch.tensor([[0.0, 0.0, -1.0]]), dim=1)
        >>> torch.cross(t, b, dim=1).tolist()
        [[0.0, 0.0, -1.0]]
    """
    x, y, z = n.unbind(dim)
    sign = torch.where(z >= 0, 1.0, -1.0).to(n.dtype)
    a = -1.0 / (sign + z)
    b = x * y * a
    t = torch.stack([1.0 + sign * x * x * a, sign * b, -sign * x], dim)
    bt = torch.stack([b, sign + y * y * a, -y], dim)
    return t, bt


def to_local(v: torch.Tensor, t: torch.Tensor, b: torch.Tensor, n: torch.Tensor, dim: int = 1) -> torch.Tensor:
    """``v`` in the frame ``(t, b, n)``."""
    return torch.stack([(v * t).sum(dim), (v * b).sum(dim), (v * n).sum(dim)], dim)


def from_local(v: torch.Tensor, t: torch.Tensor, b: torch.Tensor, n: torch.Tensor, dim: int = 1) -> torch.Tensor:
    """The local vector ``v`` back in the frame's space."""
    x, y, z = (c.unsqueeze(dim) for c in v.unbind(dim))
    return x * t + y * b + z * n


def sample_vndf(v: torch.Tensor, alpha: torch.Tensor, u1: torch.Tensor, u2: torch.Tensor,
                dim: int = 1) -> torch.Tensor:
    """A microfacet normal visible from local ``v`` (``v.z > 0``), Heitz 2018 listing 1; ``u1, u2`` in [0, 1).

    Example:
        >>> v = torch.tensor([[0.3, 0.0, 0.954]])
        >>> sample_vndf(v, torch.tensor([0.0]), torch.tensor([0.7]), torch.tensor([0.2]))   # α = 0: the normal
        tensor([[0., 0., 1.]])
    """
    vx, vy, vz = v.unbind(dim)
    vh = torch.stack([alpha * vx, alpha * vy, vz], dim)
    vh = vh / vector_norm(vh, dim).clamp_min(torch.finfo(v.dtype).tiny)
    hx, hy, hz = vh.unbind(dim)
    lensq = hx * hx + hy * hy
    inv = torch.rsqrt(lensq.clamp_min(torch.finfo(v.dtype).tiny))
    t1 = torch.stack([torch.where(lensq > 0, -hy * inv, 1.0), torch.where(lensq > 0, hx * inv, 0.0),
                      torch.zeros_like(hx)], dim)
    t2 = cross(vh, t1, dim=dim)
    r, phi = torch.sqrt(u1), 2.0 * math.pi * u2
    p1, p2 = r * torch.cos(phi), r * torch.sin(phi)
    s = 0.5 * (1.0 + hz)
    p2 = (1.0 - s) * torch.sqrt((1.0 - p1 * p1).clamp_min(0.0)) + s * p2
    nh = p1.unsqueeze(dim) * t1 + p2.unsqueeze(dim) * t2 + \
        torch.sqrt((1.0 - p1 * p1 - p2 * p2).clamp_min(0.0)).unsqueeze(dim) * vh
    nx, ny, nz = nh.unbind(dim)
    m = torch.stack([alpha * nx, alpha * ny, nz.clamp_min(0.0)], dim)
    return m / vector_norm(m, dim).clamp_min(torch.finfo(v.dtype).tiny)


def ggx_d(cos_m: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """Isotropic GGX ``D(m) = α² / (π·(cos²θ_m·(α² − 1) + 1)²)`` (0 below the surface); α ≥ :data:`MIN_ALPHA`."""
    a2 = alpha.clamp_min(MIN_ALPHA) ** 2
    k = cos_m * cos_m * (a2 - 1.0) + 1.0
    return torch.where(cos_m > 0, a2 / (math.pi * k * k), 0.0)


def smith_g1(cos_v: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """Smith's masking for GGX, ``2 / (1 + √(1 + α²·tan²θ_v))``; 0 for directions below the surface."""
    a2 = alpha.clamp_min(MIN_ALPHA) ** 2
    c2 = (cos_v * cos_v).clamp_min(torch.finfo(cos_v.dtype).tiny)
    g = 2.0 / (1.0 + torch.sqrt(1.0 + a2 * (1.0 - c2) / c2))
    return torch.where(cos_v > 0, g, 0.0)


def reflection_pdf(cos_v: torch.Tensor, cos_m: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """Density (per solid angle) of the reflected direction when ``m`` is drawn by :func:`sample_vndf`:
    ``G1(v)·D(m) / (4·v.z)``, with ``cos_v = v.z``, ``cos_m = m.z``."""
    return smith_g1(cos_v, alpha) * ggx_d(cos_m, alpha) / (4.0 * cos_v.clamp_min(torch.finfo(cos_v.dtype).tiny))
