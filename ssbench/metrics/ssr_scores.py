r"""Summary metrics of an SSR pass against the exact mirror reflection, from the per-pixel classes
(:func:`~ssbench.metrics.ssr_classify.classify`) and the pass's hits and colours.

* class shares: :func:`class_counts`, :func:`class_fractions` (``unfixable_hit`` split by target included),
  :func:`termination_fractions`;
* hit-position error: :func:`hit_error_maps`, :func:`hit_error` (pixels and view units over the pixels where
  both hit);
* colour error: :func:`color_error` (MAE, RMSE, PSNR, ꟻLIP of the faded and the raw reflection colour against
  the path-traced radiance along the mirror ray, via :mod:`ssbench.metrics.image`), :func:`color_error_map`.

The ground truth is used duck-typed, as in :mod:`ssbench.metrics.ssr_classify`. Public import path:
:mod:`ssbench.metrics.ssr`.
"""
from __future__ import annotations

import math
from typing import Any, Optional

import torch

from .. import checks
from ..rays import length
from ._ssr_checks import check_classes, check_pair, mask_arg
from .ssr_classes import CLASS_NAMES, NOT_REFLECTIVE, UNFIXABLE, UNFIXABLE_HIT, WRONG_OUTPUT

__all__ = ["class_counts", "class_fractions", "termination_fractions", "hit_error_maps", "hit_error",
           "color_error", "color_error_map"]


# ------------------------------------------------------------------------------------------ fractions
def class_counts(classes: torch.Tensor) -> dict[str, int]:
    """Pixel count of every class, by key (all batch items pooled)."""
    check_classes(classes)
    return {key: int((classes == code).sum()) for code, key in CLASS_NAMES.items()}


def class_fractions(classes: torch.Tensor, targets: Optional[torch.Tensor] = None) -> dict[str, float]:
    r"""Share of each class among the *reflective* pixels (all codes but :data:`NOT_REFLECTIVE`).

    Keys: every :data:`CLASS_NAMES` key but ``not_reflective`` (fractions of the reflective pixels, summing to
    1), ``reflective`` (share of the image that is reflective), ``reflective_pixels`` (their count, as a
    float), ``unfixable`` (targets no screen-space pass can reach: the three target classes and
    :data:`UNFIXABLE_HIT` together), ``wrong_output`` (the pass returned a wrong colour: false, misplaced,
    punch-through and unfixable hits, :data:`WRONG_OUTPUT`) and, when the truth's own classes ``targets``
    (:func:`~ssbench.metrics.ssr_classify.truth_classes`) are given, ``<target class>_pass_hit``: the
    unfixable hits split by target. Fractions are ``nan`` when no pixel is reflective.

    Example:
        >>> c = torch.tensor([0, 1, 1, 2, 10, 8], dtype=torch.int8).view(1, 1, 1, 6)
        >>> t = torch.tensor([0, 1, 1, 1, 5, 8], dtype=torch.int8).view(1, 1, 1, 6)
        >>> f = class_fractions(c, t)
        >>> f["correct"], f["unfixable_hit"], f["unfixable"], f["off_screen_target_pass_hit"], f["reflective"]
        (0.4, 0.2, 0.2, 0.2, 0.8333333333333334)
    """
    check_classes(classes)
    if targets is not None:
        check_classes(targets)
        if targets.shape != classes.shape:
            raise ValueError(f"targets: shape must match classes {tuple(classes.shape)}, got {tuple(targets.shape)}")
    refl = classes != NOT_REFLECTIVE
    n = int(refl.sum())
    frac = (lambda m: int(m.sum()) / n) if n else (lambda m: math.nan)
    out: dict[str, float] = {key: frac(classes == code) for code, key in CLASS_NAMES.items()
                             if code != NOT_REFLECTIVE}
    out["unfixable"] = frac(refl & torch.isin(classes, torch.tensor(UNFIXABLE + (UNFIXABLE_HIT,),
                                                                      dtype=classes.dtype)))
    out["wrong_output"] = frac(refl & torch.isin(classes, torch.tensor(WRONG_OUTPUT, dtype=classes.dtype)))
    if targets is not None:
        for code in UNFIXABLE:
            out[f"{CLASS_NAMES[code]}_pass_hit"] = frac((classes == UNFIXABLE_HIT) & (targets == code))
    out["reflective"] = n / classes.numel() if classes.numel() else math.nan
    out["reflective_pixels"] = float(n)
    return out


def termination_fractions(termination: torch.Tensor, mask: Optional[torch.Tensor] = None) -> dict[str, float]:
    """Share of each termination reason (``ssbench.passes.ssr.common.TERMINATION_NAMES``, spaces → ``_``) over ``mask``."""
    from ..passes.ssr.common import TERMINATION_NAMES
    checks.check_shape(termination, ["B", "1", "H", "W"], "termination")
    m = torch.ones_like(termination, dtype=torch.bool) if mask is None else mask_arg(mask, termination, "mask")
    n = int(m.sum())
    return {name.replace(" ", "_"): (int(((termination == code) & m).sum()) / n if n else math.nan)
            for code, name in TERMINATION_NAMES.items()}


