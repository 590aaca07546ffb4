"""Evaluate one SSR pass on rough surfaces against the path-traced specular lobe: one tidy row per run.

:func:`run_glossy` renders (or reuses) a G-buffer with the pass's channels and :data:`GLOSSY_GT_CHANNELS`, runs
and times the pass, traces the glossy truth (:func:`ssbench.reference.glossy.glossy_reflections`) and scores the
pass's fade-free reflection (``raw_color``: the lobe-averaged radiance it estimates) on the specular pixels
(``metallic ≥ 0.5`` or ``roughness ≤ 0.5``). Any SSR method can be scored: a mirror marcher is the baseline a
glossy method must beat. The error splits into three parts:

* **information loss** ``rmse_oracle``: the screen-space oracle (what the G-buffer can show along the lobe's
  rays) against the lobe — no screen-space method can do better;
* **marcher and filter** ``rmse_vs_oracle``: the pass against the oracle;
* **resolve** ``rmse_resolve_only``: the article's resolve (``F·(1 − roughness)``,
  :func:`ssbench.passes.ssr.resolve.specular_weight`) applied to the *true* lobe, against the true specular
  radiance; ``rmse_specular`` applies it to the pass's reflection (the whole chain).

The truth is path traced, so each score has a noisy reference: next to every RMSE against it, ``*_net`` removes
the truth's own variance (``√max(0, RMSE² − mean se²)``, the standard errors of ``ssbench.reference.glossy``).

Row keys: ``scene, method, params, width, height, seed, spp, rays, seconds, seconds_runs, threads, gt_seconds,
glossy_pixels, nonfinite``; ``mae_*`` (robust to the fireflies a path-traced rough metal lit by a point light
has) and ``rmse_*[_net]`` for ``lobe`` (the pass against the lobe), ``oracle`` (information loss),
``vs_oracle`` (marcher and filter), ``specular`` and ``resolve_only``; ``truth_se_mean`` / ``truth_se`` (mean /
RMS of the lobe's per-pixel standard error) and ``bins``: per roughness bin (:data:`ROUGHNESS_EDGES`)
``{lo, hi, n}`` and the same scores.
"""
from __future__ import annotations

import dataclasses
import math
import statistics
from typing import Any, Optional

import torch

from ..gbuffer import GBuffer
from ._common import params_as_dict, resolve_params, timed_runs

__all__ = ["run_glossy", "ssr_glossy", "GlossyEvaluation", "GLOSSY_GT_CHANNELS", "ROUGHNESS_EDGES"]

#: channels the truth and the scoring read on top of the pass's
GLOSSY_GT_CHANNELS = ("view_z", "normal", "position", "mask", "color", "roughness", "metallic", "albedo")
#: roughness bins of the error-vs-roughness curves (the glossy_ramp scene's strips fall one per bin)
ROUGHNESS_EDGES = (0.0, 0.025, 0.075, 0.15, 0.275, 0.425, 0.6)


@dataclasses.dataclass(frozen=True)
class GlossyEvaluation:
    """``row`` (the tidy dict), ``result`` (the pass's SSRResult on the CPU), ``truth`` (GlossyReference),
    ``gbuffer`` and ``scored`` (:math:`(1, 1, H, W)` bool, the pixels scored)."""

    row: dict
    result: Any
    truth: Any
    gbuffer: GBuffer
    scored: torch.Tensor


def _rmse(a: torch.Tensor, b: torch.Tensor, m: torch.Tensor) -> float:
    from ..metrics import rmse
    return float(rmse(a.double(), b.double(), m))


def _net(a: torch.Tensor, b: torch.Tensor, se: torch.Tensor, m: torch.Tensor) -> float:
    """The RMSE of ``a`` against a noisy truth ``b`` with the truth's variance (``se²``) taken out:
    ``√max(0, RMSE² − mean se²)`` (``E[(a − b̂)²] = (a − b)² + se²`` for an unbiased ``b̂``)."""
    var = _rmse(se, torch.zeros_like(se), m) ** 2
    return math.sqrt(max(0.0, _rmse(a, b, m) ** 2 - var)) if bool(m.any()) else math.nan


def _mae(a: torch.Tensor, b: torch.Tensor, m: torch.Tensor) -> float:
    from ..metrics import mae
    return float(mae(a.double(), b.double(), m))


