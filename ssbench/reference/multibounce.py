"""Ray-traced multi-bounce AO: the irradiance at each G-buffer pixel under a uniform white environment, with light
bouncing between the scene's diffuse albedos, divided by its unoccluded value (π), per RGB channel.

What GTAO's multi-bounce fit (Jimenez et al. 2016, §5: ``max(V, ((a V + b) V + c) V)`` with coefficients linear in
the albedo, :func:`ssbench.metrics.ao_multibounce.jimenez_multibounce`) approximates, traced as paths: from the
pixel, a cosine-weighted direction in the frame of its normal (the draws of the cosine AO ground truth,
:func:`ssbench.reference.ao.ambient_occlusion`: same seed → same first directions); a segment that meets nothing
within ``radius`` sees the environment (radiance 1); one that hits a surface multiplies the path's weight by that
surface's diffuse albedo (``eval_diffuse_reflectance`` at the hit, times ``albedo_scale``) and continues with a
cosine-weighted direction about the hit's normal turned toward the path, for at most ``bounces`` hits (a path
still inside after them contributes 0: a bias below ``albedo^(bounces+1)``).

.. math::  M = \\frac1n\\sum_k \\prod_{j<J_k} \\rho_{k,j}, \\qquad \\sigma_M = \\sqrt{\\hat{\\mathrm{Var}}/n}

With ``albedo_scale = 0`` every hit ends its path, so ``M`` is the cosine AO of the same draws, bit for bit
(tested). Metals and other non-diffuse BSDFs reflect nothing here (their diffuse reflectance is 0). Bounce
directions come from a second PCG32 stream, so the first directions stay those of the single-bounce truth.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from ..gbuffer import GBuffer
from ..scenes import load as load_scene
from . import cache
from .ao import check_arguments, trace_primaries

__all__ = ["MultiBounceReference", "multibounce_ao", "BOUNCES"]

_KERNEL_VERSION = 1
#: surfaces a path may hit before it is cut
BOUNCES = 6


@dataclass(frozen=True)
class MultiBounceReference:
    """``ao`` :math:`(1, 3, H, W)` multi-bounce visibility per RGB channel (1 on background), ``stderr`` its
    standard error, ``single`` :math:`(1, 1, H, W)` the single-bounce cosine AO of the same first directions,
    ``albedo`` :math:`(1, 3, H, W)` each pixel's own diffuse albedo (what the fit takes)."""

    ao: torch.Tensor
    stderr: torch.Tensor
    single: torch.Tensor
    albedo: torch.Tensor
    radius: float
    rays: int
    bounces: int
    seconds: float = 0.0


def _paths(mi, dr, mscene, ph, radius: float, rays: int, seed: int, n_px: int, bounces: int, scale: float):
    frame = mi.Frame3f(ph.n_view)
    rng = mi.PCG32(size=n_px, initstate=dr.opaque(mi.UInt64, seed), initseq=dr.arange(mi.UInt64, n_px))
    rng2 = mi.PCG32(size=n_px, initstate=dr.opaque(mi.UInt64, seed), initseq=dr.arange(mi.UInt64, n_px) + n_px)
    R, S = dr.opaque(mi.Float, radius), dr.opaque(mi.Float, scale)

    def body(k, sums, rng, rng2):
        u = mi.Point2f(rng.next_float32(), rng.next_float32())
        ray = ph.si.spawn_ray(ph.v2w @ frame.to_world(mi.warp.square_to_cosine_hemisphere(u)))
        ray.maxt = R
        weight, out = mi.Color3f(1.0), mi.Color3f(0.0)
        alive = mi.Bool(ph.hit)
        first = mi.Float(0.0)
        for j in range(bounces + 1):
            si = mscene.ray_intersect(ray, alive)
            escaped = alive & ~si.is_valid()
            out = dr.select(escaped, out + weight, out)
            if j == 0:
                first = dr.select(escaped, 1.0, 0.0)
            alive &= si.is_valid()
            if j == bounces:
                break
            weight = weight * si.bsdf().eval_diffuse_reflectance(si, alive) * S
            alive &= dr.max(weight) > 0
            n = dr.select(dr.dot(si.sh_frame.n, ray.d) > 0, -si.sh_frame.n, si.sh_frame.n)   # toward the path
            v = mi.Point2f(rng2.next_float32(), rng2.next_float32())
            ray = si.spawn_ray(mi.Frame3f(n).to_world(mi.warp.square_to_cosine_hemisphere(v)))
            ray.maxt = R
        terms = (out.x, out.y, out.z, out.x * out.x, out.y * out.y, out.z * out.z, first)
        return k + 1, [a + b for a, b in zip(sums, terms)], rng, rng2

    _, sums, _, _ = dr.while_loop((mi.UInt32(0), [dr.zeros(mi.Float, n_px) for _ in range(7)], rng, rng2),
                                  lambda k, *_: k < rays, body)
    dr.eval(sums)
    return [s.torch().double() for s in sums]


