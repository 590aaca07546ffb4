"""Ray-traced bent normals: the mean unoccluded direction of each G-buffer pixel, with its angular error bar.

GTAO returns a bent normal beside its AO (Jimenez et al. 2016, Algorithm 2): the cosine-weighted mean of the
directions that are not occluded within the radius, normalised. The truth of that quantity is traced here with
the draws of the cosine AO ground truth (:func:`ssbench.reference.ao.ambient_occlusion`, same seed → the same
directions and the same visibility, so ``visible`` equals that AO bit for bit): ``rays`` cosine-weighted
directions in the view-space frame of the pixel's normal, each kept when nothing lies within ``radius``;

.. math::  \\mathbf b = \\frac{\\mathbf m}{\\lVert\\mathbf m\\rVert}, \\qquad
           \\mathbf m = \\frac1n\\sum_k V_k\\,\\boldsymbol\\omega_k .

The error bar is the root-mean-square angle between this estimate and the exact bent normal: from the per-pixel
covariance ``C`` of ``V_k ω_k``, ``σ_θ = √((tr C − b̂ᵀCb̂)/n) / ‖m‖`` (small angles; the spread across ``b̂``).
On an open floor at 256 rays it is 3.8°, and the observed angles there have that RMS (their mean is √π/2 of it). A pixel with no
unoccluded ray has no bent normal: ``normal`` is its shading normal there and ``stderr_deg`` is ``inf``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import torch

from ..gbuffer import GBuffer
from ..scenes import load as load_scene
from . import cache
from .ao import check_arguments, trace_primaries

__all__ = ["BentNormalReference", "bent_normals"]

_KERNEL_VERSION = 1


@dataclass(frozen=True)
class BentNormalReference:
    """Ground-truth bent normals: ``normal`` :math:`(1, 3, H, W)` unit view-space (0 on background),
    ``stderr_deg`` :math:`(1, 1, H, W)` its angular standard error in degrees (0 on background, inf where no ray
    is unoccluded), ``visible`` :math:`(1, 1, H, W)` the unoccluded share of the rays (the cosine AO)."""

    normal: torch.Tensor
    stderr_deg: torch.Tensor
    visible: torch.Tensor
    radius: float
    rays: int
    seconds: float = 0.0


def _moments(mi, dr, mscene, ph, radius: float, rays: int, seed: int, n_px: int) -> tuple:
    """Sums over the rays of ``V·ω`` (3), ``V·ω ω^T`` (6: xx, yy, zz, xy, xz, yz) and ``V``, in one kernel."""
    frame = mi.Frame3f(ph.n_view)
    rng = mi.PCG32(size=n_px, initstate=dr.opaque(mi.UInt64, seed), initseq=dr.arange(mi.UInt64, n_px))
    R = dr.opaque(mi.Float, radius)

    def body(k, sums, rng):
        u = mi.Point2f(rng.next_float32(), rng.next_float32())
        w = frame.to_world(mi.warp.square_to_cosine_hemisphere(u))                 # view space
        ray = ph.si.spawn_ray(ph.v2w @ w)
        ray.maxt = R
        v = dr.select(mscene.ray_test(ray, ph.hit), 0.0, 1.0)
        x, y, z = v * w.x, v * w.y, v * w.z
        terms = (x, y, z, x * w.x, y * w.y, z * w.z, x * w.y, x * w.z, y * w.z, v)
        return k + 1, [a + b for a, b in zip(sums, terms)], rng

    _, sums, _ = dr.while_loop((mi.UInt32(0), [dr.zeros(mi.Float, n_px) for _ in range(10)], rng),
                               lambda k, *_: k < rays, body)
    dr.eval(sums)
    return [s.torch().double() for s in sums]


def bent_normals(scene, gbuffer: GBuffer, radius: float, rays: int = 256, seed: int = 0, *,
                 use_cache: bool = True) -> BentNormalReference:
    """Ray-traced cosine-weighted bent normals of every G-buffer pixel against the full scene.

    Args:
        scene: the scene ``gbuffer`` was rendered from (Scene, catalog name, file or dict).
        gbuffer: a batch-1 reference G-buffer; its camera picks the pixel centres.
        radius: occlusion radius in world units (as the AO ground truth's).
        rays: directions per pixel (≥ 2).
        seed: PCG32 seed; the cosine AO ground truth with this seed draws the same directions.
    """
    check_arguments(gbuffer, radius, rays, "cosine", seed)
    sc, cam = load_scene(scene), gbuffer.camera
    key = cache.make_key("bent_normal", _KERNEL_VERSION, sc.content_hash(), cam, float(radius), rays, seed)
    got = cache.load(key) if use_cache else None
    if got is not None:
        return BentNormalReference(torch.from_numpy(got["normal"]), torch.from_numpy(got["stderr_deg"]),
                                   torch.from_numpy(got["visible"]), float(radius), rays, float(got["seconds"]))
    t0 = time.perf_counter()
    mi, dr, mscene, ph = trace_primaries(sc, cam, "bent_normals")
    W, H = cam.width, cam.height
    sums = _moments(mi, dr, mscene, ph, float(radius), rays, seed, W * H)
    n = float(rays)
    m = torch.stack(sums[:3], 1) / n                                               # (P, 3) mean of V·ω
    second = torch.stack([torch.stack([sums[3], sums[6], sums[7]], 1), torch.stack([sums[6], sums[4], sums[8]], 1),
                          torch.stack([sums[7], sums[8], sums[5]], 1)], 1) / n    # (P, 3, 3) E[V ω ω^T]
    cov = (second - m[:, :, None] * m[:, None, :]) * (n / (n - 1.0))               # sample covariance
    length = m.norm(dim=1)
    b = m / length.clamp_min(1e-300)[:, None]
    perp = (cov.diagonal(dim1=1, dim2=2).sum(1) - torch.einsum("pi,pij,pj->p", b, cov, b)).clamp_min(0.0)
    err = torch.rad2deg((perp / n).sqrt() / length.clamp_min(1e-300))
    dr.eval(ph.hit, ph.n_view)                          # together: each conversion alone re-traced the primaries
    hit = ph.hit.torch().bool()
    shading = ph.n_view.torch().double().T                                        # (3, P) -> (P, 3)
    some = length > 0
    normal = torch.where((hit & some)[:, None], b, torch.where(hit[:, None], shading, 0.0))
    err = torch.where(hit, torch.where(some, err, math.inf), 0.0)
    visible = torch.where(hit, sums[9] / n, 1.0)
    img = lambda x, c: x.float().reshape(H, W, c).permute(2, 0, 1)[None].contiguous()    # noqa: E731
    out = {"normal": img(normal, 3), "stderr_deg": img(err, 1), "visible": img(visible, 1)}
    secs = time.perf_counter() - t0
    if use_cache:
        cache.store(key, {**{k: v.numpy() for k, v in out.items()}, "seconds": np.array(secs)})
    return BentNormalReference(out["normal"], out["stderr_deg"], out["visible"], float(radius), rays, secs)
