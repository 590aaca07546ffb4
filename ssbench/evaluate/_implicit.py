"""Evaluate one implicit-surface ray caster on one implicit scene over frames: one tidy row per run (progressive-tracing article).

:func:`run_implicit` casts ``frames`` frames with the method (the progressive method carries its
``ProgressiveState`` across frames; fixed-step and sphere tracing run each frame afresh, fixed-step with a new
jitter per frame when its ``jitter`` is on), traces the certified reference (``ssbench.reference.implicit``,
``exits=True``; one trace per distinct pose, so a static scene is traced once) and labels every pixel with
:func:`ssbench.metrics.implicit.classify`. Row keys:

* settings: ``scene, method, params, frames, width, height, seed, dtype, device, threads, static, truth_frames``;
* per frame (lists, one entry per frame; ``None`` where the frame was not scored): ``punch_through_per_frame``,
  ``evaluations_mean_per_frame``, ``hit_share_per_frame``, ``seconds_frames``, ``invalidated_per_frame``
  (progressive only, else ``None``);
* the h/w prediction (static scenes): ``predicted_punch_through`` — progressive (every frame scored): the
  survivor form :func:`ssbench.metrics.implicit.survivor_punch_through`, ``mean [unfound after k−1]·(1 − min(1,
  w/h_k))`` with ``w = t_exit − t`` the truth's chord and ``h_k = t'_k/N`` from the run's state before frame
  ``k`` (only pixels the run has not found yet are at risk; see :func:`_prediction`);
  fixed: the one-frame value with ``h = t_far/N`` held flat (a fixed lattice has no memory); ``prediction_h``,
  ``frames_to_1pct`` / ``predicted_frames_to_1pct`` (first frame, 1-based, under 1%);
* final frame (the last scored one): ``frac_<class>`` for every class of ``CLASS_NAMES`` (share of all pixels,
  they sum to 1), ``correct_rate, punch_through_rate, early_hit_rate`` (over truth hits), ``false_hit_rate,
  true_miss_rate``, ``unknown_rate``, ``false_hit_ambiguous``, ``depth_{mae,max,rel_mae,rel_max}``,
  ``term_<reason>``, ``nonfinite``, ``overshoot_pixels`` / ``fallbacks`` (sphere tracing);
* cost: ``evaluations_{mean,p95,max}`` and ``steps_{mean,max}`` pooled over all pixels of all frames,
  ``seconds_per_frame`` (median), ``seconds_total``;
* ``lambda_{declared,observed,ratio,overshoot}`` from :func:`ssbench.metrics.implicit.lipschitz_check`;
* truth: ``truth_traced`` (new traces this run), ``truth_seconds``, ``truth_engine`` (the reference's march:
  ``drjit`` or ``torch``), ``truth_hit_share``, ``truth_certified`` (share of pixels), ``truth_ambiguous_pixels``,
  ``truth_unfinished_pixels`` (of the last scored frame).
"""
from __future__ import annotations

import dataclasses
import math
import statistics
import time
from typing import Any, Callable, Mapping, Optional

import numpy as np
import torch

from ._common import params_as_dict, sync_device, resolve_params

__all__ = ["implicit", "run_implicit", "ImplicitEvaluation", "steps_param", "lipschitz_diagnostic"]

TRUTH_FRAMES = ("all", "last", "none")
KEEP = ("last", "all")
#: debug entries dropped from kept results (large, or only needed while casting)
_HEAVY = ("rays", "camera", "bracket", "t_prime_before", "R", "t_last")


@dataclasses.dataclass(frozen=True)
class ImplicitEvaluation:
    """Everything :func:`run_implicit` computed (tensors on the CPU), keyed by frame index.

    Attributes:
        row: the flat dict :func:`implicit` returns.
        results: the method's ``ImplicitResult`` of the kept frames (``keep="last"``: the last frame only).
        truths: the ``ImplicitReference`` of every scored frame (one shared object per distinct pose).
        classes: :math:`(1, 1, H, W)` int8 class maps of the kept, scored frames.
        cameras: the camera of every frame.
        scene: the loaded ``ImplicitScene``.
    """

    row: dict
    results: dict
    truths: dict
    classes: dict
    cameras: dict
    scene: Any

    @property
    def last(self) -> int:
        """Index of the last frame."""
        return self.row["frames"] - 1

    @property
    def result(self):
        """The last frame's result."""
        return self.results[self.last]

    @property
    def truth(self):
        """The last frame's reference (None when it was not scored)."""
        return self.truths.get(self.last)


