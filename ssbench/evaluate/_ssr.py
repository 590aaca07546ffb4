"""Evaluate one SSR pass on one scene against the exact mirror reflection: one tidy row per run.

:func:`ssr` renders the reference G-buffer channels the pass reads (its ``REQUIRES``, plus
``REQUIRES_BACKFACE`` when its parameters turn back-face depth on, plus :data:`SSR_GT_CHANNELS`; ``color`` is
path traced by the reference with ``spp``/``seed``), runs and times the pass, traces the ground truth
(``ssbench.reference.reflections``), labels every pixel (:func:`ssbench.metrics.ssr.classify`) and scores hit
positions and colours. Row keys:

* settings and timings: ``scene, method, params, width, height, seed, spp, k_px, channels, back_face_depth,
  reflective, seconds, seconds_runs, repeats, warmup, threads, device, gt_seconds``;
* ``coverage`` (reflective share of the image), ``reflective_pixels``, ``nonfinite`` (NaN/Inf in the pass's
  colours and hit buffer), ``hit_rate`` / ``truth_hit_rate`` (raw hits over reflective pixels);
* ``frac_<class>`` for every class of :data:`ssbench.metrics.ssr.CLASS_NAMES` but ``not_reflective``,
  ``frac_unfixable``, ``frac_wrong_output`` (false, misplaced, punch-through and unfixable hits: a wrong colour
  shown) and ``frac_<target class>_pass_hit`` (the unfixable hits by target; see
  :func:`~ssbench.metrics.ssr.class_fractions`);
* ``hit_err_n``, ``hit_err_{px,view}_{mean,median,p95,max}`` over the pixels where both hit and the class is
  correct, false, misplaced hit or punch-through; ``hit_err_correct_{px,view}_mean`` over the correct hits only;
* ``{mae,rmse,psnr,flip}_{faded,raw}``: reflection colour vs path-traced radiance along the mirror ray on the
  reflective pixels (:func:`~ssbench.metrics.ssr.color_error`; a miss costs the full radiance, sky included);
  ``mae_{raw,faded}_truth_hit``: MAE on the reflective pixels whose mirror ray hits geometry (no sky);
* ``term_<reason>`` (termination shares over reflective pixels), ``steps_mean``, ``steps_max``.
"""
from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import statistics
from typing import Any, Optional, Union

import torch

from ..gbuffer import GBuffer
from ..rays import vector_norm
from ._common import params_as_dict, timed_runs, resolve_params

__all__ = ["ssr", "run_ssr", "SSREvaluation", "pass_channels", "SSR_GT_CHANNELS"]

#: G-buffer channels the classification reads on top of the pass's (ray origins, mask, shape ids)
SSR_GT_CHANNELS = ("position", "mask", "shape_id")


@dataclasses.dataclass(frozen=True)
class SSREvaluation:
    """Everything :func:`run_ssr` computed: the tidy ``row`` plus the images behind it (all on the CPU).

    Attributes:
        row: the flat dict :func:`ssr` returns.
        result: the pass's :class:`~ssbench.passes.ssr.common.SSRResult` (tensors on the CPU).
        truth: the ``ReflectionReference``.
        classes: :math:`(1, 1, H, W)` int8 classes (:func:`ssbench.metrics.ssr.classify`).
        gbuffer: the reference G-buffer (the pass's channels and :data:`SSR_GT_CHANNELS`).
        debug: the pass's ``debug`` dict (from an extra untimed ``debug=True`` run when asked for).
    """

    row: dict
    result: Any
    truth: Any
    classes: torch.Tensor
    gbuffer: GBuffer
    debug: dict


#: the equal-settings convention: ray length and thickness as fractions of the scene's viewing distance
EQUAL_RAY_LENGTH, EQUAL_THICKNESS = 1.0, 0.02


def scene_scale(gbuffer: GBuffer) -> float:
    """The scene's size as the camera sees it: the median distance from the eye to the visible geometry."""
    gbuffer.require("position", "mask")
    d = vector_norm(gbuffer.position.double())[gbuffer.mask]
    if d.numel() == 0:
        raise ValueError("gbuffer: no valid pixel, so the scene has no size to scale the settings by")
    return float(d.median())


