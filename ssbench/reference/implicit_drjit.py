"""The certified interval march of :mod:`ssbench.reference.implicit` as one Dr.Jit (LLVM) kernel per image.

The same method and certificate as the torch march (:func:`ssbench.reference.implicit_march.interval_march`;
Mitchell, "Robust Ray Intersection with Interval Arithmetic", Graphics Interface 1990), written as the plain
one-segment rule of the module docstring of :mod:`ssbench.reference.implicit`, per ray, inside one symbolic
``dr.while_loop``: no lock-step lanes, no compaction, no Python per iteration. Each loop turn tests the segment
``[a, min(a + h, t_end)]`` of every live ray with :func:`~ssbench.implicit.interval_drjit.surface_interval_drjit`:

* excluded → ``a`` moves to its end and ``h`` doubles (an open run of unresolved leaves is closed as ambiguous);
* not excluded and wider than a leaf (``tolerance·coarse·max(1, |a|)``) → ``h`` halves;
* a leaf → the point signs at its ends decide (entering root: the hit bracket; exiting root: not clean; no sign
  change: the run of unresolved leaves goes on), ``a`` moves on and ``h`` is twice the leaf.

Long unresolved runs are crossed with doubling leaves after :data:`~ssbench.reference.implicit_march.RUN_LEAVES`,
as in the torch march. The hit (and exit) brackets are then bisected in a second Dr.Jit loop with Dr.Jit's point
evaluator, the one that classified the leaf ends, so both ends of a bracket keep their classes. ``max_iterations``
caps the segments tested per ray (the torch march caps lock-step iterations, each testing up to 128 segments).

Enclosures are a few ulps looser than the torch evaluator's (outward widening by a relative margin instead of
exact directed rounding, :mod:`ssbench.implicit.interval_drjit`), so the two marches can stop at leaves that
differ at the ``tolerance`` level and ``t`` can differ at the ``epsilon`` level; hits, misses and certificates
agree on the catalog (tested).
"""
from __future__ import annotations

import math

import torch

from ..implicit.interval_drjit import MIN_NORMAL, down, subnormal, supported, surface_interval_drjit, up
from .implicit_march import RUN_LEAVES

__all__ = ["drjit_ready", "interval_march_drjit", "bisect_drjit"]

_EPS = 2.0 ** -52


def drjit_ready(surface) -> bool:
    """Whether ``surface`` is a union of parsed objects the Dr.Jit march can evaluate (``objects`` with an
    ``expression`` tree without the real power ``pow``, and ``drjit_f``), and a vectorised Dr.Jit backend runs."""
    objs = getattr(surface, "objects", None)
    if not objs or not callable(getattr(surface, "drjit_f", None)):
        return False
    if not all(getattr(getattr(o, "expression", None), "node", None) is not None for o in objs):
        return False
    for o in objs:
        numbers = list(getattr(o, "translate", ())) + [float(getattr(o, "scale", 1.0))] + \
            [v for row in getattr(o, "rotation", ()) for v in row]
        if not supported(o.expression.node, dict(o.expression.params)) or any(subnormal(v) for v in numbers):
            return False
    from . import backend
    return backend.is_jit()


def _modules():
    from . import backend
    backend.mitsuba()
    import drjit as dr
    import drjit.llvm as L
    return dr, L


def _arrays(L, *tensors):
    """float64 Dr.Jit arrays of the tensors, subnormals set to 0 (what a parallel kernel reads them as)."""
    out = []
    for t in tensors:
        t = t.detach().to(torch.float64).cpu()
        out.append(L.Float64(torch.where(t.abs() < MIN_NORMAL, 0.0, t).contiguous().numpy()))
    return out


def _point(surface, o, d, t):
    return surface.drjit_f(o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2])