def steps_param(method: str) -> str:
    """The parameter a ``--steps N`` option sets: what the method's module declares as ``STEPS_PARAM``, else
    ``steps`` (e.g. ``max_steps`` for sphere tracing, whose step count is a cap)."""
    from ..passes import declared, implicit_method
    return declared(implicit_method(method)[0], "STEPS_PARAM", "steps")


def lipschitz_diagnostic(surface, samples: int = 20_000, seed: int = 0) -> dict:
    """The row's λ columns: declared bound, observed max ``|∇f|``, their ratio and the overshoot flag."""
    from ..metrics.implicit import lipschitz_check
    if not samples:
        return {"lambda_declared": getattr(surface, "lipschitz", None), "lambda_observed": math.nan,
                "lambda_ratio": math.nan, "lambda_overshoot": None}
    r = lipschitz_check(surface, samples, torch.Generator().manual_seed(seed))
    return {"lambda_declared": r["declared"], "lambda_observed": r["observed_max_grad"], "lambda_ratio": r["ratio"],
            "lambda_overshoot": r["overshoot"]}


def _check_int(v, name: str, lo: int) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{name}: must be an integer >= {lo}, got {v!r}")


def _cpu(result, drop: tuple = ()):
    out = {f.name: getattr(result, f.name).detach().cpu() for f in dataclasses.fields(result)
           if isinstance(getattr(result, f.name), torch.Tensor)}
    dbg = {k: (v.detach().cpu() if isinstance(v, torch.Tensor) else v) for k, v in (result.debug or {}).items()
           if k not in drop}
    return dataclasses.replace(result, **out, debug=dbg, state=None)     # the caller keeps the state


def _first_under(rates, level: float = 0.01) -> Optional[int]:
    return next((k + 1 for k, r in enumerate(rates) if r is not None and r < level), None)


def _prediction(kind: str, truth, h_maps: list, found_maps: list, t_far: torch.Tensor, n: int,
                frames: int) -> Optional[list]:
    """The h/w prediction (module docstring). Progressive: the survivor form, frame ``k`` putting at risk only
    the pixels the run had not found after frame ``k−1``, each with its own ``h_k = t'_k/N``. (The product form
    over all frames kept found pixels at risk and over-predicted late frames ~5x on thin_shell.)"""
    from ..metrics import implicit as M
    mask = truth.hit.bool() & ~truth.unfinished.bool()
    w = M.chord(truth)
    if kind == "survivor" and len(h_maps) == len(found_maps) == frames:
        return M.survivor_punch_through(torch.stack(h_maps), w, torch.stack(found_maps), mask=mask).tolist()
    if kind == "uniform":
        return M.predicted_punch_through(t_far / n, w, frames=1, mask=mask).tolist() * frames
    return None