def multibounce_ao(scene, gbuffer: GBuffer, radius: float, rays: int = 256, seed: int = 0, *,
                   bounces: int = BOUNCES, albedo_scale: float = 1.0, use_cache: bool = True) -> MultiBounceReference:
    """Path-traced multi-bounce AO of every G-buffer pixel (see the module docstring).

    Args:
        scene: the scene ``gbuffer`` was rendered from. gbuffer: a batch-1 reference G-buffer.
        radius: occlusion radius in world units, per path segment (as the AO ground truth's).
        rays: paths per pixel (≥ 2). seed: PCG32 seed (the cosine AO truth with it draws the same first rays).
        bounces: surfaces a path may hit (≥ 0; 0 is the single-bounce AO). albedo_scale: multiplies every albedo
            (0: single bounce; a sweep shows the fit's albedo dependence).
    """
    check_arguments(gbuffer, radius, rays, "cosine", seed)
    if isinstance(bounces, bool) or not isinstance(bounces, int) or not 0 <= bounces <= 64:
        raise ValueError(f"bounces: must be an integer in [0, 64], got {bounces!r}")
    if isinstance(albedo_scale, bool) or not isinstance(albedo_scale, (int, float)) or not 0 <= albedo_scale <= 1:
        raise ValueError(f"albedo_scale: must be a number in [0, 1], got {albedo_scale!r}")
    sc, cam = load_scene(scene), gbuffer.camera
    key = cache.make_key("multibounce", _KERNEL_VERSION, sc.content_hash(), cam, float(radius), rays, seed, bounces,
                         float(albedo_scale))
    got = cache.load(key) if use_cache else None
    if got is not None:
        return MultiBounceReference(*(torch.from_numpy(got[k]) for k in ("ao", "stderr", "single", "albedo")),
                                    float(radius), rays, bounces, float(got["seconds"]))
    t0 = time.perf_counter()
    mi, dr, mscene, ph = trace_primaries(sc, cam, "multibounce_ao")
    W, H = cam.width, cam.height
    sums = _paths(mi, dr, mscene, ph, float(radius), rays, seed, W * H, bounces, float(albedo_scale))
    n = float(rays)
    mean = torch.stack(sums[:3], 1) / n                                            # (P, 3)
    var = ((torch.stack(sums[3:6], 1) - n * mean * mean) / (n - 1.0)).clamp_min(0.0)
    own = ph.si.bsdf().eval_diffuse_reflectance(ph.si, ph.hit)
    dr.eval(ph.hit, own)                                # together: each conversion alone re-traced the primaries
    hit = ph.hit.torch().bool()
    albedo = torch.stack([own.x.torch(), own.y.torch(), own.z.torch()], 1).double() * float(albedo_scale)
    img = lambda x, c: x.float().reshape(H, W, c).permute(2, 0, 1)[None].contiguous()    # noqa: E731
    out = {"ao": img(torch.where(hit[:, None], mean, 1.0), 3),
           "stderr": img(torch.where(hit[:, None], (var / n).sqrt(), 0.0), 3),
           "single": img(torch.where(hit, sums[6] / n, 1.0)[:, None], 1),
           "albedo": img(torch.where(hit[:, None], albedo, 0.0), 3)}
    secs = time.perf_counter() - t0
    if use_cache:
        cache.store(key, {**{k: v.numpy() for k, v in out.items()}, "seconds": np.array(secs)})
    return MultiBounceReference(out["ao"], out["stderr"], out["single"], out["albedo"], float(radius), rays, bounces,
                                secs)
