"""Ray-traced ambient-occlusion ground truth, and the screen-space oracle.

Five flavours, each the quantity one family of screen-space passes estimates:

========== ===================================== ===============================================
weighting  directions over the hemisphere        per-ray visibility
========== ===================================== ===============================================
uniform    uniform in solid angle                1 if nothing within ``radius`` else 0
cosine     cosine-weighted (``cos θ / π``)       1 if nothing within ``radius`` else 0
obscurance uniform in solid angle                ``1 − ρ(t)``, ``ρ(t) = 1 − (t/R)²`` for a hit at
                                                 ``t < R`` (HBAO's ``W(r) = 1 − r²``), else 1
========== ===================================== ===============================================

plus the two **volume** flavours of :mod:`ssbench.reference.ao_volume` (``volume_hemisphere``,
``volume_sphere``): the fraction of a sample kernel's points that lie outside geometry, what the
point-counting SSAO passes (hemisphere, Crytek) converge to.

AO is the mean over ``rays`` samples per pixel. ``stderr`` is never 0 on finite samples: for the binary flavours
(uniform, cosine) it is the standard deviation of the Jeffreys posterior of the proportion
(:func:`jeffreys_variance`, ≈ the sample ``sd/√rays`` in the middle, ≈ ``1/(√2·rays)`` where every ray agrees);
for obscurance the sample ``sd/√rays``, floored at the Jeffreys value of an unanimous pixel.
Directions are drawn in the **view-space** frame of the pixel's normal from a PCG32 stream per pixel, so the
full ground truth and the oracle use the same directions (paired comparison) and the same seed gives the same
bits. Origins are offset by Mitsuba's ``spawn_ray`` so an open plane gives exactly 1.

:func:`screen_space_oracle` traces the same rays against the *depth buffer as a height-field mesh* (every
pixel centre a vertex, background at the far plane, neighbouring pixels joined across discontinuities,
:mod:`ssbench.reference.heightfield`): the only geometry a screen-space pass can see. ``oracle − full`` is the
information loss; ``method − oracle`` is the estimator's own error.
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from ..gbuffer import GBuffer
from ..scenes import load as load_scene
from . import ao_volume, backend, cache, convert, heightfield

WEIGHTINGS = ("uniform", "cosine", "obscurance") + ao_volume.VOLUME_WEIGHTINGS
_KERNEL_VERSION = 2  # 2: Jeffreys standard errors (never 0)
_ORACLE_VERSION = 3  # 3: the volume flavours by depth-buffer lookup (heightfield.behind), not by tracing


@dataclass(frozen=True)
class AOReference:
    """Ground-truth AO: ``ao`` and ``stderr`` are :math:`(1, 1, H, W)` float32 (background: 1 and 0)."""

    ao: torch.Tensor
    stderr: torch.Tensor
    weighting: str
    radius: float
    rays: int
    seconds: float = 0.0


def check_arguments(gbuffer: GBuffer, radius: float, rays: int, weighting: str, seed: int) -> None:
    """The AO-style ground truths' argument checks (each error names its argument)."""
    if not isinstance(gbuffer, GBuffer):
        raise TypeError(f"gbuffer: expected a GBuffer, got {type(gbuffer).__name__}")
    if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not radius > 0:
        raise ValueError(f"radius: must be a number > 0, got {radius!r}")
    if isinstance(rays, bool) or not isinstance(rays, int) or rays < 2:
        raise ValueError(f"rays: must be an integer >= 2 (for a standard error), got {rays!r}")
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting: expected one of {WEIGHTINGS}, got {weighting!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    if gbuffer.batch_size != 1:
        raise ValueError(f"gbuffer: batch size must be 1, got {gbuffer.batch_size}")


@dataclass(frozen=True)
class RaySource:
    """Where each pixel's samples start and what they are tested against (Dr.Jit values, one per pixel).

    Attributes:
        scene: the Mitsuba scene the ray flavours trace (the full scene, or the depth buffer's height field).
        origin: a ``SurfaceInteraction3f`` whose ``spawn_ray`` offsets each ray (reads ``p``, ``n``).
        n_view: the view-space normal, the frame the directions are drawn in.
        view_to_tracing: the rotation from view space to the space ``scene`` lives in.
        active: ``Bool``, pixels with a surface.
        is_inside: ``is_inside(s, active)``, the volume flavours' inside test of points in tracing space.
    """

    scene: object
    origin: object
    n_view: object
    view_to_tracing: object
    active: object
    is_inside: Callable


def _estimate(mi, dr, src: RaySource, radius: float, rays: int, weighting: str, seed: int):
    """Accumulate per-pixel mean and variance over ``rays`` directions, in one Dr.Jit kernel (a symbolic
    ``while_loop`` over the rays: the same draws and sums, in the same order, as one kernel per ray, which
    launched ``rays`` kernels and ran 1.1–2.5× slower: 33 → 53 Mrays/s on cornell_box, cosine, 320×240, 256 rays,
    2 threads)."""
    N = dr.width(src.active)
    frame = mi.Frame3f(src.n_view)
    rng = mi.PCG32(size=N, initstate=dr.opaque(mi.UInt64, seed), initseq=dr.arange(mi.UInt64, N))
    R = dr.opaque(mi.Float, radius)

    def body(k, s1, s2, rng):
        if weighting in ao_volume.VOLUME_WEIGHTINGS:
            v = ao_volume.visibility(mi, dr, src, frame, R, rng, weighting)
        else:
            v = _ray_visibility(mi, dr, src, frame, R, rng, weighting)
        return k + 1, s1 + v, s2 + v * v, rng

    _, s1, s2, rng = dr.while_loop((mi.UInt32(0), dr.zeros(mi.Float, N), dr.zeros(mi.Float, N), rng),
                                   lambda k, *_: k < rays, body)
    mean = s1 / rays
    n = float(rays)
    if weighting == "obscurance":                  # continuous visibility: sample variance, Jeffreys floor
        var = dr.maximum((s2 - rays * mean * mean) / ((rays - 1) * n), jeffreys_variance(n, n))
    else:                                          # binary rays: the Jeffreys posterior Beta(k + ½, n − k + ½)
        var = jeffreys_variance(s1, n)
    return mean, dr.sqrt(var)


def _ray_visibility(mi, dr, src: RaySource, frame, R, rng, weighting: str):
    """Visibility of one hemisphere direction per pixel (uniform / cosine: binary; obscurance: (t/R)²)."""
    mscene, active = src.scene, src.active
    u = mi.Point2f(rng.next_float32(), rng.next_float32())
    local = (mi.warp.square_to_cosine_hemisphere(u) if weighting == "cosine"
             else mi.warp.square_to_uniform_hemisphere(u))
    ray = src.origin.spawn_ray(src.view_to_tracing @ frame.to_world(local))   # view frame -> tracing space
    ray.maxt = R
    if weighting == "obscurance":
        pi = mscene.ray_intersect_preliminary(ray, active=active)
        x = dr.clip(pi.t / R, 0.0, 1.0)
        return dr.select(pi.is_valid(), x * x, 1.0)                        # 1 − ρ(t) = (t/R)²
    return dr.select(mscene.ray_test(ray, active), 0.0, 1.0)


def jeffreys_variance(k, n):
    r"""Variance of the Jeffreys posterior :math:`\mathrm{Beta}(k + \tfrac12, n - k + \tfrac12)` of a
    proportion after ``k`` successes in ``n`` binary trials (Brown, Cai & DasGupta, "Interval estimation for a
    binomial proportion", Statistical Science 16(2), 2001, https://doi.org/10.1214/ss/1009213286):

    .. math::  \sigma^2 = \frac{(k + \tfrac12)(n - k + \tfrac12)}{(n + 1)^2 (n + 2)}

    Close to the sample :math:`p(1-p)/n` in the middle, and never 0: when every ray agrees (``k = 0`` or
    ``n``) it is :math:`\approx 1/(2n^2)`, so an unanimous pixel still carries an honest error bar. Works
    on floats, tensors and Dr.Jit arrays alike.

    Example:
        >>> round(jeffreys_variance(128, 256) ** 0.5, 5), round(jeffreys_variance(256, 256) ** 0.5, 5)
        (0.03113, 0.00274)
    """
    return (k + 0.5) * (n - k + 0.5) / ((n + 1.0) ** 2 * (n + 2.0))


def _to_torch(dr, mean, err, hit, H, W) -> tuple[torch.Tensor, torch.Tensor]:
    """AO and its standard error as torch images. Both are evaluated in one kernel: converting one lazy array at a
    time ran the whole ray loop once per array (twice the tracing)."""
    ao, se = dr.select(hit, mean, 1.0), dr.select(hit, err, 0.0)
    dr.eval(ao, se)
    return ao.torch().reshape(1, 1, H, W).clone(), se.torch().reshape(1, 1, H, W).clone()


def _v2w(mi, cam):
    """View → world rotation as a Dr.Jit transform (directions only)."""
    m = cam.camera_to_world().tolist()
    return mi.Transform4f([[m[0][0], m[0][1], m[0][2], 0.0], [m[1][0], m[1][1], m[1][2], 0.0],
                           [m[2][0], m[2][1], m[2][2], 0.0], [0.0, 0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class PrimaryHits:
    """The pixel-centre rays of a camera traced once (Dr.Jit arrays of length H·W): ``ray``, the surface
    interaction ``si``, ``hit``, the view-space normal ``n_view`` turned toward the camera, and ``v2w`` (view →
    world rotation) that takes view-space sample directions to tracing space."""

    ray: object
    si: object
    hit: object
    n_view: object
    v2w: object


def primary_hits(mi, dr, mscene, cam) -> PrimaryHits:
    """Trace ``cam``'s pixel centres in the loaded Mitsuba scene: the origins and frames every AO-style ground
    truth (:func:`ambient_occlusion`, :func:`ssbench.reference.bent_normal.bent_normals`) samples from."""
    W, H = cam.width, cam.height
    idx = dr.arange(mi.UInt32, W * H)
    pos = mi.Point2f((mi.Float(idx % W) + 0.5) / W, (mi.Float(idx // W) + 0.5) / H)
    ray, _ = mscene.sensors()[0].sample_ray(0.0, 0.0, pos, mi.Point2f(0.5, 0.5))
    si = mscene.ray_intersect(ray)
    v2w = _v2w(mi, cam)
    dr.make_opaque(v2w)                          # one kernel for every camera (a literal would recompile it)
    w2v = v2w.inverse()
    n_view = dr.normalize(w2v @ mi.Vector3f(si.sh_frame.n))
    d_view = w2v @ mi.Vector3f(ray.d)
    n_view = dr.select(dr.dot(n_view, d_view) > 0, -n_view, n_view)            # face the camera
    return PrimaryHits(ray, si, si.is_valid(), n_view, v2w)


def trace_primaries(sc, cam, who: str) -> tuple:
    """``(mi, dr, mscene, PrimaryHits)``: the loaded Mitsuba scene of ``sc`` and ``cam``'s pixel centres traced in
    it, the common start of the AO-style ground truths; ``RuntimeError`` naming ``who`` without a vectorised
    Mitsuba variant."""
    if not backend.is_jit():
        raise RuntimeError(f"{who} needs a vectorised Mitsuba variant (llvm_ad_rgb or cuda_ad_rgb); "
                           "install libllvm19: apt-get install -y libllvm19")
    mi = backend.mitsuba()
    import drjit as dr
    mscene = convert.load(sc, cam)
    return mi, dr, mscene, primary_hits(mi, dr, mscene, cam)


def ambient_occlusion(scene, gbuffer: GBuffer, radius: float, rays: int = 256, weighting: str = "cosine",
                      seed: int = 0, *, use_cache: bool = True) -> AOReference:
    """Ray-traced AO of every G-buffer pixel against the full scene.

    Args:
        scene: the scene ``gbuffer`` was rendered from (Scene, catalog name, file or dict).
        gbuffer: a batch-1 reference G-buffer; its camera picks the pixel centres (rays are re-traced).
        radius: occlusion radius ``R`` in world units.
        rays: directions per pixel (≥ 2).
        weighting: ``"uniform"``, ``"cosine"`` or ``"obscurance"`` (see the module docstring).
        seed: PCG32 seed; same seed → same bits.

    Returns:
        :class:`AOReference` with ``ao`` and ``stderr`` of shape :math:`(1, 1, H, W)`.
    """
    check_arguments(gbuffer, radius, rays, weighting, seed)
    sc, cam = load_scene(scene), gbuffer.camera
    key = cache.make_key("ao", _KERNEL_VERSION, sc.content_hash(), cam, float(radius), rays, weighting, seed)
    hit_c = cache.load(key) if use_cache else None
    if hit_c is not None:
        return AOReference(torch.from_numpy(hit_c["ao"]), torch.from_numpy(hit_c["stderr"]), weighting,
                           float(radius), rays, float(hit_c["seconds"]))
    t0 = time.perf_counter()
    mi, dr, mscene, ph = trace_primaries(sc, cam, "ambient_occlusion")
    W, H = cam.width, cam.height

    def is_inside(s, active):
        return ao_volume.inside(mi, dr, mscene, ph.ray.o, s, active)

    src = RaySource(mscene, ph.si, ph.n_view, ph.v2w, ph.hit, is_inside)
    mean, err = _estimate(mi, dr, src, float(radius), rays, weighting, seed)
    ao, se = _to_torch(dr, mean, err, ph.hit, H, W)
    secs = time.perf_counter() - t0
    if use_cache:
        cache.store(key, {"ao": ao.numpy(), "stderr": se.numpy(), "seconds": np.array(secs)})
    return AOReference(ao, se, weighting, float(radius), rays, secs)


def screen_space_oracle(gbuffer: GBuffer, radius: float, rays: int = 256, weighting: str = "cosine",
                        seed: int = 0, *, use_cache: bool = True) -> AOReference:
    """AO traced against the depth buffer as a height-field mesh (what a screen-space pass can know).

    Uses the G-buffer's own ``position``, ``normal`` and ``mask`` (view space), the same per-pixel
    directions as :func:`ambient_occlusion` for the same ``seed``, and the same origin offset.
    """
    check_arguments(gbuffer, radius, rays, weighting, seed)
    gbuffer.require("position", "normal", "mask")
    h = hashlib.sha256()
    for t in (gbuffer.position, gbuffer.normal, gbuffer.mask):
        h.update(t.contiguous().numpy().tobytes())
    key = cache.make_key("oracle", _ORACLE_VERSION, h.hexdigest(), gbuffer.camera, float(radius), rays,
                         weighting, seed)
    hit_c = cache.load(key) if use_cache else None
    if hit_c is not None:
        return AOReference(torch.from_numpy(hit_c["ao"]), torch.from_numpy(hit_c["stderr"]), weighting,
                           float(radius), rays, float(hit_c["seconds"]))
    if not backend.is_jit():
        raise RuntimeError("screen_space_oracle needs a vectorised Mitsuba variant; apt-get install -y libllvm19")
    t0 = time.perf_counter()
    mi = backend.mitsuba()
    import drjit as dr
    H, W = gbuffer.height, gbuffer.width
    hf = heightfield.load(mi, dr, gbuffer, h.hexdigest())

    def is_inside(s, active):
        return heightfield.behind(mi, dr, hf, s, active)

    src = RaySource(hf.scene, hf.origin, hf.n_view, mi.Transform4f(), hf.hit, is_inside)
    mean, err = _estimate(mi, dr, src, float(radius), rays, weighting, seed)
    ao, se = _to_torch(dr, mean, err, hf.hit, H, W)
    secs = time.perf_counter() - t0
    if use_cache:
        cache.store(key, {"ao": ao.numpy(), "stderr": se.numpy(), "seconds": np.array(secs)})
    return AOReference(ao, se, weighting, float(radius), rays, secs)