def run_implicit(scene, method: str, params=None, *, frames: int = 1, width: Optional[int] = None,
                 height: Optional[int] = None, seed: int = 0, truth_frames: str = "all", keep: str = "last",
                 dtype: torch.dtype = torch.float32, device="cpu", use_cache: bool = True,
                 lipschitz_samples: int = 20_000, rtol: float = 1e-3, atol: float = 1e-6,
                 on_frame: Optional[Callable] = None, progress: bool = False,
                 truth_cache: Optional[dict] = None) -> ImplicitEvaluation:
    """:func:`implicit` with its images: returns an :class:`ImplicitEvaluation` (``.row`` is the tidy row).

    Extra keyword arguments:
        truth_frames: ``"all"`` (score every frame), ``"last"`` (only the last) or ``"none"`` (no reference:
            cost and invalidations only; class columns are NaN).
        keep: ``"last"`` or ``"all"`` frames' results (and class maps) kept in the evaluation.
        dtype, device: of the method's rays (the reference is float64 on the CPU).
        use_cache: let the reference read/write its disk cache.
        lipschitz_samples: points of the λ diagnostic (0: skip it).
        rtol, atol: depth tolerance of :func:`~ssbench.metrics.implicit.classify`.
        on_frame: called as ``on_frame(frame, result, camera, classes_or_None)`` after every frame (full
            result, debug included), e.g. to write an animation without keeping every frame.
        progress: a tqdm bar over the frames.
        truth_cache: a dict shared between runs (e.g. several methods on one scene): references are looked
            up and stored in it by ``(surface.cache_key(), camera)``; ``truth_traced`` counts only new traces.
    """
    from ..implicit.scene import load
    from ..metrics import implicit as M
    from ..passes import declared, implicit_method
    from ..passes.implicit.common import TERMINATION_NAMES, camera_rays
    from ..reference.implicit import implicit as trace

    fn, params_cls = implicit_method(method)
    p = resolve_params(params_cls, params, method)
    if "seed" in {f.name for f in dataclasses.fields(p)} and (params is None or (
            isinstance(params, Mapping) and "seed" not in params)):
        p = dataclasses.replace(p, seed=seed)
    _check_int(frames, "frames", 1)
    _check_int(seed, "seed", 0)
    for k, v in (("width", width), ("height", height)):
        if v is not None:
            _check_int(v, k, 1)
    if truth_frames not in TRUTH_FRAMES:
        raise ValueError(f"truth_frames: expected one of {', '.join(TRUTH_FRAMES)}, got {truth_frames!r}")
    if keep not in KEEP:
        raise ValueError(f"keep: expected one of {', '.join(KEEP)}, got {keep!r}")
    sc = load(scene)
    stateful = bool(declared(fn, "STATEFUL", False))
    jittered = not stateful and bool(getattr(p, "jitter", False))
    n_steps = getattr(p, "steps", None)

    results, truths, classes, cameras, traced = {}, {}, {}, {}, {}
    shared = truth_cache if truth_cache is not None else {}
    n_traced = 0
    rates, ev_means, hit_share, secs, inval, evals, steps, keys, h_maps, found = ([] for _ in range(10))
    state, last_scored, truth_s = None, None, 0.0
    from tqdm.auto import tqdm
    for k in tqdm(range(frames), disable=not progress, desc=f"{sc.name} {method}", unit="frame"):
        cam = sc.camera_at(k)
        if width is not None or height is not None:
            cam = cam.with_resolution(width or cam.width, height or cam.height)
        surf = sc.surface(k)
        cameras[k] = cam
        t0 = time.perf_counter()
        gen = torch.Generator().manual_seed(p.seed * 1_000_003 + k) if jittered else None
        res = fn(surf, cam, p, state=state, generator=gen, dtype=dtype, device=device)
        state = res.state
        sync_device(device)
        secs.append(time.perf_counter() - t0)
        res = _cpu(res)
        if stateful and n_steps and isinstance(res.debug.get("t_prime_before"), torch.Tensor):
            h_maps.append(res.debug["t_prime_before"].double() / n_steps)
        keys.append((surf.cache_key(), cam))
        truth = None
        if truth_frames == "all" or (truth_frames == "last" and k == frames - 1):
            if keys[-1] not in shared:
                t0 = time.perf_counter()
                shared[keys[-1]] = trace(surf, cam, exits=True, use_cache=use_cache)
                truth_s, n_traced = truth_s + time.perf_counter() - t0, n_traced + 1
            truth = truths[k] = traced[keys[-1]] = shared[keys[-1]]
        cls = M.classify(res, truth, rtol=rtol, atol=atol)[0] if truth is not None else None
        if truth is not None:
            rates.append(M.summary(res, truth, cls, rtol=rtol, atol=atol)["punch_through_rate"])
            found.append(cls == M.CORRECT)
            last_scored = (k, res, truth, cls)
        else:
            rates.append(None)
        evals.append(res.evaluations.reshape(-1).to(torch.int64))
        steps.append(res.steps.reshape(-1).to(torch.int64))
        ev_means.append(float(evals[-1].double().mean()))
        hit_share.append(float(res.hit.double().mean()))
        inv = res.debug.get("invalidated")
        inval.append(int(inv.sum()) if isinstance(inv, torch.Tensor) else None)
        if on_frame is not None:
            on_frame(k, res, cam, cls)
        if keep == "all" or k == frames - 1:
            results[k] = _cpu(res, _HEAVY)
            if cls is not None:
                classes[k] = cls

    static = len(set(keys)) == 1
    ev, st = torch.cat(evals).double(), torch.cat(steps).double()
    row: dict[str, Any] = {
        "scene": sc.name, "method": method, "params": params_as_dict(p), "frames": frames, "width": cameras[0].width,
        "height": cameras[0].height, "seed": seed, "dtype": str(dtype).replace("torch.", ""),
        "device": str(torch.device(device)), "threads": torch.get_num_threads(), "static": static,
        "truth_frames": truth_frames, "punch_through_per_frame": rates, "evaluations_mean_per_frame": ev_means,
        "hit_share_per_frame": hit_share, "seconds_frames": secs,
        "invalidated_per_frame": inval if stateful else None,
        "evaluations_mean": float(ev.mean()), "evaluations_p95": float(np.percentile(ev.numpy(), 95)),
        "evaluations_max": float(ev.max()), "steps_mean": float(st.mean()),
        "steps_max": float(st.max()), "seconds_per_frame": statistics.median(secs), "seconds_total": sum(secs)}
    keys_nan = [f"frac_{n}" for n in M.CLASS_NAMES.values()] + [
        "correct_rate", "punch_through_rate", "early_hit_rate", "false_hit_rate", "true_miss_rate", "unknown_rate",
        "false_hit_ambiguous", "depth_mae", "depth_max", "depth_rel_mae", "depth_rel_max", "truth_hit_share",
        "truth_certified"]
    row.update({k: math.nan for k in keys_nan})
    row.update(truth_ambiguous_pixels=None, truth_unfinished_pixels=None)
    if last_scored is not None:
        _, res, truth, cls = last_scored
        s = M.summary(res, truth, cls, rtol=rtol, atol=atol)
        n = float(cls.numel())
        row.update({f"frac_{name}": float((cls == code).sum()) / n for code, name in M.CLASS_NAMES.items()})
        row.update({k: s[k] for k in keys_nan if k in s})
        row.update(truth_hit_share=float(truth.hit.double().mean()),
                   truth_certified=float(truth.certified.double().mean()),
                   truth_ambiguous_pixels=int(torch.isfinite(truth.ambiguous_t).sum()),
                   truth_unfinished_pixels=int(truth.unfinished.sum()))
    res = results[frames - 1]
    row.update({f"term_{name.replace(' ', '_')}": float((res.termination == code).double().mean())
                for code, name in TERMINATION_NAMES.items()})
    row["nonfinite"] = int((~torch.isfinite(res.t)).sum() + (~torch.isfinite(res.normal)).sum())
    ov, fb = res.debug.get("overshoot"), res.debug.get("fallbacks")
    row["overshoot_pixels"] = int(ov.sum()) if isinstance(ov, torch.Tensor) else None
    row["fallbacks"] = int(fb.sum()) if isinstance(fb, torch.Tensor) else None
    kind = "survivor" if stateful else ("uniform" if n_steps else None)   # the prediction model (docstring)
    pred = None
    if static and traced and n_steps:
        t_far = camera_rays(cameras[0], dtype=torch.float64).t_far
        pred = _prediction(kind, next(iter(traced.values())), h_maps, found, t_far, n_steps, frames)
    row.update(predicted_punch_through=pred, prediction_h={"survivor": "t'/N", "uniform": "t_far/N"}.get(kind)
               if pred is not None else None, frames_to_1pct=_first_under(rates),
               predicted_frames_to_1pct=_first_under(pred) if pred is not None else None)
    row.update(lipschitz_diagnostic(sc.surface(0), lipschitz_samples, seed))
    engines = sorted({t.engine for t in traced.values()})
    row.update(truth_traced=n_traced, truth_seconds=truth_s, truth_engine=",".join(engines) or None)
    return ImplicitEvaluation(row, results, truths, classes, cameras, sc)


