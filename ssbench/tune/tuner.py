"""``tune``: grid narrowing, then gradient steps, on training scenes; default vs tuned on held-out scenes.

1. The baseline (:func:`ssbench.tune.space.baseline`) is scored on the training scenes.
2. :func:`ssbench.tune.grid.grid_narrow` searches the continuous parameters' box.
3. At the grid's best point :func:`ssbench.tune.gradient.probe` measures which parameters the pass is
   differentiable in; :func:`ssbench.tune.gradient.refine` takes ``steps`` Adam steps on those.
4. The tuned point is the lowest training error among baseline, grid and gradient results that meets the
   budget, so the tuned training error is never above the default's (when the default meets the budget).
5. Default and tuned are scored on the held-out scenes and timed (same timer, first training scene).

With ``blur`` the objective scores (and times) the blurred AO, as ``ssbench ao --blur`` does, and the blur's
continuous parameters (``blur_*``, :data:`~ssbench.tune.space.BLUR_SPACES`) are tuned with the pass's: the same
grid, and Adam on those the probe finds differentiable. The default is the blur's defaults.
"""
from __future__ import annotations

import dataclasses
import math
import statistics
import time
from typing import Any, Callable, Mapping, Optional, Sequence

import torch

from ..reference.ao import WEIGHTINGS as AO_WEIGHTINGS
from .core import Objective, Timer, prepare_cases
from .gradient import probe, refine
from .grid import grid_narrow
from .space import baseline, blur_defaults, check_blur, coerce_fixed, method_parts, resolve_space

__all__ = ["TuneResult", "tune", "WEIGHTINGS"]

#: ``weighting`` choices: a ground-truth flavour, or ``"flavour"`` for the one the pass approximates
WEIGHTINGS = AO_WEIGHTINGS + ("flavour",)


@dataclasses.dataclass(frozen=True)
class TuneResult:
    """Everything :func:`tune` found; :meth:`as_dict` is the JSON of ``tune.json``.

    ``rows`` holds one dict per scene: ``scene, split ("train"/"held_out"), default, tuned`` (RMSE).
    ``params`` one per tuned parameter: ``name, default, tuned, lo, hi, at_bound ("lo", "hi" or "": a tuned
    value on the edge of its range, so a wider range might do better), differentiable, grad, why``.
    """

    method: str
    settings: dict
    params: list
    rows: list
    summary: dict
    search: dict

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def _mean(xs) -> float:
    xs = [x for x in xs if math.isfinite(x)]
    return statistics.fmean(xs) if xs else math.nan


