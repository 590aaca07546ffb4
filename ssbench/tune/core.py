"""The tuning objective: mean RMSE of a pass against a *fixed* ray-traced AO over a set of scenes.

:func:`prepare_cases` renders each scene's reference G-buffer and traces its ground truth once (both through
the reference's disk cache); :class:`Objective` then scores any configuration of the pass on those cases
without touching Mitsuba again. The ground-truth radius, flavour, rays and seed are fixed for the whole run;
only the pass's parameters move. The pass's noise generator is re-seeded with ``seed`` on every call, so the
objective is a deterministic function of the parameters.

With a frame-time budget every configuration is timed (:func:`median_timer`: one warm-up call, then the median
of ``repeats`` calls on the first case) and one slower than the budget is rejected (``+inf``); each evaluation
is recorded in :attr:`Objective.history` with its status (``ok``, ``over_budget``, ``invalid``).
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
from .space import method_parts, with_values

__all__ = ["Case", "prepare_cases", "Objective", "median_timer", "Timer", "PASS_CHANNELS"]

#: G-buffer channels the cases hold: every AO pass reads a subset of these
PASS_CHANNELS = ("view_z", "normal", "mask")
#: ``timer(call, values) -> (output of call(), milliseconds per call)``
Timer = Callable[[Callable[[], Any], Mapping[str, float]], tuple[Any, float]]


@dataclasses.dataclass(frozen=True)
class Case:
    """One scene ready for tuning: its G-buffer (:data:`PASS_CHANNELS`) and fixed target AO (1, 1, H, W)."""

    scene: str
    gbuffer: GBuffer
    target: torch.Tensor
    gt_stderr: float = math.nan


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
    """

    def __init__(self, method: str, base, cases: Sequence[Case], *, seed: int = 0,
                 budget_ms: Optional[float] = None, timer: Optional[Timer] = None) -> None:
        self.fn, cls, self.requires, _ = method_parts(method)
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

    def _run(self, params, gbuffer: GBuffer) -> torch.Tensor:
        """The pass's AO on ``gbuffer``, its generator freshly seeded."""
        gen = torch.Generator(device="cpu").manual_seed(self.seed)
        return self.fn(gbuffer, params, generator=gen).ao

    def errors(self, params, cases: Optional[Sequence[Case]] = None) -> list[float]:
        """RMSE of ``params`` (a params dataclass) on each of ``cases`` (default: the objective's)."""
        out = []
        for c in (self.cases if cases is None else cases):
            ao = self._run(params, c.gbuffer.select(self.requires)).detach().float()
            out.append(float(metrics.rmse(ao, c.target, c.gbuffer.mask)))
        return out

    def time_ms(self, params, values: Optional[Mapping[str, float]] = None) -> float:
        """Time per frame of ``params`` on the first case (the objective's timer)."""
        return float(self.timer(lambda: self._run(params, self._inputs[0]), dict(values or {}))[1])

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
                hit["time_ms"] = self.time_ms(with_values(self.base, values), hit["values"])
            return hit
        rec = {"values": {k: float(v) for k, v in values.items()}, "error": math.inf, "errors": [],
               "time_ms": math.nan, "status": "ok", "reason": ""}
        try:
            params = with_values(self.base, values)
        except (ValueError, TypeError) as e:
            rec.update(status="invalid", reason=str(e))
        else:
            first = None
            if time_it:
                first, rec["time_ms"] = self.timer(lambda: self._run(params, self._inputs[0]), rec["values"])
            if self.budget_ms is not None and rec["time_ms"] > self.budget_ms:
                rec.update(status="over_budget", reason=f"{rec['time_ms']:.3g} ms > budget {self.budget_ms:g} ms")
            else:
                errs = []
                for i, c in enumerate(self.cases):
                    ao = first if (i == 0 and first is not None) else self._run(params, self._inputs[i])
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
        check); the targets are cast to their dtype.
        """
        params = inject(with_values(self.base, {k: v for k, v in fixed_values.items() if k not in tensors}),
                        tensors)
        inputs = self._inputs if gbuffers is None else list(gbuffers)
        total = 0.0
        for c, g in zip(self.cases, inputs):
            ao = self._run(params, g)
            total = total + metrics.rmse(ao, c.target.to(ao.dtype), c.gbuffer.mask)
        return total / len(self.cases)
