"""Helpers of :mod:`ssbench.implicit.interval`: directed rounding (torch has no rounding modes), NaN masks,
corner enclosures and the sin/cos crest test. Bounds travel here as plain ``(lo, hi)`` tensor pairs.

Every float operation here is done in round-to-nearest (the only mode torch offers); each primitive also says
on which side of the computed float ``r`` the *exact* result lies, so the caller moves a bound one float
outward with :func:`torch.nextafter` only when the exact value may lie outside it:

- :func:`sum_dir`: Knuth's TwoSum. ``s = fl(a + b)`` and ``err = (a + b) − s`` exactly (no FMA needed).
- :func:`prod_dir`, :func:`quot_dir`: the same question for ``a·b`` and ``a/b``. Both operands are split with
  :func:`torch.frexp` into a mantissa in [0.5, 1) and a power of two; Dekker's TwoProduct (Veltkamp split,
  no FMA) on the mantissas gives the exact sign of the rounding error, overflow-free. Scaling by a power of
  two does not change rounding while the result is a normal float, so the sign carries over. Subnormal
  results (|r| < 2⁻¹⁰²¹) are treated as inexact both ways; underflow to 0 and overflow to ±inf from finite
  operands are inexact *toward* the true value (its sign is known: sign(a)·sign(b)).

Each returns ``(r, below, above)``: ``below`` where the exact value may be < r, ``above`` where it may be > r.
Both are False where ``r`` is exact, so exact results (``1 + 2``, ``2·3``, ``1/4``, products with a 0
factor, infinities coming from infinite operands) are never widened.

>>> import torch
>>> a, b = torch.tensor([0.1, 1.0], dtype=torch.float64), torch.tensor([0.2, 2.0], dtype=torch.float64)
>>> s, below, above = sum_dir(a, b)         # 0.1 + 0.2 rounds up (the exact sum lies below); 1 + 2 is exact
>>> below.tolist(), above.tolist()
([True, False], [False, False])
"""
from __future__ import annotations

import math

import torch

INF = float("inf")
EPS = 2.0 ** -52           # ulp(1.0)
_TINY = 2.0 ** -1021       # smallest |r| whose rounding is tracked exactly (a little above the normal range)
_SPLIT = 134217729.0       # 2**27 + 1, Veltkamp's splitter for 53-bit floats
NAN = float("nan")
TRIG_HUGE = 1e15           # beyond this |x| sin/cos return [-1, 1] (one float step exceeds 0.1 rad)


def down(r: torch.Tensor, k: int = 1, exact: torch.Tensor | None = None) -> torch.Tensor:
    """``r`` moved ``k`` floats toward −inf, except where ``exact`` (a bool mask) holds."""
    out = r
    for _ in range(k):
        out = torch.nextafter(out, out.new_tensor(-INF))
    return out if exact is None else torch.where(exact, r, out)


def up(r: torch.Tensor, k: int = 1, exact: torch.Tensor | None = None) -> torch.Tensor:
    """``r`` moved ``k`` floats toward +inf, except where ``exact`` (a bool mask) holds."""
    out = r
    for _ in range(k):
        out = torch.nextafter(out, out.new_tensor(INF))
    return out if exact is None else torch.where(exact, r, out)


def lower(r: torch.Tensor, below: torch.Tensor) -> torch.Tensor:
    """A lower bound of the exact value: ``r`` if it cannot lie below ``r``, else the float before ``r``."""
    return torch.where(below, torch.nextafter(r, r.new_tensor(-INF)), r)


def upper(r: torch.Tensor, above: torch.Tensor) -> torch.Tensor:
    """An upper bound of the exact value: ``r`` if it cannot lie above ``r``, else the float after ``r``."""
    return torch.where(above, torch.nextafter(r, r.new_tensor(INF)), r)


def sum_dir(a: torch.Tensor, b: torch.Tensor):
    """``fl(a + b)`` and where the exact sum lies (TwoSum; overflow to ±inf lies toward 0)."""
    s = a + b
    bb = s - a
    err = (a - (s - bb)) + (b - bb)           # exact a + b − s when everything is finite
    finite = torch.isfinite(a) & torch.isfinite(b)
    overflow = finite & torch.isinf(s)        # err is NaN there: the true sum is finite
    below = finite & ((err < 0) | (overflow & (s > 0)))
    above = finite & ((err > 0) | (overflow & (s < 0)))
    return s, below, above


