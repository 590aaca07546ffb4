r"""Scoring implicit-surface ray casters against the certified reference (progressive-tracing article: punch-through, false hits).

:func:`classify` gives every pixel one label by comparing a method's
:class:`~ssbench.passes.implicit.common.ImplicitResult` (``t``, ``hit``) with the reference
:class:`~ssbench.reference.implicit.ImplicitReference` (``t``, ``hit``, ``unfinished``). With
``tol = atol + rtol·t_ref``:

=====================  ====  ==========================================================================
class                  code  definition
=====================  ====  ==========================================================================
:data:`TRUE_MISS`      0     truth misses, the method misses.
:data:`CORRECT`        1     truth hits, the method hits with ``|t − t_ref| ≤ tol``.
:data:`PUNCH_THROUGH`  2     truth hits, the method misses *or* hits a farther root (``t > t_ref + tol``):
                             the ray went through the surface — the article's see-through (右側の画像).
:data:`EARLY_HIT`      3     truth hits, the method hits in front of it (``t < t_ref − tol``): a wrong λ,
                             a tangency/double root taken for a hit, an epsilon too large.
:data:`FALSE_HIT`      4     truth misses, the method hits (e.g. sphere tracing stopping on (‖p‖−1)²).
:data:`UNKNOWN`        5     the reference is ``unfinished`` there (iteration cap): not scored.
=====================  ====  ==========================================================================

"Truth hits" means a sign-changing root ``f ≥ 0 → f < 0`` (the reference's definition); a root with no sign
change is a miss for the truth, seen only as ``truth.ambiguous_t`` (:func:`summary` reports how many false
hits sit on one). Also: :func:`summary` (rates, depth error, evaluations per pixel),
:func:`lipschitz_check` (declared λ vs observed max |∇f|, POV-Ray's "max_gradient found"), and the h/w
prediction of the progressive method (:func:`detection_prediction`, :func:`predicted_punch_through`).
Truth and result are used duck-typed (tests use stubs); bad input raises naming the argument.
"""
from __future__ import annotations

import math
from typing import Any, Optional

import torch

from .. import checks
from .implicit_prediction import detection_prediction, predicted_punch_through, survivor_punch_through

__all__ = ["classify", "class_counts", "summary", "chord", "lipschitz_check", "detection_prediction",
           "predicted_punch_through", "survivor_punch_through", "TRUE_MISS", "CORRECT", "PUNCH_THROUGH",
           "EARLY_HIT", "FALSE_HIT", "UNKNOWN", "CLASS_NAMES", "CLASS_DESCRIPTIONS", "CLASS_COLORS"]

TRUE_MISS, CORRECT, PUNCH_THROUGH, EARLY_HIT, FALSE_HIT, UNKNOWN = 0, 1, 2, 3, 4, 5
#: code → short key
CLASS_NAMES: dict[int, str] = {TRUE_MISS: "true_miss", CORRECT: "correct", PUNCH_THROUGH: "punch_through",
                               EARLY_HIT: "early_hit", FALSE_HIT: "false_hit", UNKNOWN: "unknown"}
#: code → one-line definition (legends, report)
CLASS_DESCRIPTIONS: dict[int, str] = {
    TRUE_MISS: "truth and method both miss", CORRECT: "hit within tol of the first root",
    PUNCH_THROUGH: "truth hits; the method missed it or hit a farther root (see-through)",
    EARLY_HIT: "hit in front of the first root (wrong λ, tangency, large epsilon)",
    FALSE_HIT: "hit where the truth has no sign-changing root", UNKNOWN: "reference unfinished (not scored)"}
#: code → display RGB in [0, 1]
CLASS_COLORS: dict[int, tuple[float, float, float]] = {
    TRUE_MISS: (0.5, 0.5, 0.5), CORRECT: (0.16, 0.70, 0.27), PUNCH_THROUGH: (0.92, 0.25, 0.86),
    EARLY_HIT: (0.98, 0.52, 0.05), FALSE_HIT: (0.89, 0.12, 0.12), UNKNOWN: (0.0, 0.0, 0.0)}


def _field(obj: Any, name: str, arg: str, like: Optional[torch.Tensor] = None) -> torch.Tensor:
    t = getattr(obj, name, None)
    if not isinstance(t, torch.Tensor):
        raise TypeError(f"{arg}.{name}: expected a torch.Tensor, got {type(t).__name__}")
    checks.check_shape(t, ["B", "1", "H", "W"], f"{arg}.{name}")
    if like is not None and t.shape != like.shape:
        raise ValueError(f"{arg}.{name}: shape {tuple(t.shape)} must match result.t {tuple(like.shape)}")
    return t


