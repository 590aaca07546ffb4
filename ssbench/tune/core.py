"""The tuning objective: mean RMSE of a pass against a *fixed* ray-traced AO over a set of scenes.

:func:`prepare_cases` renders each scene's reference G-buffer and traces its ground truth once (both through
the reference's disk cache); :class:`Objective` then scores any configuration of the pass on those cases
without touching Mitsuba again. The ground-truth radius, flavour, rays and seed are fixed for the whole run;
only the pass's parameters move. The pass's noise generator is re-seeded with ``seed`` on every call, so the
objective is a deterministic function of the parameters.

With a frame-time budget every configuration is timed (:func:`median_timer`: one warm-up call, then the median
of ``repeats`` calls on the first case) and one slower than the budget is rejected (``+inf``); each evaluation
is recorded in :attr:`Objective.history` with its status (``ok``, ``over_budget``, ``invalid``).

With ``blur`` (a name of :data:`~ssbench.tune.space.BLUR_SPACES`) the pass's AO is blurred before scoring and
timing, as ``ssbench ao --blur`` does (:func:`apply_blur`); the values may then hold ``blur_*`` parameters too,
the others stay at the blur's defaults. The blur reads the case's G-buffer (``view_z``, ``mask``, the camera).
"""
from __future__ import annotations

import dataclasses
import math
import statistics
import time
from typing import Any, Callable, Mapping, Optional, Sequence

import torch

from .. import metrics
from ..gbuffer import GBuffer
from .gradient import inject
from .space import BLUR_DEFAULTS, BLUR_SPACES, blur_defaults, check_blur, method_parts, split_values, with_values

__all__ = ["Case", "prepare_cases", "Objective", "median_timer", "Timer", "PASS_CHANNELS", "apply_blur"]

#: G-buffer channels the cases hold: every AO pass reads a subset of these, the blurs ``view_z`` (the joint
#: bilateral blur its linear depth, from ``view_z`` and the camera) and ``mask``
PASS_CHANNELS = ("view_z", "normal", "mask")
_POSITIVE = ("blur_sigma_color", "blur_sigma_space")       # > 0; every other blur_* parameter >= 0
#: ``timer(call, values) -> (output of call(), milliseconds per call)``
Timer = Callable[[Callable[[], Any], Mapping[str, float]], tuple[Any, float]]


@dataclasses.dataclass(frozen=True)
class Case:
    """One scene ready for tuning: its G-buffer (:data:`PASS_CHANNELS`) and fixed target AO (1, 1, H, W)."""

    scene: str
    gbuffer: GBuffer
    target: torch.Tensor
    gt_stderr: float = math.nan


def _check_blur_values(blur: str, values: Mapping[str, Any]) -> None:
    """``ValueError`` for an unknown ``blur_*`` name or a value out of its domain (checked as floats)."""
    known = [t.name for t in BLUR_SPACES[blur]]
    for k, v in values.items():
        if k not in known:
            raise ValueError(f"{k}: not a parameter of blur {blur}; tunable: {', '.join(known) or 'none'}")
        x = float(v.detach()) if isinstance(v, torch.Tensor) else float(v)
        if not (math.isfinite(x) and (x > 0 if k in _POSITIVE else x >= 0)):
            raise ValueError(f"{k}: must be a finite number {'>' if k in _POSITIVE else '>='} 0, got {x!r}")


def apply_blur(blur: str, ao: torch.Tensor, gbuffer: GBuffer, values: Optional[Mapping[str, Any]] = None):
    """The named blur of ``ssbench ao --blur`` (``ssbench.evaluate.blur_fn``) with ``values`` (``blur_*``: floats
    or 0-d tensors, which stay on the autograd tape) over its defaults; sizes fixed (box 5, cross-bilateral
    radius 15, joint bilateral 5)."""
    from ..passes import blur as B
    v = {**BLUR_DEFAULTS[check_blur(blur)], **(values or {})}
    if blur == "box":
        return B.box_blur(ao, 5)
    if blur == "cross_bilateral":
        return B.cross_bilateral_blur(ao, gbuffer.view_z, 15, v["blur_falloff"], v["blur_threshold"])
    s = v["blur_sigma_space"]
    return B.joint_bilateral_blur(ao, gbuffer.linear_depth, 5, v["blur_sigma_color"],
                                  s if isinstance(s, torch.Tensor) else (float(s), float(s)), mask=gbuffer.mask)