# ------------------------------------------------------------------------------------------ hit error
def hit_error_maps(result: Any, truth: Any) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Per-pixel hit error where both the pass and the truth hit, ``nan`` elsewhere.

    Returns ``(pixels, view)``, each :math:`(B, 1, H, W)` float64:
    :math:`\lVert \hat p - p\rVert_2` in pixels and :math:`\lVert \hat X - X\rVert_2` in view (scene) units.
    """
    check_pair(result, truth)
    both = result.hit.bool() & truth.hit.bool()
    px = length(result.hit_pixel.double() - truth.hit_pixel.double())
    vw = length(result.hit_view.double() - truth.hit_view.double())
    nan = torch.full_like(px, math.nan)
    return torch.where(both, px, nan), torch.where(both, vw, nan)


def summary_stats(x: torch.Tensor, prefix: str) -> dict[str, float]:
    x = x[torch.isfinite(x)]
    if x.numel() == 0:
        return {f"{prefix}_{s}": math.nan for s in ("mean", "median", "p95", "max")}
    return {f"{prefix}_mean": float(x.mean()), f"{prefix}_median": float(x.median()),
            f"{prefix}_p95": float(torch.quantile(x, 0.95)), f"{prefix}_max": float(x.max())}


def hit_error(result: Any, truth: Any, mask: Optional[torch.Tensor] = None) -> dict[str, float]:
    """Hit-position error statistics over the pixels of ``mask`` where both the pass and the truth hit.

    Use ``mask = torch.isin(classes, (CORRECT, FALSE_HIT, MISPLACED_HIT, PUNCH_THROUGH))`` for the
    correct-and-wrong-hit pairs, or ``classes == CORRECT`` for the precision of the correct hits.

    Returns:
        ``n`` (pixel count, float) and ``px_{mean,median,p95,max}`` (pixels), ``view_{mean,median,p95,max}``
        (view units); ``nan`` statistics when ``n`` is 0.

    Example:
        >>> from types import SimpleNamespace as NS
        >>> one = torch.ones(1, 1, 1, 2, dtype=torch.bool)
        >>> truth = NS(valid=one, hit=one, on_screen=one, visible=one, back_face=~one,
        ...            hit_pixel=torch.zeros(1, 2, 1, 2), hit_view=torch.zeros(1, 3, 1, 2))
        >>> ssr = NS(hit=one, hit_pixel=torch.tensor([[3.0, 0.0], [4.0, 0.0]]).view(1, 2, 1, 2),
        ...          hit_view=torch.tensor([[0.0, 0.0], [0.0, 2.0], [0.0, 0.0]]).view(1, 3, 1, 2))
        >>> e = hit_error(ssr, truth)
        >>> e["n"], e["px_mean"], e["px_max"], e["view_mean"]
        (2.0, 2.5, 5.0, 1.0)
    """
    px, vw = hit_error_maps(result, truth)
    m = torch.isfinite(px)
    if mask is not None:
        m = m & mask_arg(mask, px, "mask")
    out = {"n": float(m.sum())}
    out.update(summary_stats(px[m], "px"))
    out.update(summary_stats(vw[m], "view"))
    return out


# ------------------------------------------------------------------------------------------ colour error
def color_error(result: Any, truth: Any, mask: Optional[torch.Tensor] = None, *, flip: bool = True,
                max_val: float = 1.0) -> dict[str, float]:
    r"""Reflection colour error against the path-traced radiance along the mirror ray, faded vs raw.

    ``result.color`` (fades applied) and ``result.raw_color`` (no fades) are each compared with
    ``truth.radiance`` on ``mask`` (default ``truth.valid``): MAE, RMSE, PSNR (``max_val``, linear radiance)
    and ꟻLIP (``inputs_srgb=False``: linear values, clamped to [0, 1]). Where the pass has no hit its colour
    is 0, so a miss costs the full radiance, as it would with no fallback probe.

    Returns:
        ``{mae,rmse,psnr,flip}_{faded,raw}`` floats (``flip_*`` ``nan`` with ``flip=False``).
    """
    from . import image
    rad = getattr(truth, "radiance", None)
    col, raw = getattr(result, "color", None), getattr(result, "raw_color", None)
    for name, t in (("truth.radiance", rad), ("result.color", col), ("result.raw_color", raw)):
        if not isinstance(t, torch.Tensor):
            raise TypeError(f"{name}: expected a torch.Tensor, got {type(t).__name__}")
        checks.check_shape(t, ["B", "3", "H", "W"], name)
    if mask is None:
        mask = truth.valid.bool()
    mask = mask_arg(mask, rad, "mask")
    target = rad.float()
    out: dict[str, float] = {}
    for suffix, pred in (("faded", col), ("raw", raw)):
        p = pred.detach().float()
        if p.shape != target.shape:
            raise ValueError(f"result: colour shape {tuple(p.shape)} differs from truth.radiance "
                             f"{tuple(target.shape)}")
        out[f"mae_{suffix}"] = float(image.mae(p, target, mask))
        out[f"rmse_{suffix}"] = float(image.rmse(p, target, mask))
        out[f"psnr_{suffix}"] = float(image.psnr(p, target, mask, max_val=max_val))
        out[f"flip_{suffix}"] = float(image.flip(p, target, mask, inputs_srgb=False)) if flip else math.nan
    return out


def color_error_map(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Per-pixel mean absolute RGB error :math:`(B, 1, H, W)` (for error images)."""
    checks.check_shape(pred, ["B", "3", "H", "W"], "pred")
    checks.check_same_size(pred, target, "pred", "target")
    return (pred.float() - target.float()).abs().mean(1, keepdim=True)
