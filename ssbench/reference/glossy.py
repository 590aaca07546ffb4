"""Glossy-reflection ground truth: what each pixel's specular lobe reflects, path traced, with standard errors,
and the screen-space oracle (what a perfect marcher that sees only the G-buffer could return).

Per pixel of a batch-1 reference G-buffer (its ``roughness``, ``metallic``, ``albedo`` and ``color``), from the
primary hit at the pixel centre with the shading normal turned toward the viewer ``v``:

1. ``rays`` microfacet normals ``m`` drawn from the GGX distribution of normals visible from ``v`` (Mitsuba's
   ``MicrofacetDistribution``, ``sample_visible=True``; ``α = max(10⁻³, roughness²)`` as Mitsuba's
   ``principled``; at roughness 0 exactly ``m = n``, the mirror), reflected: ``l = 2(v·m)m − v``; a direction
   below the surface contributes 0;
2. along each ``l`` one path (the scene's own integrator) gives the incident radiance ``L(l)``;
3. per pixel, the means over the ``rays`` samples and their standard errors ``σ/√rays``:

   * ``lobe = E[L(l)]`` — the lobe-averaged incident radiance: what a glossy SSR's reflection buffer estimates
     before any Fresnel (at roughness 0, the mirror ray's radiance);
   * ``specular = E[F(v·m)·G1(l)·L(l)]`` — the specular radiance itself (VNDF sampling leaves ``F·G1(l)`` as the
     weight of ``f·cos/pdf``), with Schlick's ``F``, ``F0 = lerp(0.04, albedo, metallic)`` (the resolve's model,
     :mod:`ssbench.passes.ssr.resolve`), so a resolve can be scored on its own;
   * ``oracle = E[C(l)]`` with ``C`` the G-buffer ``color`` at the pixel where ``l``'s first hit projects, when
     that hit is on screen, seen by the camera and front-facing, else 0 (sky included): the best any screen-space
     method can return. ``lobe − oracle`` is the information the G-buffer does not hold;
   * ``reachable``: the share of directions whose hit the oracle could use.

   Every mean comes with its standard error (``*_se``; ``gap_se`` for ``lobe − oracle``, whose samples are
   paired). A score against a noisy truth is inflated by it: ``E[(x − t̂)²] = (x − t)² + se²``, so
   :mod:`ssbench.evaluate._glossy` reports RMSEs with the truth's variance removed next to the raw ones.

Directions come from a PCG32 stream per pixel, paths from Mitsuba's ``independent`` sampler seeded per pass:
same seed, same bits.
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass

import numpy as np
import torch

from ..gbuffer import GBuffer
from ..scenes import load as load_scene
from . import cache
from .ao import trace_primaries
from .color import pass_seed

__all__ = ["GlossyReference", "glossy_reflections", "GLOSSY_CHANNELS"]

_KERNEL_VERSION = 3
#: the G-buffer channels the truth reads
GLOSSY_CHANNELS = ("roughness", "metallic", "albedo", "color", "mask")


@dataclass(frozen=True)
class GlossyReference:
    """Glossy truth, every tensor :math:`(1, C, H, W)` float32 (0 off ``valid``); see the module docstring.

    Attributes:
        valid: bool, pixels with a surface. lobe, lobe_se: (3). specular, specular_se: (3). oracle,
        oracle_se: (3). gap_se: (3) the standard error of ``lobe − oracle`` (the two share their directions).
        reachable: (1) share of directions whose hit a screen-space pass could read.
        rays: directions per pixel; seconds: tracing time.
    """

    valid: torch.Tensor
    lobe: torch.Tensor
    lobe_se: torch.Tensor
    specular: torch.Tensor
    specular_se: torch.Tensor
    oracle: torch.Tensor
    oracle_se: torch.Tensor
    gap_se: torch.Tensor
    reachable: torch.Tensor
    rays: int
    seconds: float = 0.0


_FIELDS = ("valid", "lobe", "lobe_se", "specular", "specular_se", "oracle", "oracle_se", "gap_se", "reachable")


def _digest(gbuffer: GBuffer) -> str:
    h = hashlib.sha256()
    for c in GLOSSY_CHANNELS:
        h.update(getattr(gbuffer, c).detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()[:16]


def glossy_reflections(scene, gbuffer: GBuffer, *, rays: int = 32, seed: int = 0,
                       use_cache: bool = True) -> GlossyReference:
    """Trace the specular lobe of every pixel of ``gbuffer`` in ``scene`` (module docstring).

    Args:
        scene: the scene the G-buffer was rendered from.
        gbuffer: batch 1, with :data:`GLOSSY_CHANNELS`; its camera fixes the pixel centres.
        rays: directions (one path each) per pixel, ≥ 2.
        seed: seeds the directions and the paths.
    """
    if not isinstance(gbuffer, GBuffer):
        raise TypeError(f"gbuffer: expected a GBuffer, got {type(gbuffer).__name__}")
    gbuffer.require(*GLOSSY_CHANNELS)
    if gbuffer.view_z is not None and gbuffer.view_z.shape[0] != 1 or gbuffer.color.shape[0] != 1:
        raise ValueError("gbuffer: the glossy truth takes a batch-1 G-buffer")
    if isinstance(rays, bool) or not isinstance(rays, int) or rays < 2:
        raise ValueError(f"rays: must be an integer >= 2, got {rays!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    sc, cam = load_scene(scene), gbuffer.camera
    key = cache.make_key("glossy", _KERNEL_VERSION, sc.content_hash(), cam, rays, seed, _digest(gbuffer))
    got = cache.load(key) if use_cache else None
    if got is not None:
        return GlossyReference(**{k: torch.from_numpy(got[k]) for k in _FIELDS}, rays=rays,
                               seconds=float(got["seconds"]))
    t0 = time.perf_counter()
    mi, dr, mscene, ph = trace_primaries(sc, cam, "glossy_reflections")
    W, H, N = cam.width, cam.height, cam.width * cam.height
    flat = lambda t, c: t.detach().double().reshape(c, N).cpu()                  # noqa: E731  (C, N) float64
    rough, metal, albedo = flat(gbuffer.roughness, 1)[0], flat(gbuffer.metallic, 1)[0], flat(gbuffer.albedo, 3)
    colour = flat(gbuffer.color, 3)
    f0 = 0.04 + (albedo - 0.04) * metal                                          # (3, N)
    si, hit = ph.si, ph.hit
    n = dr.select(dr.dot(si.sh_frame.n, ph.ray.d) > 0, -si.sh_frame.n, si.sh_frame.n)
    frame = mi.Frame3f(n)
    wi = frame.to_local(-ph.ray.d)
    # the primary hits, once: left lazy, every ray's kernel below would trace the pixel-centre rays again
    dr.eval(si.p, si.n, frame, wi, hit)
    distr = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, mi.Float(np.maximum(rough.numpy() ** 2, 1e-3)), True)
    rng = mi.PCG32(size=N, initstate=dr.opaque(mi.UInt64, seed), initseq=dr.arange(mi.UInt64, N))
    sampler = mi.load_dict({"type": "independent"})
    integrator = mscene.integrator()
    eye = mi.Point3f(*[dr.opaque(mi.Float, float(v)) for v in cam.eye])   # opaque: one kernel for every camera
    valid = hit.torch().bool()
    sums = {k: torch.zeros(3, N, dtype=torch.float64) for k in ("lobe", "lobe2", "spec", "spec2", "orc", "orc2",
                                                                 "gap", "gap2")}
    reach = torch.zeros(N, dtype=torch.float64)
    mirror = mi.Bool(torch.as_tensor(rough.numpy() == 0))
    for k in range(rays):
        m, _ = distr.sample(wi, mi.Point2f(rng.next_float32(), rng.next_float32()))
        m = dr.select(mirror, mi.Vector3f(0.0, 0.0, 1.0), m)                  # roughness 0: the mirror itself
        lo = 2.0 * dr.dot(wi, m) * m - wi
        above = hit & (mi.Frame3f.cos_theta(lo) > 0)
        ray = si.spawn_ray(frame.to_world(lo))
        sampler.seed(dr.opaque(mi.UInt32, pass_seed(seed, k)), N)
        L, _, _ = integrator.sample(mscene, sampler, mi.RayDifferential3f(ray), None, above)
        L = dr.select(above, L, 0.0)
        g1 = dr.select(above, distr.smith_g1(lo, m), 0.0)
        cos_vm = dr.dot(wi, m)
        si_r = mscene.ray_intersect(ray, above)
        p = si_r.p
        to_p = p - eye
        dist = dr.norm(to_p)
        pi = mscene.ray_intersect_preliminary(mi.Ray3f(eye, to_p / dr.maximum(dist, 1e-30)), active=si_r.is_valid())
        seen = above & si_r.is_valid() & (pi.t >= dist * (1.0 - 1e-4)) & (dr.dot(si_r.n, eye - p) > 0)
        dr.eval(L, g1, cos_vm, p, seen, rng)           # rng too: the next ray's kernel starts from stored state
        Lt = torch.stack([L.x.torch(), L.y.torch(), L.z.torch()]).double()
        fres = f0 + (1.0 - f0) * (1.0 - cos_vm.torch().double().clamp(0, 1)) ** 5
        spec = fres * g1.torch().double() * Lt
        pw = torch.stack([p.x.torch(), p.y.torch(), p.z.torch()], -1).double()
        pv = cam.world_to_view(pw, dim=-1)
        ok = seen.torch().bool() & (pv[:, 2] < -cam.near)
        px = cam.view_to_pixel(torch.where(ok[:, None], pv, -torch.ones_like(pv)), dim=-1)
        ok &= (px[:, 0] >= 0) & (px[:, 0] < W) & (px[:, 1] >= 0) & (px[:, 1] < H)
        at = (px[:, 1].floor().clamp(0, H - 1) * W + px[:, 0].floor().clamp(0, W - 1)).long()
        orc = torch.where(ok[None], colour[:, at], 0.0)
        for name, x in (("lobe", Lt), ("spec", spec), ("orc", orc), ("gap", Lt - orc)):
            sums[name] += x
            sums[name + "2"] += x * x
        reach += ok.double()
    out = {"valid": valid.reshape(1, 1, H, W).clone()}
    img = lambda x: torch.where(valid, x, 0.0).reshape(-1, H, W)[None].float().contiguous()   # noqa: E731
    for name, key_ in (("lobe", "lobe"), ("specular", "spec"), ("oracle", "orc"), ("gap", "gap")):
        mean = sums[key_] / rays
        var = ((sums[key_ + "2"] - rays * mean * mean) / (rays - 1)).clamp_min(0.0)
        out[name], out[name + "_se"] = img(mean), img((var / rays).sqrt())
    del out["gap"]                                                               # lobe − oracle: only its error
    out["reachable"] = img((reach / rays)[None])
    secs = time.perf_counter() - t0
    if use_cache:
        cache.store(key, {**{k: v.numpy() for k, v in out.items()}, "seconds": np.array(secs)})
    return GlossyReference(**out, rays=rays, seconds=secs)
