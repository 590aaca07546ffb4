"""What sample-counting SSAO estimates: the fraction of its sample kernel that lies *inside* geometry.

Crytek's SSAO and the normal-oriented hemisphere SSAO of SSAO article §1–§2.2 (mebiusbox, 「スクリーンスペース・
アンビエント・オクルージョン (SSAO)」, 2022,
https://zenn.dev/mebiusbox/articles/c7ea4871698ada) do not integrate visibility
over directions. They place sample *points* in a ball or half-ball around the shading point ``P`` and count
those that lie behind the depth buffer; as the sample count grows and the noise rotates the kernel, the
count converges to a **volume fraction**: the probability that a point drawn from the kernel's law lies
inside solid matter. These flavours are that limit, traced by Dr.Jit against the full scene:

================== ================================================================================
flavour            sample point ``S = P + R · k`` with ``k`` drawn from (per pixel, per sample)
================== ================================================================================
volume_hemisphere  the hemisphere kernel of :func:`ssbench.passes.sampling.hemisphere_kernel` in the
                   limit of many samples: direction ``normalize(2u₀−1, 2u₁−1, u₂)`` in the frame of the
                   pixel's normal, turned by a uniform angle about it (the rotation noise), length
                   ``u₃ · lerp(0.1, 1, t²)`` with ``t`` uniform (``i/N`` for ``N → ∞``)
volume_sphere      uniform in the unit ball (:func:`ssbench.passes.sampling.sphere_kernel`; reflection by
                   the noise vector keeps the law)
================== ================================================================================

AO is ``1 −`` the inside fraction (an open plane: 1 for the hemisphere, 0.5 for the sphere — Crytek's grey).

**Inside test, without a depth buffer.** ``S`` is inside when the nearest surface on the segment from ``S``
to the eye is met from its back side (geometric normal along the ray, ``n·d > 0``): inside a solid, or behind
an open surface (a floor, a wall) as the camera sees it. A segment that meets nothing, or meets a surface's
front first, leaves ``S`` outside: in the open, possibly behind a thin object — which is exactly where a
depth-buffer count goes wrong (information loss, scored by the oracle). Run against the height-field mesh of
the depth buffer (the oracle), "inside" is "behind the depth buffer": what the passes count; there the segment
lies on one line of sight, so :func:`ssbench.reference.heightfield.behind` answers it by lookup instead of tracing.
(Aiming the segment at ``P`` instead would meet the height field exactly at a vertex, where rays slip through.)
"""
from __future__ import annotations

VOLUME_WEIGHTINGS = ("volume_hemisphere", "volume_sphere")


def kernel_point(mi, dr, rng, weighting: str):
    """One kernel offset ``k`` (|k| < 1) in the local frame of the normal (+z up), drawn from ``rng``."""
    if weighting == "volume_sphere":
        u = mi.Point2f(rng.next_float32(), rng.next_float32())
        r = dr.cbrt(rng.next_float32())                                    # uniform in volume
        return mi.warp.square_to_uniform_sphere(u) * r
    x = 2.0 * rng.next_float32() - 1.0
    y = 2.0 * rng.next_float32() - 1.0
    z = rng.next_float32()
    length = rng.next_float32()
    t = rng.next_float32()
    phi = 2.0 * dr.pi * rng.next_float32()                                 # the noise's turn about n
    d = dr.normalize(mi.Vector3f(x, y, z))
    s, c = dr.sincos(phi)
    d = mi.Vector3f(c * d.x - s * d.y, s * d.x + c * d.y, d.z)
    scale = 0.1 + 0.9 * t * t                                              # lerp(0.1, 1.0, t^2)
    return d * (length * scale)


def inside(mi, dr, mscene, eye, s, active):
    """Mask of sample points ``s`` inside geometry, seen along the segment toward the ``eye``."""
    v = eye - s
    dist = dr.norm(v)
    ok = active & (dist > 0)
    d = v / dr.maximum(dist, 1e-30)
    ray = mi.Ray3f(s, d)
    ray.maxt = dist
    si = mscene.ray_intersect(ray, ok)
    return ok & si.is_valid() & (dr.dot(si.n, d) > 0)


def visibility(mi, dr, src, frame, radius, rng, weighting: str):
    """Per-sample visibility (1 outside, 0 inside) of one kernel point ``S = p + R·k`` per pixel.

    ``src`` is the caller's :class:`ssbench.reference.ao.RaySource`: ``p`` is ``src.origin.p``, ``k`` turns from
    the normal's ``frame`` into tracing space by ``src.view_to_tracing``, and ``src.is_inside(s, active)`` answers
    the inside test (:func:`inside` against the scene, or :func:`ssbench.reference.heightfield.behind` for the
    oracle) on the pixels ``src.active``."""
    k = kernel_point(mi, dr, rng, weighting)
    s = src.origin.p + (src.view_to_tracing @ frame.to_world(k)) * radius
    return dr.select(src.is_inside(s, src.active), 0.0, 1.0)
