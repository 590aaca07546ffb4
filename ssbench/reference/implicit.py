r"""Certified first-hit ground truth for implicit surfaces f(p) = 0 (progressive-tracing article): interval march + bisection.

Per pixel, in float64, on the rays of :func:`ssbench.rays.camera_rays` (unit ``d``, ``t`` in
world units), root isolation by interval bisection (Mitchell, "Robust Ray Intersection with Interval Arithmetic",
Graphics Interface 1990):

1. **Clip** ``[t_near, t_far]`` to the surface's world ``bounds`` (slab test; f > 0 outside them).
2. **Interval march**, front to back and lock-step over all rays: a ray holds a position ``a`` and a trial
   width ``h``; the axis-aligned box of the segment ``o + t d, t ∈ [a, a + h]`` (corners widened outward by
   the rounding of ``o + t d`` and one ``nextafter``) goes through ``surface.interval``.

   * enclosure excludes 0 (``lo > 0`` or ``hi < 0``): the segment is root-free → ``a += h``, ``h *= 2``;
   * else, while ``h > tolerance·max(1, a)``: ``h /= 2`` (a NaN enclosure means "may hold a root");
   * else the segment is a *leaf*: point values ``f(a) ≥ 0 > f(a+h)`` → the first **entering** root is
     bracketed (a hit); ``f(a) < 0 ≤ f(a+h)`` → an exiting crossing (a ray starting inside), go on; no sign
     change → the leaf is *unresolved*, go on.

   A run of consecutive unresolved leaves that leads straight into the hit leaf is IA over-estimation just
   in front of a simple root (part of its bracket). A run that ends in an excluded segment (or the end of
   the ray) is **ambiguous**: a tangency, a double root such as (‖p‖−1)², an undefined/NaN region, or
   over-estimation IA could not resolve at the leaf width; ``ambiguous_t`` is the start of the first one.
   Two engines run these rules. **Dr.Jit** (default for parsed surfaces, :mod:`.implicit_drjit`): each ray
   applies them one segment at a time inside one symbolic Dr.Jit loop, with the Dr.Jit interval evaluator
   (:mod:`ssbench.implicit.interval_drjit`); 75–300× faster than torch once compiled (0.3–0.6 s to compile a
   new expression). **torch** (any surface with the protocol, :mod:`.implicit_march`): lock-step over rays,
   one iteration evaluating several segments per ray in one ``surface.interval`` call (``K`` consecutive
   widths ``h`` plus ``J`` halvings of the first, fewer lanes when many rays are active), consumed in order
   by the rules above; the lane schedule depends on the number of active rays, so a different image size or
   batch can move ``t`` at the ``epsilon`` level (identical inputs: identical bits). The engines' leaves can
   differ at the ``tolerance`` level, so ``t`` can differ at the ``epsilon`` level; hits and certificates
   agree on the catalog (tested).
3. **Bisection** of the hit bracket to ``(hi − lo) ≤ epsilon·max(1, t)``; ``t`` is the bracket midpoint.

The hit is the article's event ``f(t_i) ≥ 0 > f(t_{i+1})`` (progressive-tracing article, レイキャスティング), so every march,
the dense cross-check (:func:`ssbench.reference.implicit_dense.dense_march`) and the reference agree on what a
root is. Roots **without a sign change** are not hits: sign-change methods cannot see them; interval
arithmetic does see them, as ``ambiguous_t``. ``certified`` means every part of ``[t_start, t)`` (the whole
clipped ray for a miss) was excluded by an interval test, except the unresolved run leading into the hit
leaf, whose ends all have ``f ≥ 0``: the first entering root is isolated to that bracket (``isolation``,
at most :data:`ISOLATION_LEAVES` leaf widths ``tolerance·max(1, t)``; a root pair inside it cannot be told
apart). No ambiguous run and no exiting crossing came first, and the march finished. A ray that hits the
iteration cap is ``unfinished`` (never a silent miss).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, fields, is_dataclass
from typing import Optional

import torch

from ..implicit.shading import shade_hits
from ..indices import flat_nonzero
from .implicit_dense import flat_rays, clip_to_bounds
from .implicit_drjit import bisect_drjit, drjit_ready, interval_march_drjit
from .implicit_march import bisect_brackets, interval_march, segment_box  # noqa: F401 (segment_box: API)

__all__ = ["implicit", "ImplicitReference", "segment_box", "ISOLATION_LEAVES", "ENGINES", "engine_of"]

_KERNEL_VERSION = 4  # 2: the `isolation` field; 3: long unresolved runs crossed with doubling leaves; 4: engines
#: a hit is certified only if its isolating bracket is at most this many leaf widths long
ISOLATION_LEAVES = 64


@dataclass(frozen=True)
class ImplicitReference:
    r"""Certified first hits; every tensor is :math:`(B, C, H, W)` (``C`` = 1 unless noted).

    Attributes:
        t: float64 first entering root (bracket midpoint; ``t_far`` where none or unfinished).
        hit: bool, a sign-changing root ``f ≥ 0 → f < 0`` was bracketed and refined.
        certified: bool, ``[t_start, t)`` (``[t_start, t_end]`` on a miss) was excluded by interval tests up
            to the short unresolved run leading into the hit leaf, and the march finished (module docstring).
        ambiguous_t: float64 start of the first ambiguous run before the hit (or on a miss), ``+inf`` if none.
        t_exit: float64 with ``exits=True`` the next crossing back to ``f ≥ 0`` after the hit (bisected; the
            slab's chord end, ``t_end`` if the chord leaves the clipped range); equals ``t`` where no hit or
            ``exits=False``. ``t_exit − t`` is the chord ``w`` of the h/w prediction.
        isolation: float64 width of the bracket known to hold the first entering root: from the start of the
            unresolved run leading into the hit leaf (or the leaf itself) to the leaf's end (0 where no hit).
            ``certified`` needs it ≤ ``ISOLATION_LEAVES`` leaf widths (catalog scenes: ≤ 6).
        normal: :math:`(B, 3, H, W)` float64 unit ``∇f/|∇f|`` at the hit (0 where none).
        object_index: int32 ``surface.object_index`` at the hit (0 if the surface has none; −1 where none).
        interval_evaluations, point_evaluations: int32 per pixel (bisection and the normal's gradient
            included; a gradient counts as one point evaluation).
        unfinished: bool, the march ran out of ``max_iterations`` before deciding the first hit.
        t_start, t_end: float64 the clipped range (``t_start ≥ t_end``: the ray misses the bounds).
        iterations: torch engine: lock-step march iterations run; Dr.Jit engine: the most segments one ray
            tested. ``seconds``: wall time (a Dr.Jit kernel's first compilation included). ``engine``: which ran.

    ``interval_evaluations`` counts every box evaluated, the speculative lanes included.
    """

    t: torch.Tensor
    hit: torch.Tensor
    certified: torch.Tensor
    ambiguous_t: torch.Tensor
    t_exit: torch.Tensor
    isolation: torch.Tensor
    normal: torch.Tensor
    object_index: torch.Tensor
    interval_evaluations: torch.Tensor
    point_evaluations: torch.Tensor
    unfinished: torch.Tensor
    t_start: torch.Tensor
    t_end: torch.Tensor
    iterations: int = 0
    seconds: float = 0.0
    engine: str = "torch"


_TENSORS = tuple(f.name for f in fields(ImplicitReference) if f.name not in ("iterations", "seconds", "engine"))
#: the march engines of :func:`implicit`
ENGINES = ("auto", "torch", "drjit")


def engine_of(surface, engine: str = "auto") -> str:
    """The engine :func:`implicit` runs for ``surface``: ``"drjit"`` for ``"auto"`` when
    :func:`~ssbench.reference.implicit_drjit.drjit_ready` (else ``"torch"``); an explicit ``"drjit"`` the surface
    cannot use is a ``ValueError``."""
    if engine == "torch":
        return "torch"
    ready = drjit_ready(surface)
    if engine == "drjit" and not ready:
        raise ValueError("engine: 'drjit' needs a parsed implicit surface without the real power 'pow' and a "
                         "vectorised Mitsuba variant (llvm_ad_rgb; apt-get install -y libllvm19)")
    return "drjit" if ready else "torch"


def _bisect_drjit(surface, o, d, lo, hi, epsilon, n_pt, lo_nonneg):
    """:func:`bisect_drjit` with :func:`~.implicit_march.bisect_brackets`' signature (adds to ``n_pt`` in place)."""
    t, n = bisect_drjit(surface, o, d, lo, hi, epsilon, lo_nonneg)
    n_pt += n.to(n_pt.dtype)
    return t


def _check(epsilon, max_iterations, tolerance, batch):
    if isinstance(epsilon, bool) or not isinstance(epsilon, (int, float)) or not 1e-15 <= epsilon < 1:
        raise ValueError(f"epsilon: must be a float in [1e-15, 1), got {epsilon!r}")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, int) or max_iterations <= 0:
        raise ValueError(f"max_iterations: must be a positive integer, got {max_iterations!r}")
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) or not max(epsilon, 1e-14) \
            <= tolerance < 1:
        raise ValueError(f"tolerance: must be a float in [max(epsilon, 1e-14), 1), got {tolerance!r}")
    if isinstance(batch, bool) or not isinstance(batch, int) or batch <= 0:
        raise ValueError(f"batch: must be a positive integer, got {batch!r}")