def _tol(rtol: float, atol: float) -> tuple[float, float]:
    for n, v in (("rtol", rtol), ("atol", atol)):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{n}: must be a finite number >= 0, got {v!r}")
    return float(rtol), float(atol)


def classify(result: Any, truth: Any, *, rtol: float = 1e-3, atol: float = 1e-6
             ) -> tuple[torch.Tensor, dict[int, str]]:
    r"""Label every pixel (see the module table); ``tol = atol + rtol·|t_ref|``.

    Args:
        result: an ``ImplicitResult`` (``t``, ``hit`` :math:`(B, 1, H, W)`).
        truth: an ``ImplicitReference`` (``t``, ``hit``, ``unfinished``) of the same shape.
        rtol, atol: relative and absolute depth tolerance.

    Returns:
        ``(classes, CLASS_NAMES)``: :math:`(B, 1, H, W)` int8 codes.

    Example:
        >>> from types import SimpleNamespace as NS
        >>> v = lambda *x: torch.tensor(x).view(1, 1, 1, -1)
        >>> truth = NS(t=v(2.0, 2.0, 2.0, 2.0, 9.0, 9.0, 2.0), hit=v(1, 1, 1, 1, 0, 0, 1).bool(),
        ...            unfinished=v(0, 0, 0, 0, 0, 0, 1).bool())
        >>> res = NS(t=v(2.0, 9.0, 3.0, 1.0, 9.0, 5.0, 2.0), hit=v(1, 0, 1, 1, 0, 1, 1).bool())
        >>> [CLASS_NAMES[int(c)] for c in classify(res, truth)[0].flatten()]
        ['correct', 'punch_through', 'punch_through', 'early_hit', 'true_miss', 'false_hit', 'unknown']
    """
    rtol, atol = _tol(rtol, atol)
    t = _field(result, "t", "result")
    mh = _field(result, "hit", "result", t).bool()
    tr = _field(truth, "t", "truth", t).double()
    th = _field(truth, "hit", "truth", t).bool()
    unf = _field(truth, "unfinished", "truth", t).bool()
    tol = atol + rtol * tr.abs()
    dt = torch.nan_to_num(t.double() - tr, nan=math.inf)                  # a NaN depth is never close
    c = torch.full_like(th, TRUE_MISS, dtype=torch.int8)
    for code, m in ((FALSE_HIT, ~th & mh), (PUNCH_THROUGH, th & (~mh | (dt > tol))), (EARLY_HIT, th & mh & (dt < -tol)),
                    (CORRECT, th & mh & (dt.abs() <= tol)), (UNKNOWN, unf)):
        c[m] = code
    return c, CLASS_NAMES


def class_counts(classes: torch.Tensor) -> dict[str, int]:
    """Pixel count of every class by key (batch pooled)."""
    checks.check_shape(classes, ["B", "1", "H", "W"], "classes")
    return {k: int((classes == code).sum()) for code, k in CLASS_NAMES.items()}


def _q(x: torch.Tensor, q: float) -> float:
    return float(torch.quantile(x.double(), q)) if x.numel() else math.nan