def prepare_cases(scenes: Sequence, *, width: int, height: int, gt_radius: float, rays: int = 256,
                  weighting: str = "cosine", seed: int = 0, use_cache: bool = True) -> list[Case]:
    """A :class:`Case` per scene: the reference G-buffer at ``width × height`` and the ray-traced AO of
    ``weighting`` at ``gt_radius`` with ``rays`` rays (``ssbench.reference.ambient_occlusion``)."""
    from .. import reference
    from ..scenes import load as load_scene
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{name}: must be a positive integer, got {v!r}")
    cases = []
    for s in scenes:
        sc = load_scene(s)
        g = reference.gbuffer(sc, width, height, channels=PASS_CHANNELS, use_cache=use_cache)
        ref = reference.ambient_occlusion(sc, g, float(gt_radius), rays, weighting, seed, use_cache=use_cache)
        err = float(metrics.masked_mean(ref.stderr.float(), g.mask))
        cases.append(Case(sc.name, g, ref.ao.float(), err))
    return cases


def median_timer(repeats: int = 3) -> Timer:
    """A :data:`Timer`: one untimed call (its output is returned), then the median of ``repeats`` timed calls
    (``time.perf_counter``), in milliseconds."""
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats: must be a positive integer, got {repeats!r}")

    def timer(call, values):
        out = call()
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            call()
            times.append(time.perf_counter() - t0)
        return out, statistics.median(times) * 1e3
    return timer