def _surface_key(surface) -> Optional[object]:
    """A content key for the cache: ``cache_key``/``content_hash`` if the surface has one, else the objects of
    an ``ImplicitSurface`` (expression dataclass repr, bounds, transform); None (no caching) otherwise."""
    for name in ("cache_key", "content_hash"):
        k = getattr(surface, name, None)
        if k is not None:
            return k() if callable(k) else k
    objs = getattr(surface, "objects", None)
    if not objs or not all(is_dataclass(getattr(o, "expression", None)) for o in objs):
        return None                          # a repr could hold a memory address: never cache on it
    return [type(surface).__name__] + [[repr(o.expression), o.bounds, o.translate, o.rotate, o.scale]
                                        for o in objs]


def implicit(surface, camera, *, epsilon: float = 1e-12, max_iterations: int = 20000, exits: bool = False,
             batch: int = 1, jitter: Optional[torch.Tensor] = None, tolerance: float = 1e-7,
             use_cache: bool = True, engine: str = "auto") -> ImplicitReference:
    r"""Certified first entering root of ``surface`` on every pixel ray of ``camera`` (see the module docstring).

    Args:
        surface: the surface protocol of :mod:`ssbench.passes.implicit.common` (``f``, ``f_and_grad``,
            ``interval``, ``bounds``; ``object_index`` optional).
        camera: the :class:`~ssbench.camera.Camera`; rays are ``camera_rays(camera, batch, jitter, float64)``.
        epsilon: relative bisection width: stop when ``hi − lo ≤ epsilon·max(1, t)``.
        max_iterations: cap on lock-step interval-march iterations; undecided rays are ``unfinished``.
        exits: also march on past the hit to the next crossing back to ``f ≥ 0`` (``t_exit``, the chord).
        batch, jitter: as :func:`~ssbench.rays.camera_rays` (``jitter`` :math:`(B, 2, H, W)`).
        tolerance: relative width of a leaf segment (``tolerance·max(1, t)``), where subdivision stops and
            point signs decide; an ambiguous stretch costs about ``tolerance^{-1/2}`` leaves at an exact
            tangency, so keep it ≥ 1e-9.
        use_cache: read/write the on-disk cache (only when the surface has ``cache_key``/``content_hash``).
        engine: ``"torch"`` (the lock-step march of :mod:`.implicit_march`, any surface with the protocol),
            ``"drjit"`` (the same method as one Dr.Jit kernel, :mod:`.implicit_drjit`: 75–290× faster once
            compiled; parsed catalog/file surfaces without the real power ``pow``, a vectorised Mitsuba variant)
            or ``"auto"`` (Dr.Jit where it can run, else torch).

    Returns:
        :class:`ImplicitReference`.

    Example:
        >>> from ssbench.camera import Camera
        >>> class Ball:                                   # ‖p‖² − 1 with a hand-written enclosure
        ...     bounds = ((-1, -1, -1), (1, 1, 1))
        ...     def f(self, p): return (p * p).sum(-1) - 1
        ...     def f_and_grad(self, p): return self.f(p), 2 * p
        ...     def interval(self, lo, hi):
        ...         m = torch.where((lo <= 0) & (hi >= 0), 0.0, torch.minimum(lo * lo, hi * hi))
        ...         return m.sum(-1) - 1, torch.maximum(lo * lo, hi * hi).sum(-1) - 1
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 30.0, 3, 3, 0.1, 10.0)
        >>> ref = implicit(Ball(), cam)
        >>> round(float(ref.t[0, 0, 1, 1]), 9), bool(ref.certified.all()), int(ref.hit.sum())
        (3.0, True, 9)
    """
    _check(epsilon, max_iterations, tolerance, batch)
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {', '.join(ENGINES)}, got {engine!r}")
    for name in ("f", "f_and_grad", "interval"):
        if not callable(getattr(surface, name, None)):
            raise TypeError(f"surface: needs a callable {name!r} (the implicit surface protocol), "
                            f"got {type(surface).__name__}")
    bounds = getattr(surface, "bounds", None)
    if bounds is None or len(bounds) != 2 or any(len(b) != 3 for b in bounds):
        raise ValueError(f"surface.bounds: expected ((x0, y0, z0), (x1, y1, z1)), got {bounds!r}")
    engine = engine_of(surface, engine)
    key = None
    skey = _surface_key(surface) if use_cache and jitter is None else None
    if skey is not None:
        from . import cache
        key = cache.make_key("implicit", _KERNEL_VERSION, skey, camera, epsilon, max_iterations, exits, batch,
                             tolerance, engine)
        got = cache.load(key)
        if got is not None:
            return ImplicitReference(**{k: torch.from_numpy(got[k]) for k in _TENSORS},
                                     iterations=int(got["iterations"]), seconds=float(got["seconds"]), engine=engine)
    start = time.perf_counter()
    o, d, tn, tf, img = flat_rays(camera, batch, jitter)
    t0, t1 = clip_to_bounds(o, d, tn, tf, bounds)
    if engine == "drjit":
        s = interval_march_drjit(surface, o, d, t0, t1, float(tolerance), max_iterations, exits)
        bisect = _bisect_drjit
    else:
        s = interval_march(surface, o, d, t0, t1, float(tolerance), max_iterations, exits)
        bisect = bisect_brackets
    found, n_pt = s["found"], s["n_pt"]
    t, t_exit = tf.clone(), tf.clone()
    gi = flat_nonzero(found)
    normal = torch.zeros_like(o)
    obj = torch.full((o.shape[0],), -1, dtype=torch.int32)
    if gi.numel():
        sub = n_pt[gi].clone()
        t[gi] = bisect(surface, o[gi], d[gi], s["br_lo"][gi], s["br_hi"][gi], epsilon, sub, True)
        normal[gi], obj[gi] = shade_hits(surface, o[gi] + t[gi, None] * d[gi])      # one gradient each
        n_pt[gi] = sub + 1
        t_exit[gi] = t[gi]
        if exits:
            t_exit[gi] = torch.maximum(s["ex_lo"][gi], t[gi])           # no exit: where the march stopped
            ex = gi[~s["no_exit"][gi]]
            if ex.numel():
                sub = n_pt[ex].clone()
                t_exit[ex] = bisect(surface, o[ex], d[ex], s["ex_lo"][ex], s["ex_hi"][ex], epsilon, sub, False)
                n_pt[ex] = sub
    unfinished = s["unfinished"]
    iso = torch.where(found, s["br_hi"] - s["iso"], 0.0)
    short = iso <= ISOLATION_LEAVES * tolerance * t.abs().clamp(min=1.0)
    out = dict(t=img(t), hit=img(found), certified=img(s["clean"] & ~unfinished & short),
               ambiguous_t=img(s["amb"]), t_exit=img(t_exit), isolation=img(iso), normal=img(normal, 3),
               object_index=img(obj),
               interval_evaluations=img(s["n_int"]), point_evaluations=img(n_pt), unfinished=img(unfinished),
               t_start=img(torch.where(t1 > t0, t0, tf)), t_end=img(torch.where(t1 > t0, t1, tf)))
    ref = ImplicitReference(**out, iterations=s["iterations"], seconds=time.perf_counter() - start, engine=engine)
    if key is not None:
        import numpy as np
        from . import cache
        cache.store(key, dict({k: v.numpy() for k, v in out.items()}, iterations=np.array(ref.iterations),
                              seconds=np.array(ref.seconds)))
    return ref