def summary(result: Any, truth: Any, classes: Optional[torch.Tensor] = None, *, rtol: float = 1e-3,
            atol: float = 1e-6, mask: Optional[torch.Tensor] = None) -> dict[str, float]:
    r"""Rates, depth error and cost of a method on one image (all batch items pooled).

    Keys: ``pixels``, ``truth_hit_pixels``, ``truth_miss_pixels`` (known pixels, counts as floats);
    ``n_<class>``; ``correct_rate``, ``punch_through_rate``, ``early_hit_rate`` (over truth-hit pixels, they sum
    to 1); ``false_hit_rate``, ``true_miss_rate`` (over truth-miss pixels); ``unknown_rate`` (over all);
    ``false_hit_ambiguous`` (share of the false hits where the truth saw an ambiguous root, e.g. a double root);
    ``depth_mae``, ``depth_max``, ``depth_rel_mae``, ``depth_rel_max`` on CORRECT pixels;
    ``evaluations_{mean,p50,p95,max}`` and ``steps_mean`` over all pixels (``mask``: only those). Rates are
    ``nan`` when their denominator is 0.

    Example:
        >>> from types import SimpleNamespace as NS
        >>> v = lambda *x: torch.tensor(x).view(1, 1, 1, -1)
        >>> truth = NS(t=v(2.0, 4.0, 9.0, 9.0), hit=v(1, 1, 0, 0).bool(), unfinished=v(0, 0, 0, 0).bool(),
        ...            ambiguous_t=v(math.inf, math.inf, 3.0, math.inf))
        >>> res = NS(t=v(2.001, 9.0, 3.0, 9.0), hit=v(1, 0, 1, 0).bool(), evaluations=v(10, 20, 30, 40),
        ...          steps=v(1, 2, 3, 4))
        >>> s = summary(res, truth)
        >>> s["punch_through_rate"], s["false_hit_rate"], s["false_hit_ambiguous"], round(s["depth_mae"], 6)
        (0.5, 0.5, 1.0, 0.001)
        >>> s["evaluations_mean"], s["evaluations_p50"], s["evaluations_max"]
        (25.0, 25.0, 40.0)
    """
    if classes is None:
        classes, _ = classify(result, truth, rtol=rtol, atol=atol)
    t = _field(result, "t", "result")
    checks.check_shape(classes, ["B", "1", "H", "W"], "classes")
    m = torch.ones_like(classes, dtype=torch.bool)
    if mask is not None:
        checks.check_shape(mask, ["B", "1", "H", "W"], "mask")
        if mask.shape != t.shape or mask.dtype != torch.bool:
            raise ValueError(f"mask: expected a bool tensor of shape {tuple(t.shape)}, got {mask.dtype} "
                             f"{tuple(mask.shape)}")
        m = mask
    th = _field(truth, "hit", "truth", t).bool() & m
    known = m & (classes != UNKNOWN)
    n_hit, n_miss = int((th & known).sum()), int((~th & known).sum())
    rate = lambda k, n: int(((classes == k) & m).sum()) / n if n else math.nan     # noqa: E731
    out: dict[str, float] = {"pixels": float(m.sum()), "truth_hit_pixels": float(n_hit),
                             "truth_miss_pixels": float(n_miss)}
    for code, key in CLASS_NAMES.items():
        out[f"n_{key}"] = float(((classes == code) & m).sum())
    for code in (CORRECT, PUNCH_THROUGH, EARLY_HIT):
        out[f"{CLASS_NAMES[code]}_rate"] = rate(code, n_hit)
    for code in (FALSE_HIT, TRUE_MISS):
        out[f"{CLASS_NAMES[code]}_rate"] = rate(code, n_miss)
    out["unknown_rate"] = rate(UNKNOWN, int(m.sum()))
    fh = (classes == FALSE_HIT) & m
    amb = getattr(truth, "ambiguous_t", None)
    out["false_hit_ambiguous"] = (int((fh & torch.isfinite(amb)).sum()) / int(fh.sum()) if int(fh.sum()) else
                                  math.nan) if isinstance(amb, torch.Tensor) else math.nan
    ok = (classes == CORRECT) & m
    err = (t.double() - truth.t.double()).abs()[ok]
    rel = err / truth.t.double().abs()[ok].clamp(min=1e-300)
    for key, x in (("depth", err), ("depth_rel", rel)):
        out[f"{key}_mae"] = float(x.mean()) if x.numel() else math.nan
        out[f"{key}_max"] = float(x.max()) if x.numel() else math.nan
    ev = getattr(result, "evaluations", None)
    e = ev[m].double() if isinstance(ev, torch.Tensor) else torch.zeros(0, dtype=torch.float64)
    out.update(evaluations_mean=float(e.mean()) if e.numel() else math.nan, evaluations_p50=_q(e, 0.5),
               evaluations_p95=_q(e, 0.95), evaluations_max=float(e.max()) if e.numel() else math.nan)
    st = getattr(result, "steps", None)
    out["steps_mean"] = float(st[m].double().mean()) if isinstance(st, torch.Tensor) and int(m.sum()) else math.nan
    return out


def chord(truth: Any) -> torch.Tensor:
    r"""Chord ``w = t_exit − t`` :math:`(B, 1, H, W)` of the first slab along each ray (0 where the truth misses).

    Needs a reference computed with ``exits=True``.
    """
    h = _field(truth, "hit", "truth").bool()
    w = (_field(truth, "t_exit", "truth", h).double() - _field(truth, "t", "truth", h).double()).clamp(min=0)
    return torch.where(h, w, torch.zeros_like(w))


