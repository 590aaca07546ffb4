"""Equal-error cost: how much ground truth a screen-space method's error is worth.

The ground truth is itself an estimator with a cost knob (AO rays per pixel, mirror-radiance samples, march
steps). A :class:`Ladder` measures its error at ``n = n_0, 2 n_0, …`` against the same high-``n`` reference the
sweep rows were scored against, with an **independent seed**; :func:`equal_error_n` then finds the ``n`` of the
same error by piecewise-linear interpolation in log–log (exact for a power law such as Monte Carlo's σ/√n), and
:meth:`Ladder.seconds_at` the ground truth's time there (least-squares ``a + b·n`` over the ladder's times).

* **AO** (:func:`ao_ladder`): ray-traced AO with ``n`` rays vs the ``R``-ray reference (the rows' ``rmse_cos``
  target). With independent seeds ``E[RMSE²(n)] = σ̄²(1/n + 1/R)``, σ̄² the mask mean of the per-pixel
  variance, estimated from the reference's own standard error (``stderr² · R``): the ladder's ``predicted``.
* **SSR** (:func:`ssr_ladder`): the exact mirror trace has zero hit error at one ray per pixel, so its hit cost
  is the ``spp = 1`` time; for colour, the mirror radiance at ``n`` spp vs the ``S``-spp truth (``rmse_faded``).
* **Implicit** (:func:`implicit_ladder`): fixed-step marching without jitter at ``N`` steps (a dense march)
  scored by punch-through against the certified reference, whose own time is ``reference_seconds``.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Iterable, Mapping, Optional, Sequence

import numpy as np

from .pareto import row_time_ms, row_value, usable

__all__ = ["EqualError", "Ladder", "equal_error_n", "ao_ladder", "ssr_ladder", "implicit_ladder", "best_rows",
           "equal_error_table", "LADDER_SEED_OFFSET"]

#: the ladder's seed is the reference's plus this (PCG32 streams of different seeds are independent)
LADDER_SEED_OFFSET = 7919


@dataclasses.dataclass(frozen=True)
class EqualError:
    """The ``n`` at which the ground truth's error equals a target.

    ``status``: ``"interpolated"`` (between two ladder points), ``"at_most"`` (the ladder point ``n`` already
    reaches it: ≤ n), ``"extrapolated"`` (below the ladder's last error; last log–log segment continued) or
    ``"unreachable"`` (> the last n; no decreasing trend to continue).
    """

    n: float
    status: str

    @property
    def text(self) -> str:
        """``"≈ 37"``, ``"≤ 2"``, ``"≈ 900 (extrapolated)"`` or ``"> 1024"``."""
        v = f"{self.n:.3g}" if self.n < 1000 else f"{self.n:.0f}"
        return {"interpolated": f"≈ {v}", "at_most": f"≤ {v}", "extrapolated": f"≈ {v} (extrapolated)",
                "unreachable": f"> {v}"}[self.status]


def equal_error_n(ns: Sequence[float], errors: Sequence[float], target: float) -> EqualError:
    """``n`` where ``errors(n)`` first falls to ``target`` (log–log interpolation between ladder points).

    Args:
        ns: :math:`(k,)` increasing positive costs; errors: :math:`(k,)` errors at them (NaN points dropped).
        target: the error to match (≥ 0).

    Example:
        >>> ns = [2, 4, 8, 16]; errs = [0.1 / math.sqrt(n) for n in ns]          # σ/√n with σ = 0.1
        >>> round(equal_error_n(ns, errs, 0.1 / math.sqrt(10)).n, 9)
        10.0
        >>> equal_error_n(ns, errs, 1.0).text, equal_error_n(ns, errs, 0.1 / 8).text
        ('≤ 2', '≈ 64 (extrapolated)')
    """
    n = np.asarray(ns, dtype=float)
    e = np.asarray(errors, dtype=float)
    if n.shape != e.shape or n.ndim != 1:
        raise ValueError(f"ns, errors: expected two 1-d sequences of one length, got {n.shape} and {e.shape}")
    if not (isinstance(target, (int, float)) and not isinstance(target, bool) and target >= 0):
        raise ValueError(f"target: must be a number >= 0, got {target!r}")
    ok = np.isfinite(n) & np.isfinite(e)
    n, e = n[ok], e[ok]
    if n.size == 0:
        raise ValueError("errors: no finite ladder point")
    if np.any(n <= 0) or np.any(np.diff(n) <= 0):
        raise ValueError(f"ns: must be positive and increasing, got {n.tolist()}")
    hit = np.flatnonzero(e <= target)
    if hit.size:
        i = int(hit[0])
        if i == 0 or e[i] <= 0 or target <= 0:
            return EqualError(float(n[i]), "at_most")
        x0, x1, y0, y1 = np.log(n[i - 1]), np.log(n[i]), np.log(e[i - 1]), np.log(e[i])
        frac = (np.log(target) - y0) / (y1 - y0) if y1 != y0 else 1.0
        return EqualError(float(np.exp(x0 + frac * (x1 - x0))), "interpolated")
    pos = np.flatnonzero(e > 0)
    if target > 0 and pos.size >= 2:
        a, b = pos[-2], pos[-1]
        slope = (np.log(e[b]) - np.log(e[a])) / (np.log(n[b]) - np.log(n[a]))
        if slope < 0:
            return EqualError(float(n[b] * np.exp((np.log(target) - np.log(e[b])) / slope)), "extrapolated")
    return EqualError(float(n[-1]), "unreachable")


@dataclasses.dataclass(frozen=True)
class Ladder:
    """A ground truth's error and time at increasing cost ``ns`` (``kind``: ``"rays"``, ``"spp"``, ``"steps"``).

    Attributes:
        errors: error at each n against the reference (``reference_n`` rays/spp, or the certified truth).
        seconds: wall time of the ground truth at each n, measured afresh after a warm-up call (never read
            from the disk cache, whose times may include kernel compilation).
        predicted: the σ/√n model's error at each n (AO), else ``None``.
        reference_seconds: time of the reference itself (e.g. the certified implicit trace).
    """

    kind: str
    ns: tuple
    errors: tuple
    seconds: tuple
    reference_n: Optional[int] = None
    reference_seconds: float = math.nan
    predicted: Optional[tuple] = None
    label: str = ""

    def n_for(self, target: float) -> EqualError:
        """The equal-error ``n`` of ``target`` (:func:`equal_error_n`)."""
        return equal_error_n(self.ns, self.errors, target)

    def seconds_at(self, n: float) -> float:
        """Ground-truth seconds at ``n``: least-squares ``a + b·n`` (``a, b ≥ 0``) over the ladder's times."""
        x, y = np.asarray(self.ns, float), np.asarray(self.seconds, float)
        ok = np.isfinite(y)
        x, y = x[ok], y[ok]
        if x.size == 0:
            return math.nan
        if x.size == 1 or np.ptp(x) == 0:
            return float(y.mean() * n / x.mean())
        b, a = np.polyfit(x, y, 1)
        if a < 0:
            a, b = 0.0, float((x * y).sum() / (x * x).sum())
        elif b < 0:
            a, b = float(y.mean()), 0.0
        return float(a + b * n)


def _ladder_ns(ns: Optional[Iterable[int]], lo: int, hi: int) -> list[int]:
    """``ns`` sorted and checked (positive integers, at least one), or ``lo, 2 lo, …`` up to ``hi``."""
    if ns is None:
        return _doubling(lo, max(lo, hi))
    out = sorted(set(ns))
    if not out or any(isinstance(n, bool) or not isinstance(n, int) or n < lo for n in out):
        raise ValueError(f"ns: expected integers >= {lo}, at least one; got {out}")
    return out


def _doubling(lo: int, hi: int) -> list[int]:
    out, n = [], lo
    while n <= hi:
        out.append(n)
        n *= 2
    return out


def ao_ladder(scene, width: int, height: int, radius: float, rays: int, seed: int = 0, *,
              weighting: str = "cosine", ns: Optional[Iterable[int]] = None, use_cache: bool = True) -> Ladder:
    """RMSE of ``n``-ray AO (seed ``seed + LADDER_SEED_OFFSET``) vs the ``rays``-ray reference of ``seed``.

    ``ns`` defaults to ``2, 4, …`` below ``rays``. ``predicted`` is ``sqrt(σ̄² (1/n + 1/rays))`` with σ̄² the mask
    mean of ``stderr² · rays`` of the reference (:mod:`ssbench.reference.ao`).
    """
    from .. import metrics
    from ..evaluate import GT_CHANNELS
    from ..reference.ao import ambient_occlusion
    from ..reference.gbuffer import gbuffer
    g = gbuffer(scene, width, height, channels=GT_CHANNELS, use_cache=use_cache)
    ref = ambient_occlusion(scene, g, radius, rays, weighting, seed, use_cache=use_cache)
    mask = g.mask.cpu()
    ns = _ladder_ns(ns, 2, rays // 2)
    var = float(metrics.masked_mean(ref.stderr.double() ** 2 * rays, mask))
    errs, secs = [], []

    def trace(n: int):
        return ambient_occlusion(scene, g, radius, int(n), weighting, seed + LADDER_SEED_OFFSET, use_cache=False)
    trace(ns[0])                                   # warm-up: compiled kernels, so the times are warm ones
    for n in ns:
        est = trace(n)
        errs.append(float(metrics.rmse(est.ao.float(), ref.ao.float(), mask)))
        secs.append(float(est.seconds))
    pred = tuple(math.sqrt(var * (1.0 / n + 1.0 / rays)) for n in ns)
    return Ladder("rays", tuple(ns), tuple(errs), tuple(secs), rays, float(ref.seconds), pred,
                  f"ray-traced {weighting} AO")


def ssr_ladder(scene, width: int, height: int, spp: int, seed: int = 0, *, ns: Optional[Iterable[int]] = None,
               use_cache: bool = True) -> Ladder:
    """Colour RMSE of the mirror radiance at ``n`` spp (seed ``seed + LADDER_SEED_OFFSET``) vs the ``spp`` truth
    on the reflective pixels (G-buffer hits, as ``rmse_faded`` with ``reflective: null``). The ``n = 1``
    time is the exact mirror trace's (one ray per pixel, zero hit error; its 1-spp radiance included)."""
    import types

    from ..metrics import ssr as M
    from ..reference.gbuffer import gbuffer
    from ..reference.reflections import reflections
    g = gbuffer(scene, width, height, channels=("mask",), use_cache=use_cache)
    truth = reflections(scene, g, spp=spp, seed=seed, use_cache=use_cache)
    ns = _ladder_ns(ns, 1, spp // 2)
    errs, secs = [], []
    valid = truth.valid.bool() & g.mask.bool().cpu()           # the rows' mask with ``reflective: null``

    def trace(n: int):
        return reflections(scene, g, spp=int(n), seed=seed + LADDER_SEED_OFFSET, use_cache=False)
    trace(ns[0])                                   # warm-up: compiled kernels, so the times are warm ones
    for n in ns:
        est = trace(n)
        fake = types.SimpleNamespace(color=est.radiance, raw_color=est.radiance)
        errs.append(M.color_error(fake, truth, valid, flip=False)["rmse_faded"])
        secs.append(float(est.seconds))
    return Ladder("spp", tuple(ns), tuple(errs), tuple(secs), spp, float(truth.seconds), None,
                  "mirror trace + path-traced radiance")


def implicit_ladder(scene, width: int, height: int, seed: int = 0, *, ns: Optional[Iterable[int]] = None,
                    stop_at: float = 0.0, truth_cache: Optional[dict] = None, use_cache: bool = True) -> Ladder:
    """Punch-through rate of fixed-step marching (no jitter) at ``N`` steps, ``16, 32, …, 1024`` by default,
    stopping after the first ``N`` whose rate is ``≤ stop_at`` (the smallest error to match); ``seconds`` per
    frame; ``reference_seconds`` the certified reference's trace time."""
    from ..evaluate import run_implicit
    cache = truth_cache if truth_cache is not None else {}
    ns = _ladder_ns(ns, 1, 1024) if ns is not None else _doubling(16, 1024)
    errs, secs, ref_s, used = [], [], math.nan, []
    for n in ns:
        ev = run_implicit(scene, "fixed", {"steps": int(n), "jitter": False}, width=width, height=height,
                          seed=seed, lipschitz_samples=0, truth_cache=cache, use_cache=use_cache)
        errs.append(float(ev.row["punch_through_rate"]))
        secs.append(float(ev.row["seconds_per_frame"]))
        ref_s = float(getattr(ev.truth, "seconds", math.nan))
        used.append(int(n))
        if errs[-1] <= stop_at:
            break
    return Ladder("steps", tuple(used), tuple(errs), tuple(secs), None, ref_s, None, "fixed-step march")


def best_rows(rows: Iterable[Mapping], error: str) -> dict:
    """``{(scene, method): row}`` of each method's best configuration per scene: least ``error``, then least
    time (:func:`~ssbench.analysis.pareto.row_time_ms`); rows with an error or a NaN ``error`` are skipped."""
    best: dict = {}
    for r in rows:
        e, t = row_value(r, error), row_time_ms(r)
        if not usable(r) or not math.isfinite(e):
            continue
        key = (r.get("scene"), r.get("method"))
        t = t if math.isfinite(t) else math.inf
        if key not in best or (e, t) < best[key][0]:
            best[key] = ((e, t), r)
    return {k: v[1] for k, v in best.items()}


def equal_error_table(rows: Iterable[Mapping], ladders: Mapping, error: str) -> list[dict]:
    """One entry per (scene, method) best configuration: its error and time, the ground truth's equal-error
    ``n`` on the scene's ladder (``ladders[scene]``) and that ground truth's time, and their ratio."""
    out = []
    for (scene, method), r in best_rows(rows, error).items():
        lad = ladders.get(scene)
        if lad is None:
            continue
        e, t = row_value(r, error), row_time_ms(r)
        eq = lad.n_for(e)
        gt_ms = 1e3 * lad.seconds_at(eq.n)
        out.append({"scene": scene, "method": method, "config_id": r.get("config_id"),
                    "params": dict((r.get("config") or {}).get("params", {})), "error": e, "time_ms": t,
                    "kind": lad.kind, "n": eq.n, "status": eq.status, "n_text": eq.text, "gt_ms": gt_ms,
                    "ratio": gt_ms / t if t and math.isfinite(t) and t > 0 else math.nan})
    return out