def _scores(est: torch.Tensor, truth, m: torch.Tensor) -> dict:
    """The error split on the pixels ``m``: MAE (robust to the fireflies of path-traced glossy light), RMSE, and
    RMSE with the truth's noise removed (``*_net``); ``truth_se_mean`` is the lobe's mean standard error."""
    zero = torch.zeros_like(truth.lobe_se)
    return {"mae_lobe": _mae(est, truth.lobe, m), "mae_oracle": _mae(truth.oracle, truth.lobe, m),
            "mae_vs_oracle": _mae(est, truth.oracle, m), "truth_se_mean": _mae(truth.lobe_se, zero, m),
            "rmse_lobe": _rmse(est, truth.lobe, m), "rmse_lobe_net": _net(est, truth.lobe, truth.lobe_se, m),
            "rmse_oracle": _rmse(truth.oracle, truth.lobe, m),
            "rmse_oracle_net": _net(truth.oracle, truth.lobe, truth.gap_se, m),
            "rmse_vs_oracle": _rmse(est, truth.oracle, m),
            "rmse_vs_oracle_net": _net(est, truth.oracle, truth.oracle_se, m),
            "truth_se": _rmse(truth.lobe_se, zero, m)}


def run_glossy(scene, method: str, params=None, *, width: int = 160, height: int = 120, seed: int = 0,
               repeats: int = 1, spp: int = 16, rays: int = 32, warmup: bool = True, device="cpu",
               gbuffer: Optional[GBuffer] = None, truth=None, use_cache: bool = True) -> GlossyEvaluation:
    """Run SSR ``method`` on ``scene`` and score it against the glossy truth (module docstring).

    Args:
        scene, method, params: as :func:`ssbench.evaluate.ssr`.
        width, height, seed, spp: the reference G-buffer (``spp`` for its colour); ``seed`` also seeds the pass.
        rays: lobe directions per pixel of the truth. repeats, warmup, device: the timing.
        gbuffer, truth: a batch-1 G-buffer (with the pass's channels and :data:`GLOSSY_GT_CHANNELS`) and its
            GlossyReference to reuse.
    """
    from .. import reference
    from ..passes import ssr_method
    from ..passes.ssr.resolve import specular_weight
    from ..reference.glossy import glossy_reflections
    from ..scenes import load as load_scene
    from ._ssr import accepted_kwargs, on_cpu, pass_channels
    import importlib
    fn, params_cls, _ = ssr_method(method)
    p = resolve_params(params_cls, params, method)
    for name, v, lo in (("repeats", repeats, 1), ("seed", seed, 0), ("spp", spp, 1), ("rays", rays, 2)):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name}: must be an integer >= {lo}, got {v!r}")
    sc = load_scene(scene)
    needs = pass_channels(importlib.import_module(fn.__module__), p)
    chans = tuple(dict.fromkeys(needs + GLOSSY_GT_CHANNELS))
    if gbuffer is None:
        gbuffer = reference.gbuffer(sc, width, height, channels=chans, spp=spp, seed=seed, use_cache=use_cache)
    gbuffer.require(*chans)
    if gbuffer.batch_size != 1:
        raise ValueError(f"gbuffer: batch size must be 1, got {gbuffer.batch_size}")
    g_pass = gbuffer.select(needs).to(device)

    def run_pass():
        gen = torch.Generator(device="cpu").manual_seed(seed)
        return fn(g_pass, p, **accepted_kwargs(fn, generator=gen))

    result, times = timed_runs(run_pass, repeats, device, warmup)
    result = on_cpu(result)
    if truth is None:
        truth = glossy_reflections(sc, gbuffer, rays=rays, seed=seed, use_cache=use_cache)
    g = gbuffer.to("cpu")
    scored = truth.valid.bool() & g.mask & ((g.metallic >= 0.5) | (g.roughness <= 0.5))
    est = result.raw_color.double()
    weight = specular_weight(g).double()
    row: dict[str, Any] = {
        "scene": sc.name, "method": method, "params": params_as_dict(p), "width": g.width, "height": g.height,
        "seed": seed, "spp": spp, "rays": int(truth.rays), "seconds": statistics.median(times), "seconds_runs": times,
        "threads": torch.get_num_threads(), "gt_seconds": float(truth.seconds), "glossy_pixels": int(scored.sum()),
        "nonfinite": int((~torch.isfinite(result.raw_color)).sum()),
        **_scores(est, truth, scored),
        "mae_specular": _mae(weight * est, truth.specular, scored),
        "mae_resolve_only": _mae(weight * truth.lobe.double(), truth.specular, scored),
        "rmse_specular": _rmse(weight * est, truth.specular, scored),
        "rmse_resolve_only": _rmse(weight * truth.lobe.double(), truth.specular, scored),
    }
    r = g.roughness
    bins = []
    for lo, hi in zip(ROUGHNESS_EDGES[:-1], ROUGHNESS_EDGES[1:]):
        m = scored & (r >= lo) & (r < hi)
        bins.append({"lo": lo, "hi": hi, "n": int(m.sum()), **_scores(est, truth, m)})
    row["bins"] = bins
    return GlossyEvaluation(row, result, truth, gbuffer, scored)


def ssr_glossy(scene, method: str, params=None, **kwargs) -> dict:
    """:func:`run_glossy`'s tidy row only."""
    return run_glossy(scene, method, params, **kwargs).row