def _two_prod_err(a: torch.Tensor, b: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """Exact ``a·b − p`` for ``p = fl(a·b)`` (Dekker; |a|, |b| of order 1 so nothing over/underflows)."""
    ca, cb = _SPLIT * a, _SPLIT * b
    ah = ca - (ca - a)
    bh = cb - (cb - b)
    al, bl = a - ah, b - bh
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


def _directions(r, err_sign, zero_exact, inf_exact, true_sign):
    """Turn the mantissa error sign into (below, above) masks, handling 0, subnormal and ±inf results."""
    mag = r.abs()
    normal = torch.isfinite(r) & (mag >= _TINY)
    sub = (mag > 0) & (mag < _TINY)           # subnormal range: direction unknown, widen both ways
    zero = (r == 0) & ~zero_exact             # underflow: the exact value is on the side of its sign
    ovf = torch.isinf(r) & ~inf_exact         # overflow: the exact value is finite, toward 0
    below = (normal & (err_sign < 0)) | sub | (zero & (true_sign < 0)) | (ovf & (r > 0))
    above = (normal & (err_sign > 0)) | sub | (zero & (true_sign > 0)) | (ovf & (r < 0))
    return below, above


def prod_dir(a: torch.Tensor, b: torch.Tensor):
    """``fl(a·b)`` and where the exact product lies. A 0 factor gives an exact 0 (``0·inf`` is NaN)."""
    p = a * b
    ma, _ = torch.frexp(a)
    mb, _ = torch.frexp(b)
    m = ma * mb
    err = torch.where(torch.isfinite(m), _two_prod_err(ma, mb, m), torch.zeros_like(m))
    true_sign = torch.sign(a) * torch.sign(b)
    return (p, *_directions(p, torch.sign(err), (a == 0) | (b == 0),
                            torch.isinf(a) | torch.isinf(b), true_sign))


def quot_dir(a: torch.Tensor, b: torch.Tensor):
    """``fl(a/b)`` and where the exact quotient lies (``b`` must be nonzero; ``a/inf`` is an exact 0)."""
    q = a / b
    ma, _ = torch.frexp(a)
    mb, _ = torch.frexp(b)
    mq = ma / mb                               # in (0.5, 2): fl(a/b) = mq · 2^(ea − eb) while normal
    ok = torch.isfinite(mq) & (mb != 0)
    mq = torch.where(ok, mq, torch.ones_like(mq))
    mbs = torch.where(ok, mb, torch.ones_like(mb))
    P = mq * mbs
    resid = (ma - P) - _two_prod_err(mq, mbs, P)   # ma − P is exact (Sterbenz); sign is exact
    err_sign = torch.where(ok, torch.sign(resid) * torch.sign(mbs), torch.zeros_like(resid))
    true_sign = torch.sign(a) * torch.sign(b)
    return (q, *_directions(q, err_sign, (a == 0) | torch.isinf(b), torch.isinf(a) | (b == 0), true_sign))


def is_exact_root(r: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Where ``r = fl(sqrt(v))`` is exact: ``r·r == v`` with no rounding."""
    p, below, above = prod_dir(r, r)
    return (p == v) & ~below & ~above


def ipow_bound(m: torch.Tensor, n: int, upward: bool) -> torch.Tensor:
    """A bound on ``m**n`` for ``m >= 0`` (inf allowed) and ``n >= 1``: binary exponentiation, each product
    rounded the same way. Multiplication of non-negative numbers is monotone, so rounding every step down
    (up) gives a lower (upper) bound; exact powers (``2**10``) stay exact."""
    def mul(u, v):
        p, below, above = prod_dir(u, v)
        return upper(p, above) if upward else lower(p, below)

    acc, base = None, m
    while n:
        if n & 1:
            acc = base if acc is None else mul(acc, base)
        n >>= 1
        if n:
            base = mul(base, base)
    return acc


def finish(lo: torch.Tensor, hi: torch.Tensor, bad: torch.Tensor):
    """Broadcast, and make both bounds NaN wherever ``bad`` or either bound is NaN."""
    lo, hi, bad = torch.broadcast_tensors(lo, hi, bad)
    bad = bad | lo.isnan() | hi.isnan()
    return lo.masked_fill(bad, NAN), hi.masked_fill(bad, NAN)


def nan_in(*pairs) -> torch.Tensor:
    """True where any of the ``(lo, hi)`` pairs is NaN."""
    out = torch.zeros((), dtype=torch.bool, device=pairs[0][0].device)
    for lo, hi in pairs:
        out = out | lo.isnan() | hi.isnan()
    return out


def has0(x) -> torch.Tensor:
    return (x[0] <= 0) & (x[1] >= 0)


def has_inf(x) -> torch.Tensor:
    return torch.isinf(x[0]) | torch.isinf(x[1])


def _stack(ts) -> torch.Tensor:
    return torch.stack(torch.broadcast_tensors(*ts))


def corners(op, x, y):
    """Rounded-down min and rounded-up max of ``op(u, v) -> (r, below, above)`` over the four corners."""
    lows, highs = [], []
    for u in x:
        for v in y:
            r, below, above = op(u, v)
            lows.append(lower(r, below))
            highs.append(upper(r, above))
    return _stack(lows).amin(0), _stack(highs).amax(0)


def pow_corners(x, y):
    """Min / max of libm ``u**v`` over the corners, widened 2 floats except at exact points, ``>= 0``."""
    lows, highs = [], []
    for u in x:
        for v in y:
            r = torch.pow(u, v)
            exact = (v == 0) | (u == 1) | torch.isinf(u) | torch.isinf(v)
            lows.append(down(r, 2, exact))
            highs.append(up(r, 2, exact))
    return _stack(lows).amin(0).clamp_min(0.0), _stack(highs).amax(0)


def trig_bounds(a: torch.Tensor, b: torch.Tensor, fn, crest: float, trough: float):
    """Bounds of ``fn`` (sin or cos) on ``[a, b]``: the endpoint values widened 2 floats (exact at 0), then
    1 (−1) if some ``crest + 2kπ`` (``trough + 2kπ``) lies in ``[a − m, b + m]``, ``m = 4ε(max|x| + 2π)``."""
    fa, fb = fn(a), fn(b)
    ea, eb = a == 0, b == 0                       # sin 0 = 0, cos 0 = 1 exactly
    lo = torch.minimum(down(fa, 2, ea), down(fb, 2, eb))
    hi = torch.maximum(up(fa, 2, ea), up(fb, 2, eb))
    mag = torch.maximum(a.abs(), b.abs())
    m = 4 * EPS * (mag + 2 * math.pi)             # margin > error of the float crest test below
    two_pi = 2 * math.pi

    def contains(offset):                         # floor difference >= 1 <=> an integer k in between
        return torch.floor((b + m - offset) / two_pi) > torch.floor((a - m - offset) / two_pi)

    huge = mag > TRIG_HUGE
    hi = torch.where(contains(crest) | huge, 1.0, hi).clamp(-1.0, 1.0)
    lo = torch.where(contains(trough) | huge, -1.0, lo).clamp(-1.0, 1.0)
    return lo, hi
