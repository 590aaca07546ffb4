"""Evaluate one AO pass on one scene against the ray-traced ground truth: one tidy row per run.

:func:`ao` renders the reference G-buffer, runs and times the pass, traces the ground truth in the flavour the
pass approximates (its module's ``FLAVOUR``; ``"cosine"`` when it declares none), the cosine ground truth and
the screen-space oracle, and scores the pass against each with every metric of :mod:`ssbench.metrics`.
Metric keys are ``<metric>_<target>`` with targets

* ``cos`` — cosine-weighted ray-traced AO (the common yardstick);
* ``flavour`` — ray-traced AO in the pass's own flavour (``weighting`` in the row);
* ``oracle`` — the same flavour traced against the depth buffer as a height field (what a screen-space pass
  can know), so ``rmse_oracle`` is the *estimator* error; ``info_loss_*`` score the oracle against the
  flavour ground truth (the *information loss* of screen space). They are ``nan`` when no oracle is available.

The row also holds ``banding`` (the low-passed error against the oracle, or the flavour ground truth without
one: ``banding_target``; :func:`ssbench.metrics.banding`), ``tile_energy`` (the share of the image at the noise
tile ``tile``) and ``noise`` (with a blur also ``*_raw`` before it), the reference
noise floor ``gt_stderr_*`` (mean per-pixel standard error), timings and settings. No files are written here
(the reference's disk cache aside: ``use_cache=False`` turns it off).
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import statistics
from typing import Any, Callable, Mapping, Optional

import torch

from .. import metrics
from ..gbuffer import GBuffer
from ._common import params_as_dict, as_float, timed_runs, resolve_params

__all__ = ["ao", "run_ao", "AOEvaluation", "resolve_params", "radius_param", "flavour", "score", "blur_fn",
           "RADIUS_NAMES", "GT_CHANNELS", "BLUR_NAMES"]

#: parameter names taken to be a pass's occlusion radius (world units), in order of preference; a pass module
#: may name its own with a module-level ``RADIUS_PARAM``.
RADIUS_NAMES = ("radius", "kernel_radius", "sample_radius")
#: G-buffer channels the ground truth, the oracle and the metrics read (on top of the pass's ``REQUIRES``).
GT_CHANNELS = ("view_z", "position", "normal", "mask")
#: metrics scored against each target
TARGET_METRICS = ("mae", "rmse", "bias", "psnr", "ssim", "flip", "halo_band", "halo_elsewhere", "halo_ratio",
                  "halo_bias", "halo_dark", "halo_missing", "flat_bias", "over_darkening")
TARGETS = ("cos", "flavour", "oracle")


@dataclasses.dataclass(frozen=True)
class AOEvaluation:
    """Everything :func:`run_ao` computed: the tidy ``row`` plus the images behind it.

    Attributes:
        row: the flat dict :func:`ao` returns.
        ao: :math:`(1, 1, H, W)` the pass's AO (after ``blur`` when one was given), on the CPU.
        ao_raw: :math:`(1, 1, H, W)` the pass's AO before the blur (``ao`` itself without one).
        references: ``{"cos", "flavour", "oracle"}`` → ``AOReference`` (``"oracle"`` absent when unavailable).
        gbuffer: the reference G-buffer the pass read (all of :data:`GT_CHANNELS` and the pass's channels).
        result: the pass's :class:`~ssbench.passes.AOResult` (its debug buffers included).
    """

    row: dict
    ao: torch.Tensor
    ao_raw: torch.Tensor
    references: dict
    gbuffer: GBuffer
    result: Any


def radius_param(params_cls: type, module=None) -> Optional[str]:
    """Name of the pass's radius parameter: ``module.RADIUS_PARAM`` if set, else the first of
    :data:`RADIUS_NAMES` among the dataclass fields (``None`` when there is none)."""
    names = [f.name for f in dataclasses.fields(params_cls)]
    explicit = getattr(module, "RADIUS_PARAM", None) if module is not None else None
    if explicit is not None:
        return explicit if explicit in names else None
    return next((n for n in RADIUS_NAMES if n in names), None)


def flavour(fn: Callable) -> str:
    """The AO flavour a pass approximates: its module's ``FLAVOUR`` (default ``"cosine"``)."""
    from ..passes import declared
    return declared(fn, "FLAVOUR", "cosine")


def score(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor, view_z: torch.Tensor, suffix: str,
          *, flip: bool = True, halo_band: int = 4) -> dict:
    """Every metric of ``pred`` vs ``target`` (both :math:`(B, 1, H, W)`) as ``{"<metric>_<suffix>": float}``."""
    h = metrics.halo(pred, target, view_z, mask, band=halo_band)
    row = {"mae": metrics.mae(pred, target, mask), "rmse": metrics.rmse(pred, target, mask),
           "bias": metrics.bias(pred, target, mask), "psnr": metrics.psnr(pred, target, mask),
           "ssim": metrics.ssim(pred, target, mask),
           "flip": metrics.flip(pred, target, mask) if flip else None,
           "halo_band": h.band, "halo_elsewhere": h.elsewhere, "halo_ratio": h.ratio, "halo_bias": h.band_bias,
           "halo_dark": h.dark, "halo_missing": h.missing, "flat_bias": metrics.flat_bias(pred, target, mask),
           "over_darkening": metrics.over_darkening(pred, target, mask)}
    return {f"{k}_{suffix}": as_float(v) for k, v in row.items()}


def _nan_scores(suffix: str) -> dict:
    return {f"{k}_{suffix}": math.nan for k in TARGET_METRICS}


#: named blurs (``blur=`` of :func:`ao`): ``ssbench.passes.blur`` at the article's settings
BLUR_NAMES = ("box", "cross_bilateral", "joint_bilateral")


def blur_fn(name: str) -> Callable:
    """The named blur as ``fn(ao, gbuffer) -> ao``: ``"box"`` (the SSAO article's 5×5 box, not depth-aware),
    ``"cross_bilateral"`` (the SSAO article's 2-pass blur guided by ``view_z``, radius 15) or ``"joint_bilateral"``
    (kornia's joint bilateral guided by the linear depth, background masked out)."""
    from ..passes import blur as B
    table = {"box": lambda ao, g: B.box_blur(ao, 5),
             "cross_bilateral": lambda ao, g: B.cross_bilateral_blur(ao, g.view_z),
             "joint_bilateral": lambda ao, g: B.joint_bilateral_blur(ao, g.linear_depth, mask=g.mask)}
    if name not in table:
        raise ValueError(f"blur: unknown blur {name!r}; known: {', '.join(BLUR_NAMES)}")
    return table[name]


def _resolve_blur(blur) -> tuple[Optional[Callable], Optional[str]]:
    """``blur`` as ``(callable(ao, gbuffer) -> ao, name)``."""
    if blur is None:
        return None, None
    if isinstance(blur, str):
        return blur_fn(blur), blur
    if callable(blur):
        return blur, getattr(blur, "__name__", "blur")
    raise TypeError(f"blur: expected None, a name ({', '.join(BLUR_NAMES)}) or a callable, "
                    f"got {type(blur).__name__}")


def run_ao(scene, method: str, params=None, *, width: int = 320, height: int = 240,
           radius: Optional[float] = None, rays: int = 256, weighting: Optional[str] = None, seed: int = 0,
           blur=None, repeats: int = 3, warmup: bool = True, device="cpu", gbuffer: Optional[GBuffer] = None,
           references: Optional[dict] = None, oracle: bool = True, flip: bool = True,
           use_cache: bool = True) -> AOEvaluation:
    """:func:`ao` with its images: returns an :class:`AOEvaluation` (``.row`` is the tidy row).

    Extra keyword arguments (for reports and sweeps):
        warmup: run the pass once untimed first (``False``: time the first call, e.g. for a quick report).
        device: where the pass runs (timings synchronise CUDA); metrics run on the CPU.
        gbuffer: a batch-1 reference G-buffer to reuse (it sets the size and must hold :data:`GT_CHANNELS`
            and the pass's ``REQUIRES``); ``None`` renders one.
        references: a dict shared between calls on the same scene and G-buffer, memoising ground truths by
            ``(kind, weighting, radius, rays, seed)``.
        oracle: trace the screen-space oracle (``False``: its metrics are ``nan``).
        flip: compute ꟻLIP (the slowest metric).
        use_cache: let the reference read/write its disk cache.
    """
    from .. import reference
    from ..passes import ao_method
    from ..scenes import load as load_scene

    fn, params_cls, requires = ao_method(method)
    module = importlib.import_module(fn.__module__)
    p = resolve_params(params_cls, params, method)
    rname = radius_param(params_cls, module)
    if radius is not None:
        if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not radius > 0:
            raise ValueError(f"radius: must be a number > 0, got {radius!r}")
        if rname is None:
            raise ValueError(f"radius: method {method!r} has no radius parameter (looked for "
                             f"{', '.join(RADIUS_NAMES)})")
        if isinstance(params, Mapping) and rname in params and params[rname] != radius:
            raise ValueError(f"radius: {radius} conflicts with params[{rname!r}] = {params[rname]}")
        p = dataclasses.replace(p, **{rname: float(radius) if isinstance(getattr(p, rname), float) else radius})
    if rname is None:
        raise ValueError(f"method: {method!r} has no radius parameter ({', '.join(RADIUS_NAMES)}), so the "
                         f"ground-truth radius is unknown; set RADIUS_PARAM in its module")
    gt_radius = float(getattr(p, rname))
    flav = weighting if weighting is not None else flavour(fn)
    if flav not in reference.WEIGHTINGS:
        raise ValueError(f"weighting: expected one of {', '.join(reference.WEIGHTINGS)}, got {flav!r}")
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise ValueError(f"repeats: must be a positive integer, got {repeats!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    blur_call, blur_name = _resolve_blur(blur)

    sc = load_scene(scene)
    chans = tuple(dict.fromkeys(tuple(requires) + GT_CHANNELS))
    if gbuffer is None:
        gbuffer = reference.gbuffer(sc, width, height, channels=chans, use_cache=use_cache)
    else:
        gbuffer.require(*chans)
    if gbuffer.batch_size != 1:
        raise ValueError(f"gbuffer: batch size must be 1, got {gbuffer.batch_size}")
    g_pass = gbuffer.select(tuple(dict.fromkeys(requires))).to(device)

    def run_pass():
        gen = torch.Generator(device="cpu").manual_seed(seed)               # same bits on every repeat
        return fn(g_pass, p, generator=gen)

    from ..passes import compiled
    compile_before = compiled.compile_seconds()
    result, times = timed_runs(run_pass, repeats, device, warmup)
    compile_s = compiled.compile_seconds() - compile_before
    raw = result.ao.detach().float().cpu()
    if tuple(raw.shape) != (1, 1, gbuffer.height, gbuffer.width):
        raise ValueError(f"method: {method!r} returned ao of shape {tuple(raw.shape)}, expected "
                         f"(1, 1, {gbuffer.height}, {gbuffer.width})")
    blur_times: list[float] = []
    pred = raw
    if blur_call is not None:
        g_blur = gbuffer.to(device)
        out, blur_times = timed_runs(lambda: blur_call(result.ao, g_blur), repeats, device, warmup)
        pred = (out.ao if hasattr(out, "ao") else out).detach().float().cpu()

    memo = references if references is not None else {}

    def ref(kind: str, w: str):
        key = (kind, w, gt_radius, rays, seed)
        if key not in memo:
            if kind == "full":
                memo[key] = reference.ambient_occlusion(sc, gbuffer, gt_radius, rays, w, seed, use_cache=use_cache)
            else:
                memo[key] = reference.screen_space_oracle(gbuffer, gt_radius, rays, w, seed, use_cache=use_cache)
        return memo[key]

    refs = {"cos": ref("full", "cosine"), "flavour": ref("full", flav)}
    oracle_error = None
    if oracle:
        try:
            refs["oracle"] = ref("oracle", flav)
        except (ImportError, AttributeError, RuntimeError) as e:
            oracle_error = f"{type(e).__name__}: {e}"
    mask, view_z = gbuffer.mask.cpu(), gbuffer.view_z.float().cpu()

    row: dict[str, Any] = {
        "scene": sc.name, "method": method, "params": params_as_dict(p), "width": gbuffer.width,
        "height": gbuffer.height, "radius": gt_radius, "radius_param": rname, "weighting": flav,
        "blur": blur_name, "seconds": statistics.median(times), "seconds_runs": times,
        "blur_seconds": statistics.median(blur_times) if blur_times else None, "repeats": repeats,
        "warmup": bool(warmup),
        "threads": torch.get_num_threads(), "device": str(torch.device(device)), "rays": rays, "seed": seed,
        "compiled": compiled.enabled(), "compile_s": compile_s,
        "coverage": float(mask.float().mean()), "nonfinite": int((~torch.isfinite(raw)).sum()),
        "oracle": "oracle" in refs, "oracle_error": oracle_error,
    }
    scored: dict[str, dict] = {}
    for t in TARGETS:
        if t not in refs:
            row.update(_nan_scores(t))
            continue
        same = next((u for u in scored if refs[u] is refs[t]), None)     # e.g. a cosine pass: flavour = cos
        scored[t] = {k[:-len(same)] + t: v for k, v in scored[same].items()} if same else \
            score(pred, refs[t].ao.float(), mask, view_z, t, flip=flip)
        row.update(scored[t])
    band_target = "oracle" if "oracle" in refs else "flavour"     # structured *estimator* error when possible
    tref = refs[band_target]

    def band(x):
        return float(metrics.banding(x, tref.ao.float(), view_z, mask, target_stderr=tref.stderr.float()))

    tile = int(getattr(p, "noise_size", 4))          # the pass's own noise tile (GTAO/Crytek: the article's 4)
    row.update(banding=band(pred), banding_target=band_target, tile=tile,
               tile_energy=float(metrics.tile_energy(pred, mask, tile=tile)), noise=float(metrics.noise(pred, mask)))
    if blur_call is not None:
        row.update(banding_raw=band(raw), tile_energy_raw=float(metrics.tile_energy(raw, mask, tile=tile)),
                   noise_raw=float(metrics.noise(raw, mask)))
    if "oracle" in refs:
        o, full = refs["oracle"].ao.float(), refs["flavour"].ao.float()
        row.update(info_loss_mae=float(metrics.mae(o, full, mask)), info_loss_rmse=float(metrics.rmse(o, full, mask)),
                   info_loss_bias=float(metrics.bias(o, full, mask)))
    else:
        row.update(info_loss_mae=math.nan, info_loss_rmse=math.nan, info_loss_bias=math.nan)
    row["estimator_rmse"], row["estimator_mae"] = row["rmse_oracle"], row["mae_oracle"]
    for t, r in refs.items():
        row[f"gt_stderr_{t}"] = float(metrics.masked_mean(r.stderr.float(), mask))
        row[f"gt_seconds_{t}"] = float(getattr(r, "seconds", math.nan))
    return AOEvaluation(row, pred, raw, refs, gbuffer, result)


def ao(scene, method: str, params=None, *, width: int = 320, height: int = 240, radius: Optional[float] = None,
       rays: int = 256, weighting: Optional[str] = None, seed: int = 0, blur=None, repeats: int = 3,
       **kwargs) -> dict:
    """Run AO ``method`` on ``scene`` and score it against the ray-traced ground truth: one tidy row.

    Args:
        scene: catalog name, scene file, dict or :class:`~ssbench.scenes.Scene`.
        method: a name of :data:`ssbench.passes.AO_METHODS` (``"ssao"``, ``"hbao"``, ``"gtao"``, ``"crytek"``).
        params: ``None`` (defaults), the pass's params dataclass, or a dict of overrides (unknown names →
            ``ValueError`` naming them).
        width, height: image size of the reference G-buffer.
        radius: occlusion radius for the pass *and* the ground truth (sets the pass's radius parameter:
            ``radius``, ``kernel_radius``, …); ``None`` keeps the pass's value and traces the GT with it.
        rays: ground-truth rays per pixel.
        weighting: the flavour to score against as ``*_flavour``/``*_oracle`` (default: the pass's ``FLAVOUR``).
        seed: seeds the pass's generator (fresh each repeat) and the ground truth.
        blur: ``None``, a name of :data:`BLUR_NAMES` (see :func:`blur_fn`) or a callable
            ``blur(ao, gbuffer) -> ao`` (it gets the full G-buffer); metrics then score the blurred AO and
            ``noise_raw``/``banding_raw``/``tile_energy_raw`` the pass output (``blur_seconds`` times the blur).
        repeats: timed runs after one warm-up; ``seconds`` is their median (``time.perf_counter``).
        **kwargs: see :func:`run_ao` (``warmup``, ``device``, ``gbuffer``, ``references``, ``oracle``,
            ``flip``, ``use_cache``).

    Returns:
        A flat dict: ``scene, method, params`` (dict), ``width, height, radius, radius_param, weighting, blur,
        seconds, seconds_runs, blur_seconds, repeats, warmup, threads, device, rays, seed, coverage, nonfinite,
        oracle, oracle_error``, ``<metric>_<cos|flavour|oracle>`` for each metric in
        :data:`TARGET_METRICS`, ``banding, banding_target, tile, tile_energy, noise`` (``*_raw`` with a blur),
        ``info_loss_{mae,rmse,bias}``,
        ``estimator_{rmse,mae}``, ``gt_stderr_<target>`` and ``gt_seconds_<target>``.
    """
    return run_ao(scene, method, params, width=width, height=height, radius=radius, rays=rays,
                  weighting=weighting, seed=seed, blur=blur, repeats=repeats, **kwargs).row