def implicit(scene, method: str, params=None, *, frames: int = 1, width: Optional[int] = None,
             height: Optional[int] = None, seed: int = 0, **kwargs) -> dict:
    """Run implicit ray caster ``method`` on ``scene`` for ``frames`` frames and score it: one tidy row.

    Args:
        scene: an implicit catalog name (``ssbench.implicit.catalog.names()``), a ``.yaml``/``.toml`` file, a
            dict or an ``ImplicitScene``.
        method: a name of :data:`ssbench.passes.IMPLICIT_METHODS` (``"fixed"``, ``"sphere"``, ``"progressive"``).
        params: ``None`` (defaults), the method's params dataclass, or a dict of overrides (unknown names →
            ``ValueError`` naming them). A ``seed`` field not given here is set to ``seed``.
        frames: frames to cast (an animated scene moves; the progressive method carries its state).
        width, height: image size (default: the scene camera's).
        seed: seeds the method's random numbers (``R`` of the progressive method, fixed-step jitter) and the λ
            diagnostic.
        **kwargs: those of :func:`run_implicit` (``truth_frames``, ``keep``, ``dtype``, ``device``,
            ``use_cache``, ``lipschitz_samples``, ``rtol``, ``atol``, ``on_frame``, ``progress``,
            ``truth_cache``).

    Returns:
        A flat dict; keys in the module docstring of :mod:`ssbench.evaluate._implicit`.

    Example:
        >>> row = implicit("sphere", "fixed", {"steps": 16}, width=8, height=6, lipschitz_samples=0)
        >>> row["frames"], round(sum(row[k] for k in row if k.startswith("frac_")), 12)
        (1, 1.0)
    """
    return run_implicit(scene, method, params, frames=frames, width=width, height=height, seed=seed,
                        **kwargs).row