class Objective:
    """Mean RMSE of ``method`` over ``cases`` as a function of the tuned values (``{name: float}``).

    Args:
        method: an AO method name.
        base: the params dataclass the tuned values are applied to (discrete settings live here).
        cases: the :class:`Case` list to average over.
        seed: seeds the pass's generator (fresh on every call).
        budget_ms: reject configurations whose time per frame exceeds it (``None``: no timing while searching).
        timer: a :data:`Timer` (default :func:`median_timer` with 3 repeats).
        blur: blur the pass's AO before scoring and timing (a name of ``BLUR_SPACES``; ``None``: no blur).
    """

    def __init__(self, method: str, base, cases: Sequence[Case], *, seed: int = 0,
                 budget_ms: Optional[float] = None, timer: Optional[Timer] = None,
                 blur: Optional[str] = None) -> None:
        self.fn, cls, self.requires, _ = method_parts(method)
        self.blur, self.blur_base = check_blur(blur), blur_defaults(blur)
        if not isinstance(base, cls):
            raise TypeError(f"base: expected {cls.__name__}, got {type(base).__name__}")
        if not cases:
            raise ValueError("cases: need at least one scene")
        if budget_ms is not None and (isinstance(budget_ms, bool) or not isinstance(budget_ms, (int, float))
                                      or not budget_ms > 0 or not math.isfinite(budget_ms)):
            raise ValueError(f"budget_ms: must be a finite number > 0, got {budget_ms!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
        self.method, self.base, self.cases, self.seed = method, base, list(cases), seed
        self.budget_ms, self.timer = budget_ms, timer or median_timer(3)
        self.history: list[dict] = []
        self._memo: dict[tuple, dict] = {}
        self._inputs = [c.gbuffer.select(self.requires) for c in self.cases]

    def _run(self, params, gbuffer: GBuffer, blur_values: Optional[Mapping[str, Any]] = None,
             guide: Optional[GBuffer] = None) -> torch.Tensor:
        """The pass's AO on ``gbuffer``, its generator freshly seeded; blurred (guided by ``guide``, default
        ``gbuffer``) with ``blur_values`` over the blur's defaults when the objective has a blur."""
        gen = torch.Generator(device="cpu").manual_seed(self.seed)
        ao = self.fn(gbuffer, params, generator=gen).ao
        if self.blur is None:
            return ao
        return apply_blur(self.blur, ao, gbuffer if guide is None else guide,
                          {**self.blur_base, **(blur_values or {})})

    def config(self, values: Mapping[str, Any]):
        """``values`` as ``(params dataclass, {blur_*: float})``; ``ValueError``/``TypeError`` when invalid."""
        pv, bv = split_values(values)
        if bv:
            if self.blur is None:
                raise ValueError(f"{', '.join(bv)}: blur parameters need a blur (blur=...)")
            _check_blur_values(self.blur, bv)
        return with_values(self.base, pv), {k: float(v) for k, v in bv.items()}

    def errors(self, params, cases: Optional[Sequence[Case]] = None,
               blur_values: Optional[Mapping[str, float]] = None) -> list[float]:
        """RMSE of ``params`` (a params dataclass; ``blur_values`` for the blur) on each of ``cases`` (default:
        the objective's)."""
        out = []
        for c in (self.cases if cases is None else cases):
            ao = self._run(params, c.gbuffer.select(self.requires), blur_values, c.gbuffer).detach().float()
            out.append(float(metrics.rmse(ao, c.target, c.gbuffer.mask)))
        return out

    def time_ms(self, params, values: Optional[Mapping[str, float]] = None,
                blur_values: Optional[Mapping[str, float]] = None) -> float:
        """Time per frame of ``params`` (and the blur) on the first case (the objective's timer)."""
        g0 = self.cases[0].gbuffer
        return float(self.timer(lambda: self._run(params, self._inputs[0], blur_values, g0), dict(values or {}))[1])

    def evaluate(self, values: Mapping[str, float], *, time_it: Optional[bool] = None) -> dict:
        """One recorded evaluation ``{"values", "error", "errors", "time_ms", "status", "reason"}`` (memoised).

        ``error`` is the mean RMSE, ``+inf`` when the values are invalid for the params class or the time
        exceeds the budget. ``time_it`` (default: when a budget is set) times the configuration.
        """
        key = tuple(sorted((k, round(float(v), 12)) for k, v in values.items()))
        time_it = self.budget_ms is not None if time_it is None else time_it
        hit = self._memo.get(key)
        if hit is not None:
            if time_it and math.isnan(hit["time_ms"]) and hit["status"] == "ok":    # time it now, in place
                params, bvals = self.config(values)
                hit["time_ms"] = self.time_ms(params, hit["values"], bvals)
            return hit
        rec = {"values": {k: float(v) for k, v in values.items()}, "error": math.inf, "errors": [],
               "time_ms": math.nan, "status": "ok", "reason": ""}
        try:
            params, bvals = self.config(values)
        except (ValueError, TypeError) as e:
            rec.update(status="invalid", reason=str(e))
        else:
            first = None
            if time_it:
                first, rec["time_ms"] = self.timer(
                    lambda: self._run(params, self._inputs[0], bvals, self.cases[0].gbuffer), rec["values"])
            if self.budget_ms is not None and rec["time_ms"] > self.budget_ms:
                rec.update(status="over_budget", reason=f"{rec['time_ms']:.3g} ms > budget {self.budget_ms:g} ms")
            else:
                errs = []
                for i, c in enumerate(self.cases):
                    ao = (first if (i == 0 and first is not None)
                          else self._run(params, self._inputs[i], bvals, c.gbuffer))
                    errs.append(float(metrics.rmse(ao.detach().float(), c.target, c.gbuffer.mask)))
                rec.update(errors=errs, error=statistics.fmean(errs))
                if not math.isfinite(rec["error"]):
                    rec.update(error=math.inf, status="invalid", reason="non-finite error")
        self._memo[key] = rec
        self.history.append(rec)
        return rec

    def __call__(self, values: Mapping[str, float]) -> float:
        """The mean training RMSE of ``values`` (``+inf`` when rejected)."""
        return self.evaluate(values)["error"]

    def loss(self, fixed_values: Mapping[str, float], tensors: Mapping[str, torch.Tensor],
             gbuffers: Optional[Sequence[GBuffer]] = None) -> torch.Tensor:
        """Differentiable mean RMSE: ``fixed_values`` as floats, ``tensors`` injected as 0-d tensors.

        ``gbuffers``: the pass inputs to use instead of the cases' (e.g. cast to float64 for a gradient
        check); the targets are cast to their dtype. ``blur_*`` entries go to the blur (tensors stay on the tape).
        """
        params, bvals = self.config({k: v for k, v in fixed_values.items() if k not in tensors})
        ptens, btens = split_values(tensors)
        if btens:
            self.config(btens)                                  # names and domains, checked as floats
        params, bvals = inject(params, ptens), {**bvals, **btens}
        inputs = self._inputs if gbuffers is None else list(gbuffers)
        total = 0.0
        for c, g in zip(self.cases, inputs):
            ao = self._run(params, g, bvals, c.gbuffer)
            total = total + metrics.rmse(ao, c.target.to(ao.dtype), c.gbuffer.mask)
        return total / len(self.cases)
