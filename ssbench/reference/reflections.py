"""Exact mirror-reflection ground truth for SSR: one reflected ray per G-buffer pixel, traced in the full scene.

For each pixel centre the eye ray is re-traced (same rays as :func:`ssbench.reference.gbuffer`), reflected about
the shading normal turned toward the viewer (``r = d − 2(d·n)n``, SSR article §1.1) and traced from a robustly
offset origin nudged along the mirror ray itself. The hit is then classified the way a screen-space pass could or could not see it:
projected to a pixel, tested against the screen and the frustum, against the camera (an eye ray to the hit
point must reach it unobstructed) and for facing (a back face cannot be in a depth buffer).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from ..gbuffer import GBuffer
from ..scenes import load as load_scene
from . import backend, cache, convert
from .color import pass_seed

_KERNEL_VERSION = 1


@dataclass(frozen=True)
class ReflectionReference:
    """Exact reflections; every tensor is :math:`(1, C, H, W)`.

    Attributes:
        valid: bool, pixels that spawn a mirror ray (the G-buffer's hits).
        hit: bool, the mirror ray hits geometry.
        hit_world, hit_view: (3) hit point (0 where no hit).
        hit_pixel: (2) continuous pixel coordinates of the hit (−1 where no hit or behind the camera).
        on_screen: bool, the hit projects inside the image and lies between the near and far planes.
        visible: bool, an eye ray to the hit point reaches it unobstructed (so a depth buffer holds it).
        back_face: bool, the hit surface faces away from the camera.
        hit_shape: int32 scene index of the hit shape (−1 where none).
        ray_length: float distance from the reflecting point to the hit (inf where none).
        radiance: (3) path-traced radiance arriving along the mirror ray (``spp`` samples; 0 off ``valid``).
    """

    valid: torch.Tensor
    hit: torch.Tensor
    hit_world: torch.Tensor
    hit_view: torch.Tensor
    hit_pixel: torch.Tensor
    on_screen: torch.Tensor
    visible: torch.Tensor
    back_face: torch.Tensor
    hit_shape: torch.Tensor
    ray_length: torch.Tensor
    radiance: torch.Tensor
    seconds: float = 0.0


_FIELDS = ("valid", "hit", "hit_world", "hit_view", "hit_pixel", "on_screen", "visible", "back_face",
           "hit_shape", "ray_length", "radiance")


def _vec(v, H, W) -> torch.Tensor:
    return torch.stack([v.x.torch(), v.y.torch(), v.z.torch()]).double().reshape(1, 3, H, W)


def reflections(scene, gbuffer: GBuffer, *, spp: int = 16, seed: int = 0, use_cache: bool = True
                ) -> ReflectionReference:
    """Trace the exact mirror ray of every pixel of ``gbuffer`` (batch 1) in ``scene``.

    Args:
        scene: the scene the G-buffer was rendered from (Scene, catalog name, file or dict).
        gbuffer: its camera fixes the pixel centres; channels are not read.
        spp: path samples for ``radiance`` (> 0).
        seed: seed of the radiance samples; same seed → same bits.
    """
    if not isinstance(gbuffer, GBuffer):
        raise TypeError(f"gbuffer: expected a GBuffer, got {type(gbuffer).__name__}")
    if isinstance(spp, bool) or not isinstance(spp, int) or spp <= 0:
        raise ValueError(f"spp: must be a positive integer, got {spp!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    sc, cam = load_scene(scene), gbuffer.camera
    key = cache.make_key("reflections", _KERNEL_VERSION, sc.content_hash(), cam, spp, seed)
    hit_c = cache.load(key) if use_cache else None
    if hit_c is not None:
        return ReflectionReference(**{k: torch.from_numpy(hit_c[k]) for k in _FIELDS},
                                   seconds=float(hit_c["seconds"]))
    if not backend.is_jit():
        raise RuntimeError("reflections needs a vectorised Mitsuba variant; apt-get install -y libllvm19")
    t0 = time.perf_counter()
    mi = backend.mitsuba()
    import drjit as dr
    mscene = convert.load(sc, cam)
    W, H, N = cam.width, cam.height, cam.width * cam.height
    idx = dr.arange(mi.UInt32, N)
    pos = mi.Point2f((mi.Float(idx % W) + 0.5) / W, (mi.Float(idx // W) + 0.5) / H)
    ray, _ = mscene.sensors()[0].sample_ray(0.0, 0.0, pos, mi.Point2f(0.5, 0.5))
    si = mscene.ray_intersect(ray)
    valid = si.is_valid()

    # ---- Mirror ray about the shading normal turned toward the viewer ----
    n = si.sh_frame.n
    n = dr.select(dr.dot(n, ray.d) > 0, -n, n)
    r_dir = dr.normalize(ray.d - 2.0 * dr.dot(ray.d, n) * n)
    # origin nudged along r itself (not along n as spawn_ray does, which shifts the whole line by ~1e-4·|p| and
    # the hit by ~1e-3 relative): the ray stays on the exact mirror line, scale-invariantly
    eye = mi.Point3f(*[dr.opaque(mi.Float, float(v)) for v in cam.eye])     # opaque: one kernel for every camera
    t_eye = si.t + dr.norm(ray.o - eye)
    step = 1e-4 * t_eye
    rray = mi.Ray3f(ray.o + si.t * ray.d + step * r_dir, r_dir)
    si_r = mscene.ray_intersect(rray, valid)
    hit = valid & si_r.is_valid()
    p = rray.o + si_r.t * rray.d

    # ---- Seen from the camera: an eye ray to the hit point, and facing ----
    to_p = p - eye
    dist = dr.norm(to_p)
    pi = mscene.ray_intersect_preliminary(mi.Ray3f(eye, to_p / dr.maximum(dist, 1e-30)), active=hit)
    visible = hit & (pi.t >= dist * (1.0 - 1e-4))
    back_face = hit & (dr.dot(si_r.n, eye - p) < 0)
    shapes, rids = mscene.shapes(), dr.reinterpret_array(mi.UInt32, mscene.shapes_dr()).numpy()
    table = np.full(int(rids.max()) + 1, -1, dtype=np.int32)
    for rid, sh in zip(rids, shapes):
        table[int(rid)] = convert.scene_index(sh.id())
    hit_shape = dr.select(hit, dr.gather(mi.Int32, mi.Int32(table), dr.reinterpret_array(mi.UInt32, si_r.shape),
                                         hit), -1)

    # ---- Radiance along the mirror ray (path tracer, spp passes of one sample) ----
    sampler = mi.load_dict({"type": "independent"})
    integrator = mscene.integrator()
    acc = torch.zeros(3, N, dtype=torch.float64)
    dr.eval(rray, valid)                             # traced once, not again in every sample's kernel
    for k in range(spp):
        sampler.seed(dr.opaque(mi.UInt32, pass_seed(seed, k)), N)
        L, _, _ = integrator.sample(mscene, sampler, mi.RayDifferential3f(rray), None, valid)
        L = dr.select(valid, L, 0.0)
        dr.eval(L)                                   # one kernel for x, y, z (one conversion each traced 3 paths)
        acc += torch.stack([L.x.torch(), L.y.torch(), L.z.torch()]).double()
    radiance = (acc / spp).reshape(1, 3, H, W).float()

    # ---- To torch, project the hits (float64) ----
    ray_t = si_r.t + step
    dr.eval(hit, valid, p, visible, back_face, hit_shape, ray_t)       # one kernel, not one trace per conversion
    mask = lambda b: b.torch().reshape(1, 1, H, W).clone()                   # noqa: E731
    hit_t, valid_t = mask(hit), mask(valid)
    pw = torch.where(hit_t, _vec(p, H, W), torch.zeros(1, 3, H, W, dtype=torch.float64))
    pv = torch.where(hit_t, cam.world_to_view(pw), torch.zeros_like(pw))
    in_front = hit_t & (pv[:, 2:3] < -cam.near) & (pv[:, 2:3] > -cam.far)
    px = torch.where(in_front, cam.view_to_pixel(torch.where(in_front, pv, -torch.ones_like(pv))),
                     torch.full((1, 2, H, W), -1.0, dtype=torch.float64))
    on_screen = in_front & (px[:, :1] >= 0) & (px[:, :1] < W) & (px[:, 1:] >= 0) & (px[:, 1:] < H)
    length = torch.where(hit_t, ray_t.torch().double().reshape(1, 1, H, W),
                         torch.full((1, 1, H, W), float("inf"), dtype=torch.float64))
    out = dict(valid=valid_t, hit=hit_t, hit_world=pw.float(), hit_view=pv.float(), hit_pixel=px.float(),
               on_screen=on_screen, visible=mask(visible), back_face=mask(back_face),
               hit_shape=hit_shape.torch().reshape(1, 1, H, W).clone(), ray_length=length.float(),
               radiance=radiance)
    secs = time.perf_counter() - t0
    if use_cache:
        cache.store(key, {k: v.numpy() for k, v in out.items()} | {"seconds": np.array(secs)})
    return ReflectionReference(**out, seconds=secs)