def interval_march_drjit(surface, o, d, t0, t1, tol_rel, max_iterations, exits, run_leaves=RUN_LEAVES) -> dict:
    """The march on rays ``o``, ``d`` :math:`(N, 3)` over ``[t0, t1]`` :math:`(N,)`; returns the torch march's dict
    (``found``, ``iso``, ``br_lo``, ``br_hi``, ``ex_lo``, ``ex_hi``, ``no_exit``, ``amb``, ``clean``,
    ``unfinished``, ``n_int``, ``n_pt`` as torch tensors; ``iterations``: the most segments one ray tested)."""
    dr, L = _modules()
    N = o.shape[0]
    O, D = _arrays(L, *o.unbind(1)), _arrays(L, *d.unbind(1))
    a, T1 = _arrays(L, t0, t1)
    inf = dr.full(L.Float64, math.inf, N)
    h = T1 - a
    state = (a, h, T1 > a, dr.zeros(L.Bool, N), dr.zeros(L.Bool, N), dr.full(L.Bool, True, N),
             inf, inf, inf, inf, inf, inf, inf, dr.zeros(L.Int32, N), dr.zeros(L.Int32, N), dr.full(L.Float64, 1.0, N),
             dr.zeros(L.Int32, N), dr.zeros(L.Int32, N))
    cap, coarse_max = dr.opaque(L.Int32, int(max_iterations)), dr.opaque(L.Float64, 1.0 / tol_rel)
    tol_o = dr.opaque(L.Float64, tol_rel)

    def cond(a, h, active, *rest):
        return active

    def body(a, h, active, phase, found, clean, run, iso, br_lo, br_hi, ex_lo, ex_hi, amb, n_int, n_pt, coarse,
             n_run, it):
        b = dr.minimum(a + h, T1)
        lo, hi = [], []
        for k in range(3):                                   # the segment's box, widened outward
            pa, pb = O[k] + a * D[k], O[k] + b * D[k]
            m = dr.maximum(dr.abs(a), dr.abs(b))           # rounding of o + t·d, and a flushed d (< 2⁻¹⁰²²)
            slack = 4 * _EPS * (dr.abs(O[k]) + m * dr.abs(D[k])) + (1.0 + m) * 2.0 ** -1020
            lo.append(down(dr.minimum(pa, pb) - slack))
            hi.append(up(dr.maximum(pa, pb) + slack))
        flo, fhi = surface_interval_drjit(surface, lo, hi)
        excl = (flo > 0) | (fhi < 0)                         # NaN: may hold a root
        n_int = dr.select(active, n_int + 1, n_int)
        leaf = active & ~excl & (b - a <= tol_o * coarse * dr.maximum(dr.abs(a), 1.0))
        wide = active & ~excl & ~leaf
        moved = active & excl
        # ---- an excluded segment: close an open run (ambiguous), advance, grow
        closing = moved & dr.isfinite(run) & ~phase
        amb = dr.select(closing, dr.minimum(amb, run), amb)
        clean = clean & ~closing
        run = dr.select(closing, math.inf, run)
        n_run = dr.select(moved, 0, n_run)
        # ---- a leaf: the point signs at its ends
        fs, fe = _point(surface, O, D, a), _point(surface, O, D, b)
        n_pt = dr.select(leaf, n_pt + 2, n_pt)
        enter, leave = (fs >= 0) & (fe < 0), (fs < 0) & (fe >= 0)
        hit, out = leaf & ~phase & enter, leaf & phase & leave
        pend, back = leaf & ~phase & ~enter & ~leave, leaf & ~phase & leave
        iso = dr.select(hit, dr.minimum(run, a), iso)
        clean = clean & ~back
        run = dr.select(hit | back, math.inf, run)
        run = dr.select(pend & dr.isinf(run), a, run)
        n_run = dr.select(pend | (leaf & phase & ~leave), n_run + 1, n_run)
        n_run = dr.select(hit | out, 0, n_run)
        br_lo, br_hi = dr.select(hit, a, br_lo), dr.select(hit, b, br_hi)
        ex_lo, ex_hi = dr.select(out, a, ex_lo), dr.select(out, b, ex_hi)
        found, phase = found | hit, phase | hit
        stop = out | (hit if not exits else dr.zeros(L.Bool, N))
        h = dr.select(moved, 2.0 * h, dr.select(wide, 0.5 * h, dr.select(leaf, 2.0 * (b - a), h)))
        a = dr.select(moved | leaf, b, a)
        # ---- a long unresolved run is crossed with doubling leaves
        open_ = n_run > 0
        long_run = active & open_ & (n_run > run_leaves)
        coarse = dr.select(active, dr.select(open_, dr.select(long_run, dr.minimum(2.0 * coarse, coarse_max),
                                                              coarse), 1.0), coarse)
        h = dr.select(long_run, 2.0 * h, h)
        it = dr.select(active, it + 1, it)
        active = active & ~stop & (a < T1) & (it < cap)
        return (a, h, active, phase, found, clean, run, iso, br_lo, br_hi, ex_lo, ex_hi, amb, n_int, n_pt, coarse,
                n_run, it)

    s = dr.while_loop(state, cond, body)
    (a, h, active, phase, found, clean, run, iso, br_lo, br_hi, ex_lo, ex_hi, amb, n_int, n_pt, coarse, n_run,
     it) = s
    closing = dr.isfinite(run) & ~phase                      # a run not ended by a sign change was ambiguous
    amb, clean = dr.select(closing, dr.minimum(amb, run), amb), clean & ~closing
    no_exit = found & dr.isinf(ex_lo)
    ex_lo, ex_hi = dr.select(no_exit, a, ex_lo), dr.select(no_exit, a, ex_hi)
    unfinished = ~found & (a < T1) & (it >= cap)                # stopped by the cap, first hit undecided
    dr.eval(found, iso, br_lo, br_hi, ex_lo, ex_hi, no_exit, amb, clean, unfinished, n_int, n_pt, it)
    tt = lambda v: torch.from_numpy(v.numpy().copy())                           # noqa: E731
    return dict(found=tt(found), iso=tt(iso), br_lo=tt(br_lo), br_hi=tt(br_hi), ex_lo=tt(ex_lo), ex_hi=tt(ex_hi),
                no_exit=tt(no_exit), amb=tt(amb), clean=tt(clean), unfinished=tt(unfinished), n_int=tt(n_int),
                n_pt=tt(n_pt), iterations=int(dr.max(it)[0]) if N else 0)