def tune(method: str, train: Sequence, held_out: Sequence = (), *, width: int = 160, height: int = 120,
         gt_radius: float = 0.5, rays: int = 256, weighting: str = "cosine", seed: int = 0,
         fixed: Optional[Mapping[str, Any]] = None, names: Optional[Sequence[str]] = None,
         bounds: Optional[Mapping[str, tuple]] = None, points: int = 5, rounds: int = 3, shrink: float = 0.5,
         steps: int = 10, lr: float = 0.05, budget_ms: Optional[float] = None, timer: Optional[Timer] = None,
         use_cache: bool = True, cases: Optional[tuple] = None, blur: Optional[str] = None,
         progress: Optional[Callable[[str], None]] = None) -> TuneResult:
    """Tune ``method``'s continuous parameters against a fixed ray-traced AO on ``train``; report ``held_out``.

    Args:
        method: an AO method (``ssbench.passes.AO_METHODS``).
        train, held_out: scenes (catalog names or files); ``held_out`` may be empty.
        width, height: image size of tuning and scoring.
        gt_radius: ground-truth occlusion radius (fixed; the baseline's pass radius is set to it).
        rays, seed: ground-truth rays per pixel and seed (the seed also seeds the pass's noise).
        weighting: ground-truth flavour (:data:`WEIGHTINGS`; ``"flavour"``: the pass's own).
        fixed: parameter overrides held fixed (discrete ones: sample counts, quality, ...).
        names, bounds: parameters to tune (default: all of ``SPACES[method]`` not in ``fixed``) and range
            overrides ``{name: (lo, hi)}``.
        points, rounds, shrink: grid narrowing (:func:`~ssbench.tune.grid.grid_narrow`).
        steps, lr: Adam steps on the differentiable parameters (0: none) and learning rate (fraction of range).
        budget_ms: reject configurations slower than this per frame (timed at ``width × height``).
        timer: replaces :func:`~ssbench.tune.core.median_timer` (tests inject a fake one).
        use_cache: let the reference read/write its disk cache.
        cases: ``(train_cases, held_out_cases)`` already prepared (:func:`~ssbench.tune.core.prepare_cases`
            with the same settings) to reuse between methods.
        blur: score ``blur(pass output)`` (``"box"``, ``"cross_bilateral"``, ``"joint_bilateral"``; ``None``: no
            blur) and tune the blur's ``blur_*`` parameters too (``names``/``bounds`` may name them).
        progress: called with a short status line per stage.
    """
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    fn, _, _, module = method_parts(method)
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting: expected one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    flav = getattr(module, "FLAVOUR", "cosine") if weighting == "flavour" else weighting
    train, held_out = list(train), list(held_out)
    if not train:
        raise ValueError("train: need at least one training scene")
    overlap = [s for s in held_out if s in train]
    if overlap:
        raise ValueError(f"held_out: {', '.join(map(str, overlap))} also in train; held-out scenes must differ")
    check_blur(blur)
    fixed = coerce_fixed(method, fixed)
    base = baseline(method, gt_radius, fixed)
    space = resolve_space(method, gt_radius, names, bounds, fixed, blur=blur)
    if cases is None:
        say(f"{method}: ground truth for {len(train) + len(held_out)} scenes")
        kw = dict(width=width, height=height, gt_radius=gt_radius, rays=rays, weighting=flav, seed=seed,
                  use_cache=use_cache)
        cases = (prepare_cases(train, **kw), prepare_cases(held_out, **kw) if held_out else [])
    train_cases, held_cases = cases
    obj = Objective(method, base, train_cases, seed=seed, budget_ms=budget_ms, timer=timer, blur=blur)
    bdef = blur_defaults(blur)
    default_values = {n: float(bdef[n]) if n in bdef else float(getattr(base, n)) for n in space}
    default = obj.evaluate(default_values)

    say(f"{method}: grid {points}^{len(space)} x {rounds} rounds")
    grid = grid_narrow(obj, space, points=points, rounds=rounds, shrink=shrink)
    start = {**default_values, **grid.best} if math.isfinite(grid.value) else default_values
    diff = probe(lambda t: obj.loss(start, t), start, list(space))
    dnames = [n for n in space if diff[n]["differentiable"]]
    grad_res = None
    if dnames and steps > 0 and math.isfinite(grid.value):             # not when the budget rejected all
        say(f"{method}: {steps} Adam steps on {', '.join(dnames)}")
        grad_res = refine(lambda t: obj.loss(start, t), start, dnames, space, steps=steps, lr=lr)
        obj.evaluate(grad_res.best)
    candidates = [("default", default_values), ("grid", start)] + ([("gradient", grad_res.best)] if grad_res else [])
    scored = [(obj.evaluate(v)["error"], i, src, v) for i, (src, v) in enumerate(candidates)]
    _, _, source, tuned_values = min(scored, key=lambda t: (t[0], t[1]))
    tuned_params, tuned_blur = obj.config(tuned_values)

    say(f"{method}: held-out scoring and timing")
    held_default = obj.errors(base, held_cases) if held_cases else []
    held_tuned = obj.errors(tuned_params, held_cases, tuned_blur) if held_cases else []
    t_default = obj.evaluate(default_values, time_it=True)["time_ms"]
    t_tuned = obj.evaluate(tuned_values, time_it=True)["time_ms"]
    met = obj.evaluate(tuned_values)["status"] == "ok"                # False: nothing met the budget
    train_default = default["errors"] or obj.errors(base)               # scored even when over budget
    train_tuned = obj.evaluate(tuned_values)["errors"] or obj.errors(tuned_params, None, tuned_blur)
    rows = [{"scene": c.scene, "split": "train", "default": d, "tuned": t}
            for c, d, t in zip(train_cases, train_default, train_tuned)]
    rows += [{"scene": c.scene, "split": "held_out", "default": d, "tuned": t}
             for c, d, t in zip(held_cases, held_default, held_tuned)]
    for r in rows:
        r["change"] = (r["tuned"] - r["default"]) / r["default"] if r["default"] > 0 else math.nan
    edge = lambda n, v: ("lo" if math.isclose(v, space[n][0], abs_tol=1e-9)        # noqa: E731
                         else "hi" if math.isclose(v, space[n][1], abs_tol=1e-9) else "")
    params = [{"name": n, "default": default_values[n], "tuned": float(tuned_values[n]), "lo": space[n][0],
               "hi": space[n][1], "at_bound": edge(n, float(tuned_values[n])) if source != "default" else "",
               **diff[n]} for n in space]
    hd, ht = _mean(held_default), _mean(held_tuned)
    statuses = [h["status"] for h in obj.history]
    times = [h["time_ms"] for h in obj.history if math.isfinite(h["time_ms"])]
    note = ("" if met else f"no configuration met the budget of {budget_ms:g} ms per frame (fastest measured "
            f"{min(times):.3g} ms): the defaults are kept" if budget_ms is not None and times
            else "no configuration gave a finite error: the defaults are kept")
    summary = {"train_default": _mean(train_default), "train_tuned": _mean(train_tuned), "held_default": hd,
               "held_tuned": ht, "held_improved": bool(held_cases) and ht < hd, "source": source,
               "time_ms_default": t_default, "time_ms_tuned": t_tuned, "default_status": default["status"],
               "within_budget": met, "note": note, "seconds": time.perf_counter() - t0}
    search = {"evaluations": len(obj.history), "grid_evaluations": grid.evaluations, "grid_rounds": grid.rounds,
              "rejected_over_budget": statuses.count("over_budget"), "rejected_invalid": statuses.count("invalid"),
              "gradient": grad_res.history if grad_res else [], "differentiable": dnames}
    settings = {"train": [c.scene for c in train_cases], "held_out": [c.scene for c in held_cases],
                "width": width, "height": height, "gt_radius": float(gt_radius), "rays": rays, "weighting": flav,
                "seed": seed, "blur": blur, "fixed": {k: (list(v) if isinstance(v, tuple) else v) for k, v in fixed.items()},
                "points": points, "rounds": rounds, "shrink": shrink, "steps": steps, "lr": lr,
                "budget_ms": budget_ms, "threads": torch.get_num_threads(), "pass": f"{fn.__module__}.{fn.__name__}"}
    return TuneResult(method, settings, params, rows, summary, search)