def equal_roles(method: str) -> dict:
    """``{"thickness": name, "ray_length": name}``: the module's ``EQUAL_SETTINGS`` of SSR ``method``."""
    from ..passes import declared, ssr_method
    roles = declared(ssr_method(method)[0], "EQUAL_SETTINGS")
    if not roles or set(roles) != {"thickness", "ray_length"}:
        raise ValueError(f"method: {method!r} declares no EQUAL_SETTINGS (thickness, ray_length) in its module")
    return dict(roles)


def equal_settings(method: str, gbuffer: GBuffer, *, ray_length: float = EQUAL_RAY_LENGTH,
                   thickness: float = EQUAL_THICKNESS) -> dict:
    """Parameter overrides that put SSR ``method`` at the settings every marcher shares in an equal comparison:
    ray length ``ray_length·S`` and depth thickness ``thickness·S``, ``S`` = :func:`scene_scale`. Each pass
    module names its own parameters for the two roles in ``EQUAL_SETTINGS``.

    Example:
        >>> import torch
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 100.0)
        >>> pos = torch.zeros(1, 3, 3, 4); pos[:, 2] = -5.0
        >>> g = GBuffer(cam, position=pos, mask=torch.ones(1, 1, 3, 4, dtype=torch.bool))
        >>> equal_settings("dda", g)
        {'z_thickness': 0.1, 'max_ray_distance': 5.0}
    """
    roles = equal_roles(method)
    s = scene_scale(gbuffer)
    return {roles["thickness"]: thickness * s, roles["ray_length"]: ray_length * s}


def _back_face_on(params) -> bool:
    """Whether ``params`` turn on back-face depth: any True bool field whose name mentions ``back``."""
    return any(isinstance(getattr(params, f.name), bool) and getattr(params, f.name) and "back" in f.name
               for f in dataclasses.fields(params))


def pass_channels(module, params) -> tuple[str, ...]:
    """Channels an SSR pass reads with ``params``: ``module.required_channels(params)`` (or ``requires``) when
    the module defines it, else ``REQUIRES`` plus ``REQUIRES_BACKFACE`` when :func:`_back_face_on` (a True bool
    field named ``*back*``, e.g. ``use_back_face_depth``)."""
    fn = getattr(module, "required_channels", None) or getattr(module, "requires", None)
    if callable(fn):
        return tuple(dict.fromkeys(fn(params)))
    chans = tuple(getattr(module, "REQUIRES", ()))
    if _back_face_on(params):
        chans += tuple(getattr(module, "REQUIRES_BACKFACE", ("back_z",)))
    return tuple(dict.fromkeys(chans))