def bisect_drjit(surface, o, d, lo, hi, epsilon: float, lo_nonneg: bool) -> tuple[torch.Tensor, torch.Tensor]:
    """Bisect brackets ``[lo, hi]`` (:math:`(M,)`) whose ``lo`` end has class ``(f ≥ 0) == lo_nonneg`` with the
    Dr.Jit point evaluator until ``hi − lo ≤ epsilon·max(1, |lo|)``; returns ``(midpoints, point evaluations)``."""
    dr, L = _modules()
    if o.shape[0] == 0:
        return lo.clone(), torch.zeros(0, dtype=torch.int32)
    O, D = _arrays(L, *o.unbind(1)), _arrays(L, *d.unbind(1))
    a, b = _arrays(L, lo, hi)
    eps = dr.opaque(L.Float64, epsilon)

    def todo(a, b):
        mid = 0.5 * (a + b)
        return ((b - a) > eps * dr.maximum(dr.abs(a), 1.0)) & (mid > a) & (mid < b)

    def body(a, b, n, k):
        go = todo(a, b)
        mid = 0.5 * (a + b)
        same = (_point(surface, O, D, mid) >= 0) == lo_nonneg
        a, b = dr.select(go & same, mid, a), dr.select(go & ~same, mid, b)
        return a, b, dr.select(go, n + 1, n), k + 1

    a, b, n, _ = dr.while_loop((a, b, dr.zeros(L.Int32, dr.width(a)), dr.zeros(L.Int32, dr.width(a))),
                               lambda a, b, n, k: todo(a, b) & (k < 200), body)
    t = 0.5 * (a + b)
    dr.eval(t, n)
    return torch.from_numpy(t.numpy().copy()), torch.from_numpy(n.numpy().copy())