def lipschitz_check(surface, samples: int = 100_000, generator: Optional[torch.Generator] = None, *,
                    near_fraction: float = 0.5, newton_steps: int = 6, rtol: float = 1e-6,
                    chunk: int = 65_536) -> dict[str, Any]:
    r"""Compare the declared Lipschitz bound with the largest autograd ``|∇f|`` seen (POV-Ray's diagnostic).

    ``samples`` points: a share ``1 − near_fraction`` uniform in ``surface.bounds``, the rest uniform points
    pulled toward ``f = 0`` by ``newton_steps`` Newton steps ``p ← p − f ∇f/|∇f|²`` (kept if still inside the
    bounds), since holes open where the surface is. ``overshoot`` is ``observed > declared·(1 + rtol)``.

    Returns:
        dict with ``declared`` (float or None), ``observed_max_grad``, ``overshoot`` (bool; False when nothing
        is declared), ``ratio`` (observed/declared or nan), ``argmax`` (the point, a tuple), ``samples``,
        ``near_samples`` and ``nonfinite`` (points whose gradient is not finite, ignored).

    Example:
        >>> from ssbench.passes.implicit.common import FunctionSurface
        >>> wavy = FunctionSurface(lambda p: p.norm(dim=-1) - 1 + 0.1 * torch.sin(30 * p[..., 0]), lipschitz=1.0,
        ...                        bounds=((-1.2,) * 3, (1.2,) * 3))
        >>> r = lipschitz_check(wavy, samples=2000)
        >>> r["overshoot"], r["observed_max_grad"] > 3.5
        (True, True)
    """
    if isinstance(samples, bool) or not isinstance(samples, int) or samples <= 0:
        raise ValueError(f"samples: must be a positive integer, got {samples!r}")
    if not 0.0 <= near_fraction <= 1.0:
        raise ValueError(f"near_fraction: must be in [0, 1], got {near_fraction!r}")
    if not callable(getattr(surface, "f_and_grad", None)):
        raise TypeError(f"surface: needs a callable f_and_grad(p), got {type(surface).__name__}")
    lo, hi = (torch.tensor(b, dtype=torch.float64) for b in surface.bounds)
    if not (torch.isfinite(lo).all() and torch.isfinite(hi).all()):
        raise ValueError(f"surface.bounds: lipschitz_check samples inside the bounds, which must be finite, "
                         f"got {surface.bounds!r}")
    gen = generator if generator is not None else torch.Generator().manual_seed(0)
    n_near = int(round(samples * near_fraction))
    p = lo + (hi - lo) * torch.rand(samples, 3, generator=gen, dtype=torch.float64)
    keep = torch.ones(samples, dtype=torch.bool)
    for _ in range(newton_steps if n_near else 0):
        q = p[:n_near]
        v, g = _value_grad(surface, q, chunk)
        step = (v / (g * g).sum(-1).clamp(min=1e-300))[:, None] * g
        p[:n_near] = torch.where(torch.isfinite(step), q - step, q)
    keep[:n_near] = ((p[:n_near] >= lo) & (p[:n_near] <= hi)).all(-1)
    p = p[keep]
    _, g = _value_grad(surface, p, chunk)
    gn = g.norm(dim=-1)
    fin = torch.isfinite(gn)
    i = int(torch.where(fin, gn, -1.0).argmax()) if int(fin.sum()) else 0
    obs = float(gn[i]) if int(fin.sum()) else math.nan
    lam = getattr(surface, "lipschitz", None)
    return {"declared": lam, "observed_max_grad": obs,
            "overshoot": bool(lam is not None and obs > float(lam) * (1.0 + rtol)),
            "ratio": obs / float(lam) if lam else math.nan, "argmax": tuple(p[i].tolist()) if len(p) else None,
            "samples": int(p.shape[0]), "near_samples": int(keep[:n_near].sum()), "nonfinite": int((~fin).sum())}


def _value_grad(surface, p: torch.Tensor, chunk: int) -> tuple[torch.Tensor, torch.Tensor]:
    vs, gs = [], []
    for k in range(0, max(1, p.shape[0]), chunk):
        v, g = surface.f_and_grad(p[k:k + chunk])
        vs.append(v.detach().double().reshape(-1)), gs.append(g.detach().double().reshape(-1, 3))
    return torch.cat(vs), torch.cat(gs)