def accepted_kwargs(fn, **candidates) -> dict:
    """The keyword arguments of ``candidates`` that ``fn`` accepts."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return {}
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in sig.parameters.values()):
        return candidates
    return {k: v for k, v in candidates.items() if k in sig.parameters}


def on_cpu(result):
    """``result`` with every tensor field detached and on the CPU."""
    if not dataclasses.is_dataclass(result):
        raise TypeError(f"method: expected the pass to return an SSRResult, got {type(result).__name__}")
    out = {f.name: getattr(result, f.name).detach().cpu() for f in dataclasses.fields(result)
           if isinstance(getattr(result, f.name), torch.Tensor)}
    return dataclasses.replace(result, **out)


def reflections_module():
    from .. import reference
    fn = getattr(reference, "reflections", None)
    if fn is not None and not callable(fn):                       # the submodule, not the function
        fn = getattr(fn, "reflections", None)
    if fn is None:
        raise ImportError("ssbench.reference.reflections is not available yet")
    return fn


def _check_int(v, name: str, lo: int) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{name}: must be an integer >= {lo}, got {v!r}")


def run_ssr(scene, method: str, params=None, *, width: int = 320, height: int = 240, seed: int = 0,
            repeats: int = 3, spp: int = 16, k_px: float = 1.5, warmup: bool = True, device="cpu",
            gbuffer: Optional[GBuffer] = None, truth=None, reflective: Union[None, str, torch.Tensor] = None,
            flip: bool = True, debug: bool = False, use_cache: bool = True) -> SSREvaluation:
    """:func:`ssr` with its images: returns an :class:`SSREvaluation` (``.row`` is the tidy row).

    Extra keyword arguments (for reports and sweeps):
        warmup: run the pass once untimed first (``False``: time the first call).
        device: where the pass runs (timings synchronise CUDA); metrics run on the CPU.
        gbuffer: a batch-1 reference G-buffer to reuse (it must hold the pass's channels and
            :data:`SSR_GT_CHANNELS`); ``None`` renders one.
        truth: a ``ReflectionReference`` of that G-buffer to reuse; ``None`` traces it.
        reflective: ``None`` (every G-buffer hit), ``"marched"`` (pixels where the pass marched a ray,
            termination ≠ NO_RAY), ``"specular"`` (hits with ``metallic ≥ 0.5`` or ``roughness ≤ 0.5``: the
            surfaces a renderer would give screen-space reflections) or a :math:`(1, 1, H, W)` bool mask; the
            other pixels are not reflective.
        flip: compute ꟻLIP (the slowest metric).
        debug: one extra untimed run with ``debug=True`` (when the pass takes it) for ``debug["visits"]``.
        use_cache: let the reference read/write its disk cache.
    """
    from .. import reference
    from ..metrics import mae
    from ..metrics import ssr as M
    from ..passes import ssr_method
    from ..passes.ssr.common import NO_RAY
    from ..scenes import load as load_scene

    fn, params_cls, _ = ssr_method(method)
    module = importlib.import_module(fn.__module__)
    p = resolve_params(params_cls, params, method)
    _check_int(repeats, "repeats", 1)
    _check_int(seed, "seed", 0)
    _check_int(spp, "spp", 1)
    M.k_px_arg(k_px)
    if not (reflective is None or reflective in ("marched", "specular") or isinstance(reflective, torch.Tensor)):
        raise ValueError(f"reflective: expected None, 'marched', 'specular' or a bool mask, got {reflective!r}")

    sc = load_scene(scene)
    needs = pass_channels(module, p)
    chans = tuple(dict.fromkeys(needs + SSR_GT_CHANNELS
                                + (("metallic", "roughness") if reflective == "specular" else ())))
    if gbuffer is None:
        gbuffer = reference.gbuffer(sc, width, height, channels=chans, spp=spp, seed=seed, use_cache=use_cache)
    else:
        gbuffer.require(*chans)
    if gbuffer.batch_size != 1:
        raise ValueError(f"gbuffer: batch size must be 1, got {gbuffer.batch_size}")
    g_pass = gbuffer.select(needs).to(device)
    H, W = gbuffer.height, gbuffer.width

    def run_pass(dbg: bool = False):
        gen = torch.Generator(device="cpu").manual_seed(seed)               # same bits on every repeat
        extra = accepted_kwargs(fn, generator=gen, **({"debug": True} if dbg else {}))
        return fn(g_pass, p, **extra)

    result, times = timed_runs(run_pass, repeats, device, warmup)
    result = on_cpu(result)
    if tuple(result.hit.shape) != (1, 1, H, W):
        raise ValueError(f"method: {method!r} returned hit of shape {tuple(result.hit.shape)}, expected "
                         f"(1, 1, {H}, {W})")
    dbg = dict(getattr(result, "debug", None) or {})
    if debug and "debug" in accepted_kwargs(fn, debug=True):
        dbg = dict(on_cpu(run_pass(True)).debug or {})
    dbg = {k: (v.detach().cpu() if isinstance(v, torch.Tensor) else v) for k, v in dbg.items()}

    if truth is None:
        truth = reflections_module()(sc, gbuffer, spp=spp, seed=seed, use_cache=use_cache)
    g_cpu = gbuffer.to("cpu")
    if reflective == "specular":
        refl = g_cpu.mask & ((g_cpu.metallic >= 0.5) | (g_cpu.roughness <= 0.5))
    else:
        refl = result.termination != NO_RAY if isinstance(reflective, str) else reflective
    classes, _ = M.classify(result, truth, g_cpu, k_px, reflective=refl)
    valid = classes != M.NOT_REFLECTIVE
    frac = M.class_fractions(classes, M.truth_classes(truth, g_cpu, reflective=refl))
    pairs = torch.isin(classes, torch.tensor((M.CORRECT, M.FALSE_HIT, M.MISPLACED_HIT, M.PUNCH_THROUGH),
                                             dtype=classes.dtype))
    err = M.hit_error(result, truth, pairs)
    err_ok = M.hit_error(result, truth, classes == M.CORRECT)
    n = int(valid.sum())

    row: dict[str, Any] = {
        "scene": sc.name, "method": method, "params": params_as_dict(p), "width": W, "height": H, "seed": seed,
        "spp": spp, "k_px": float(k_px), "channels": list(needs), "back_face_depth": _back_face_on(p),
        "reflective": reflective if isinstance(reflective, str) or reflective is None else "mask",
        "seconds": statistics.median(times), "seconds_runs": times, "repeats": repeats, "warmup": bool(warmup),
        "threads": torch.get_num_threads(), "device": str(torch.device(device)),
        "gt_seconds": float(getattr(truth, "seconds", math.nan)),
        "coverage": frac["reflective"], "reflective_pixels": n,
        "nonfinite": int(sum(int((~torch.isfinite(t.float())).sum()) for t in
                             (result.color, result.raw_color, result.hit_view, result.hit_pixel))),
        "hit_rate": float((result.hit.bool() & valid).sum()) / n if n else math.nan,
        "truth_hit_rate": float((truth.hit.bool() & valid).sum()) / n if n else math.nan,
    }
    row.update({f"frac_{k}": v for k, v in frac.items() if k not in ("reflective", "reflective_pixels")})
    row.update({f"hit_err_{k}": v for k, v in err.items()})
    row["hit_err_correct_px_mean"], row["hit_err_correct_view_mean"] = err_ok["px_mean"], err_ok["view_mean"]
    row.update(M.color_error(result, truth, valid, flip=flip))
    th = valid & truth.hit.bool()                         # no sky: what a fallback probe could not excuse
    for suffix, col in (("raw", result.raw_color), ("faded", result.color)):
        row[f"mae_{suffix}_truth_hit"] = float(mae(col.float(), truth.radiance.float(), th))
    row.update({f"term_{k}": v for k, v in M.termination_fractions(result.termination, valid).items()})
    steps = result.steps[valid].float()
    row["steps_mean"] = float(steps.mean()) if steps.numel() else math.nan
    row["steps_max"] = int(steps.max()) if steps.numel() else 0
    return SSREvaluation(row, result, truth, classes, gbuffer, dbg)


def ssr(scene, method: str, params=None, *, width: int = 320, height: int = 240, seed: int = 0,
        repeats: int = 3, spp: int = 16, **kwargs) -> dict:
    """Run SSR ``method`` on ``scene`` and score it against the exact mirror reflection: one tidy row.

    Args:
        scene: catalog name, scene file, dict or :class:`~ssbench.scenes.Scene`.
        method: a name of :data:`ssbench.passes.SSR_METHODS` (``"linear"``, ``"dda"``, ``"dda_supercover"``).
        params: ``None`` (defaults), the pass's params dataclass, or a dict of overrides (unknown names →
            ``ValueError`` naming them).
        width, height: image size of the reference G-buffer.
        seed: seeds the pass's generator (fresh each repeat), the colour buffer and the truth's radiance.
        repeats: timed runs after one warm-up; ``seconds`` is their median (``time.perf_counter``).
        spp: path samples per pixel of the colour buffer and of the truth's radiance.
        **kwargs: ``k_px`` (hit tolerance in pixels, 1.5) and those of :func:`run_ssr` (``warmup``,
            ``device``, ``gbuffer``, ``truth``, ``reflective``, ``flip``, ``debug``, ``use_cache``).

    Returns:
        A flat dict; keys in the module docstring of :mod:`ssbench.evaluate._ssr`.
    """
    return run_ssr(scene, method, params, width=width, height=height, seed=seed, repeats=repeats, spp=spp,
                   **kwargs).row
