"""The interval march behind :func:`ssbench.reference.implicit.implicit`: outward-rounded segment boxes, the
lock-step march over rays (Mitchell-style root isolation, exits for chords) and the bisection of brackets.
All float64; see the module docstring of :mod:`ssbench.reference.implicit` for the method and its certificate.
"""
from __future__ import annotations

import math

import torch

from ..indices import flat_nonzero

__all__ = ["segment_box"]

_EPS = 2.0 ** -52


def segment_box(o: torch.Tensor, d: torch.Tensor, a: torch.Tensor, b: torch.Tensor
                ) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Outward-rounded AABB :math:`(N, 3)` ``(lo, hi)`` of the segments ``o + t d``, ``t ∈ [a, b]`` (:math:`(N,)`).

    The corners are computed in float64, widened by a bound on the rounding of ``o + t d`` and then moved one
    more ulp outward with ``torch.nextafter``, so the box contains the exact segment.

    Example:
        >>> o, d = torch.zeros(1, 3, dtype=torch.float64), torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64)
        >>> t = lambda v: torch.tensor([v], dtype=torch.float64)
        >>> lo, hi = segment_box(o, d, t(1.0), t(2.0))
        >>> bool(lo[0, 0] < 1.0 < 2.0 < hi[0, 0]), bool(lo[0, 1] < 0 < hi[0, 1])
        (True, True)
    """
    pa, pb = o + a[:, None] * d, o + b[:, None] * d
    slack = 4 * _EPS * (o.abs() + (torch.maximum(a.abs(), b.abs())[:, None] * d).abs()) + 1e-300
    lo = torch.nextafter(torch.minimum(pa, pb) - slack, torch.full_like(pa, -math.inf))
    hi = torch.nextafter(torch.maximum(pa, pb) + slack, torch.full_like(pa, math.inf))
    return lo, hi


def _f(surface, o, d, t):
    with torch.no_grad():
        return surface.f(o + t[:, None] * d).reshape(-1).to(torch.float64)


#: after this many unresolved leaves in a row the run is no longer walked leaf by leaf: the ray's leaf width
#: doubles every iteration until the run ends. Such a ray is not certified anyway (an ambiguous run), and
#: without this a NaN or zero region (f = 0 on a solid, log of a negative) costs ~1 iteration per leaf, i.e.
#: hours; an exact tangency at the default tolerance runs ~tolerance^{-1/2} ≈ 3·10³ leaves.
RUN_LEAVES = 256


def interval_march(surface, o, d, t0, t1, tol_rel, max_iterations, exits, budget=2048, max_lanes=128, run_leaves=RUN_LEAVES):
    """Lock-step interval march over the rays (a loop over iterations, compacted to the active rays).

    One iteration evaluates, per active ray and in one ``surface.interval`` call, ``K`` consecutive segments
    of width ``h`` from ``a`` and a ladder of ``J`` prefixes ``[a, a + h/2^j]`` (``K + J`` lanes, fewer when
    many rays are active, so a call holds about ``budget`` boxes). The segments are then consumed in order
    exactly as the one-segment rule of the module docstring would: excluded → advance; leaf → point signs;
    wide and not excluded → stop and descend (to the widest excluded ladder prefix, or to the leaf level).
    """
    N, dev = o.shape[0], o.device
    a, h = t0.clone(), (t1 - t0).clone()
    active = t1 > t0
    phase = torch.zeros(N, dtype=torch.bool, device=dev)               # False: entry search, True: exit search
    found = torch.zeros_like(phase)
    clean = torch.ones_like(phase)
    inf = torch.full((N,), math.inf, dtype=torch.float64, device=dev)
    br_lo, br_hi, ex_lo, ex_hi, amb = inf.clone(), inf.clone(), inf.clone(), inf.clone(), inf.clone()
    run = inf.clone()                        # start of the open run of unresolved leaves (entry search)
    iso = inf.clone()                        # start of the bracket that isolates the first root
    n_int = torch.zeros(N, dtype=torch.int32, device=dev)
    n_pt = torch.zeros_like(n_int)
    coarse = torch.ones(N, dtype=torch.float64, device=dev)    # leaf-width factor of a ray in a long run
    n_run = torch.zeros_like(n_int)                 # unresolved leaves since the last excluded segment

    def close_runs(g):                       # a run not ended by a sign change was ambiguous
        g = g[torch.isfinite(run[g]) & ~phase[g]]
        amb[g] = torch.minimum(amb[g], run[g])
        clean[g] = False
        run[g] = math.inf

    def leaf(g, s, e, fs, fe):               # one leaf [s, e] on distinct rays g; True where the ray stops
        ph = phase[g]
        enter, leave = (fs >= 0) & (fe < 0), (fs < 0) & (fe >= 0)
        hit, out, pend, back = ~ph & enter, ph & leave, ~ph & ~enter & ~leave, ~ph & leave
        iso[g[hit]] = torch.minimum(run[g[hit]], s[hit])                # the run led into the root
        run[g[hit]] = math.inf
        clean[g[back]], run[g[back]] = False, math.inf                  # an exiting root: ray started inside
        run[g[pend]] = torch.where(torch.isinf(run[g[pend]]), s[pend], run[g[pend]])
        n_run[g[pend | (ph & ~leave)]] += 1                           # unresolved (entry) / no exit yet
        n_run[g[hit | out]] = 0
        br_lo[g[hit]], br_hi[g[hit]], found[g[hit]], phase[g[hit]] = s[hit], e[hit], True, True
        ex_lo[g[out]], ex_hi[g[out]] = s[out], e[out]
        return out | (hit & (not exits))

    def points(g, t):                        # f at (n, m) ray parameters of rays g
        n_pt[g] += t.shape[1]
        p = o[g, None, :] + t[..., None] * d[g, None, :]
        with torch.no_grad():
            return surface.f(p).reshape(t.shape).to(torch.float64)

    it = 0
    while it < max_iterations:
        idx = flat_nonzero(active)
        n = idx.numel()
        if n == 0:
            break
        it += 1
        lanes = max(1, min(max_lanes, budget // n))
        J = min(lanes // 2, 16)
        K = lanes - J
        A, Hh, T1 = a[idx], h[idx], t1[idx]
        grid = torch.minimum(A[:, None] + torch.arange(K + 1, dtype=A.dtype) * Hh[:, None], T1[:, None])
        lad = torch.minimum(A[:, None] + Hh[:, None] * 2.0 ** -torch.arange(1, J + 1, dtype=A.dtype), T1[:, None])
        lo_t = torch.cat([grid[:, :-1], A[:, None].expand(n, J)], 1).reshape(-1)
        hi_t = torch.cat([grid[:, 1:], lad], 1).reshape(-1)
        rep = idx.repeat_interleave(K + J)
        with torch.no_grad():
            flo, fhi = surface.interval(*segment_box(o[rep], d[rep], lo_t, hi_t))
        excl = ((flo.reshape(-1) > 0) | (fhi.reshape(-1) < 0)).reshape(n, K + J)   # NaN: may hold a root
        n_int[idx] += K + J
        tol = tol_rel * coarse[idx, None] * grid.abs().clamp(min=1.0)
        leafmode = Hh <= tol[:, 0]                                      # every segment is a leaf
        # rows not in leaf mode: skip the leading excluded segments, stop at the first other one
        exk = excl[:, :K] & (grid[:, 1:] > grid[:, :-1])
        m = torch.where(exk.all(1), K, (~exk).to(torch.int8).argmax(1)).long()
        mv = ~leafmode & (m > 0)
        close_runs(idx[mv])
        n_run[idx[mv]] = 0
        a[idx[mv]] = grid[mv, m[mv]]
        grow_by = 2.0 ** max(1, J // 2)                                 # after K excluded segments
        grow = ~leafmode & (m == K)
        h[idx[grow]] = grow_by * Hh[grow]
        mm = m.clamp(max=K - 1)[:, None]
        dlo, dhi = grid.gather(1, mm)[:, 0], grid.gather(1, mm + 1)[:, 0]
        st = ~leafmode & (m < K) & (dhi > dlo)
        dfr = st & (dhi - dlo <= tol.gather(1, mm)[:, 0])              # a leaf: deferred, its own points
        ladder = st & ~dfr & (m == 0)                                   # wide at a: descend
        stop = torch.zeros_like(leafmode)
        # leaf-mode rows: consume the segments in order, jumping over excluded runs, leaf by leaf
        go = leafmode.clone()
        if bool(go.any()):
            kp = torch.zeros(n, dtype=torch.long)
            event = ~excl[:, :K] | (grid[:, 1:] <= grid[:, :-1])          # a leaf (or the end of the range)
            ar = torch.arange(K)
            for _ in range(16):                                         # at most 16 leaves a ray per call
                if not bool(go.any()):
                    break
                cand = event & (ar[None, :] >= kp[:, None])
                nk = torch.where(cand.any(1), cand.to(torch.int8).argmax(1).long(), K)
                close_runs(idx[go & (nk > kp)])
                n_run[idx[go & (nk > kp)]] = 0
                kc = nk.clamp(max=K - 1)[:, None]
                s, e = grid.gather(1, kc)[:, 0], grid.gather(1, kc + 1)[:, 0]
                a[idx[go]] = torch.where(nk < K, s, grid[:, K])[go]
                h[idx[go & (nk == K)]] = Hh[go & (nk == K)] * grow_by
                go &= (nk < K) & (e > s)
                lf = go & (e - s <= tol.gather(1, kc)[:, 0])
                ladder |= go & ~lf & (nk == 0)
                r = flat_nonzero(lf)
                if r.numel():
                    fv = points(idx[r], torch.stack([s[r], e[r]], 1))
                    stop[r] = leaf(idx[r], s[r], e[r], fv[:, 0], fv[:, 1])
                    a[idx[r]] = e[r]
                kp = nk + 1
                go = lf & ~stop & (kp < K)
        if J and bool(ladder.any()):                                    # descend: widest excluded prefix
            L = flat_nonzero(ladder)
            width = lad[L] - A[L, None]
            ok = excl[L, K:] & (width > 0)
            jleaf = torch.where((width <= tol[L, :1]).any(1), (width <= tol[L, :1]).to(torch.int8).argmax(1), J)
            ok &= torch.arange(J)[None, :] <= jleaf[:, None]
            jx = torch.where(ok.any(1), ok.to(torch.int8).argmax(1), J)
            adv = jx < J
            gl = idx[L]
            a[gl[adv]], h[gl[adv]] = lad[L[adv], jx[adv]], Hh[L[adv]] * 2.0 ** -(jx[adv] + 1).double()
            n_run[gl[adv]] = 0
            lf = ~adv & (jleaf < J)
            dfr[L[lf]], dlo[L[lf]], dhi[L[lf]] = True, A[L[lf]], lad[L[lf], jleaf[lf]]
            deeper = ~adv & ~lf
            h[gl[deeper]] = Hh[L[deeper]] * 2.0 ** -J
        elif bool(ladder.any()):
            h[idx[ladder]] = 0.5 * Hh[ladder]
        if bool(dfr.any()):                                             # deferred leaves: their own points
            r = flat_nonzero(dfr)
            fv = points(idx[r], torch.stack([dlo[r], dhi[r]], 1))
            stop[r] = leaf(idx[r], dlo[r], dhi[r], fv[:, 0], fv[:, 1])
            a[idx[r]], h[idx[r]] = dhi[r], 2.0 * (dhi[r] - dlo[r])
        active[idx[stop | (a[idx] >= T1)]] = False
        # a long unresolved run (NaN, zero or tangent stretch) is crossed with doubling leaves, not walked
        open_ = n_run[idx] > 0
        long_run = open_ & (n_run[idx] > run_leaves)
        coarse[idx] = torch.where(open_, torch.where(long_run, (2.0 * coarse[idx]).clamp(max=1.0 / tol_rel),
                                                     coarse[idx]), 1.0)
        h[idx] = torch.where(long_run, 2.0 * h[idx], h[idx])
    close_runs(torch.arange(N, device=dev))
    unfinished = active & ~found                                        # undecided first hit
    no_exit = found & torch.isinf(ex_lo)                                # chord cut by the range (or the cap)
    ex_lo, ex_hi = torch.where(no_exit, a, ex_lo), torch.where(no_exit, a, ex_hi)
    return dict(found=found, iso=iso, br_lo=br_lo, br_hi=br_hi, ex_lo=ex_lo, ex_hi=ex_hi, no_exit=no_exit, amb=amb,
                clean=clean, unfinished=unfinished, n_int=n_int, n_pt=n_pt, iterations=it)


def bisect_brackets(surface, o, d, lo, hi, epsilon, n_pt, lo_nonneg):
    """Bisect brackets whose ``lo`` end has class ``(f ≥ 0) == lo_nonneg`` and ``hi`` end the other class."""
    lo, hi = lo.clone(), hi.clone()
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        todo = ((hi - lo) > epsilon * lo.abs().clamp(min=1.0)) & (mid > lo) & (mid < hi)
        if not bool(todo.any()):
            break
        ti = flat_nonzero(todo)
        fm = _f(surface, o[ti], d[ti], mid[ti])
        n_pt[ti] += 1
        same = (fm >= 0) == lo_nonneg
        lo[ti] = torch.where(same, mid[ti], lo[ti])
        hi[ti] = torch.where(same, hi[ti], mid[ti])
    return 0.5 * (lo + hi)
