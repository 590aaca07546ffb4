r"""Per-pixel classification of an SSR pass against the exact mirror reflection, and SSR metrics.

A screen-space reflection pass (:class:`~ssbench.passes.ssr_common.SSRResult`) reports, per pixel, whether its
march found a hit and where (``hit``, ``hit_pixel``, ``hit_view``). The ground truth
(``ssbench.reference.reflections`` → ``ReflectionReference``) traces the exact mirror ray of the same pixel
in the full scene and says where it really lands and whether a depth buffer *could* hold that point
(``on_screen``, ``visible``, ``back_face``). :func:`classify` compares the two and gives every pixel exactly
one label (seed 000 §4, Figs. 14–16; ``ssr_anchors.md`` (e)):

============================ ==== ==========================================================================
class                        code definition (``k`` = ``k_px``; the pass hit is the *raw* hit, before fades)
============================ ==== ==========================================================================
:data:`NOT_REFLECTIVE`       0    no mirror ray: background (``truth.valid`` False, ``gbuffer.mask`` False) or
                                  outside the optional ``reflective`` mask.
:data:`CORRECT`              1    visible target (below) and the pass hit within ``k`` px of the true hit
                                  pixel: :math:`\lVert \hat p - p \rVert_2 \le k`.
:data:`MISSED`               2    visible target and the pass found nothing (no hit, whatever the
                                  termination: off screen, max distance, out of steps, behind camera).
:data:`FALSE_HIT`            3    the pass hit but the truth misses everything, or the truth has a visible
                                  target and the pass hit more than ``k`` px away (and it is no punch-through).
:data:`PUNCH_THROUGH`        4    visible target, the pass hit more than ``k`` px away *behind* the true hit
                                  along the ray (:math:`\hat t > t`, projected on the true ray direction)
                                  and, when ``gbuffer.shape_id`` is available, on another shape than the one
                                  the truth hit: the march passed the thin occluder the truth hit.
:data:`OFF_SCREEN_TARGET`    5    the truth hits a point outside the image or outside the near/far planes
                                  (``~on_screen``; Fig. 14).
:data:`OCCLUDED_TARGET`      6    the truth hits an on-screen, front-facing point that the camera cannot see
                                  (``~visible``: another surface is in front of it in the depth buffer; Fig. 16).
:data:`BACK_FACE_TARGET`     7    the truth hits an on-screen point of a surface facing away from the camera
                                  (``back_face``; Fig. 15): a depth buffer never holds it, even when visible.
:data:`TRUE_MISS`            8    the truth misses all geometry and so does the pass.
============================ ==== ==========================================================================

A *visible target* is ``truth.hit & on_screen & ~back_face & visible``. The three **target** labels
(off-screen, back-face, occluded; checked in that order) take precedence over the pass's outcome: no
screen-space method can fix them (seed 000 §4). Whether the pass still produced a hit there (which can only
be a wrong one) is kept apart: :func:`class_fractions` reports ``<class>_pass_hit`` and :func:`class_rgb`
stipples those pixels.

Metrics: :func:`class_fractions`, :func:`hit_error` (pixels and view units over the pixels where both hit),
:func:`color_error` (MAE, RMSE, PSNR, ꟻLIP of the faded and the raw reflection colour against the path-traced
radiance along the mirror ray, via :mod:`ssbench.metrics.image`), :func:`termination_fractions`.
Pictures: :data:`CLASS_COLORS`, :func:`class_rgb`, :func:`legend_entries`, :func:`legend_handles`.

The ground truth is used duck-typed: any object with the ``ReflectionReference`` fields works (tests use
stubs). Bad input raises ``ValueError``/``TypeError`` naming the argument.
"""
from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np
import torch

from .. import checks

__all__ = ["classify", "truth_classes", "class_fractions", "class_counts", "hit_error", "hit_error_maps",
           "color_error", "color_error_map", "termination_fractions", "class_rgb", "legend_entries",
           "legend_handles", "NOT_REFLECTIVE", "CORRECT", "MISSED", "FALSE_HIT", "PUNCH_THROUGH",
           "OFF_SCREEN_TARGET", "OCCLUDED_TARGET", "BACK_FACE_TARGET", "TRUE_MISS", "CLASS_NAMES",
           "CLASS_LABELS", "CLASS_DESCRIPTIONS", "CLASS_COLORS", "UNFIXABLE"]

NOT_REFLECTIVE = 0     #: no mirror ray (background / not reflective)
CORRECT = 1            #: pass hit within k px of the visible true hit
MISSED = 2             #: visible true hit, pass found nothing
FALSE_HIT = 3          #: pass hit where the truth misses, or > k px from the visible true hit
PUNCH_THROUGH = 4      #: pass hit behind the visible true hit (passed a thin occluder)
OFF_SCREEN_TARGET = 5  #: true hit outside the screen / frustum
OCCLUDED_TARGET = 6    #: true hit hidden from the camera
BACK_FACE_TARGET = 7   #: true hit on a back face
TRUE_MISS = 8          #: truth and pass both miss

#: code → short key (row keys, file names)
CLASS_NAMES: dict[int, str] = {NOT_REFLECTIVE: "not_reflective", CORRECT: "correct", MISSED: "missed",
                               FALSE_HIT: "false_hit", PUNCH_THROUGH: "punch_through",
                               OFF_SCREEN_TARGET: "off_screen_target", OCCLUDED_TARGET: "occluded_target",
                               BACK_FACE_TARGET: "back_face_target", TRUE_MISS: "true_miss"}
#: code → human label
CLASS_LABELS: dict[int, str] = {NOT_REFLECTIVE: "not reflective", CORRECT: "correct hit", MISSED: "missed hit",
                                FALSE_HIT: "false hit", PUNCH_THROUGH: "punch-through",
                                OFF_SCREEN_TARGET: "off-screen target", OCCLUDED_TARGET: "occluded target",
                                BACK_FACE_TARGET: "back-face target", TRUE_MISS: "true miss"}
#: code → one-line definition (legends, report)
CLASS_DESCRIPTIONS: dict[int, str] = {
    NOT_REFLECTIVE: "background: no mirror ray",
    CORRECT: "pass hit within k px of the visible true hit",
    MISSED: "true hit visible on screen, pass found nothing",
    FALSE_HIT: "pass hit where the truth misses, or more than k px from the true hit",
    PUNCH_THROUGH: "pass hit behind the true hit: it passed the thin occluder the truth hit",
    OFF_SCREEN_TARGET: "true hit outside the screen or frustum (no screen-space fix)",
    OCCLUDED_TARGET: "true hit hidden from the camera by another surface (no screen-space fix)",
    BACK_FACE_TARGET: "true hit on a surface facing away from the camera (no screen-space fix)",
    TRUE_MISS: "truth and pass both miss (sky)",
}
#: code → linear-free display RGB in [0, 1] (fixed across figures)
CLASS_COLORS: dict[int, tuple[float, float, float]] = {
    NOT_REFLECTIVE: (0.0, 0.0, 0.0), CORRECT: (0.16, 0.70, 0.27), MISSED: (0.20, 0.45, 0.95),
    FALSE_HIT: (0.89, 0.12, 0.12), PUNCH_THROUGH: (0.92, 0.25, 0.86), OFF_SCREEN_TARGET: (0.98, 0.84, 0.12),
    OCCLUDED_TARGET: (0.98, 0.52, 0.05), BACK_FACE_TARGET: (0.10, 0.80, 0.82), TRUE_MISS: (0.50, 0.50, 0.50)}
#: the three labels no screen-space method can fix (seed 000 §4)
UNFIXABLE = (OFF_SCREEN_TARGET, OCCLUDED_TARGET, BACK_FACE_TARGET)

_RESULT_FIELDS = {"hit": 1, "hit_pixel": 2, "hit_view": 3}
_TRUTH_FIELDS = {"valid": 1, "hit": 1, "hit_view": 3, "hit_pixel": 2, "on_screen": 1, "visible": 1, "back_face": 1}


# ------------------------------------------------------------------------------------------ checks
def _field(obj: Any, name: str, arg: str, channels: int, like: Optional[torch.Tensor] = None) -> torch.Tensor:
    t = getattr(obj, name, None)
    if not isinstance(t, torch.Tensor):
        raise TypeError(f"{arg}.{name}: expected a torch.Tensor, got {type(t).__name__}")
    checks.check_shape(t, ["B", str(channels), "H", "W"], f"{arg}.{name}")
    if like is not None and (t.shape[0] != like.shape[0] or t.shape[-2:] != like.shape[-2:]):
        raise ValueError(f"{arg}.{name}: batch and image size must match result.hit {tuple(like.shape)}, "
                         f"got {tuple(t.shape)}")
    return t


def _mask_arg(m: Optional[torch.Tensor], like: torch.Tensor, name: str) -> Optional[torch.Tensor]:
    if m is None:
        return None
    if not isinstance(m, torch.Tensor):
        raise TypeError(f"{name}: expected a torch.Tensor, got {type(m).__name__}")
    checks.check_shape(m, ["B", "1", "H", "W"], name)
    if m.dtype != torch.bool:
        raise TypeError(f"{name}: expected dtype torch.bool, got {m.dtype}")
    if m.shape[0] != like.shape[0] or m.shape[-2:] != like.shape[-2:]:
        raise ValueError(f"{name}: batch and image size must match {tuple(like.shape)}, got {tuple(m.shape)}")
    return m


def _check_pair(result: Any, truth: Any) -> torch.Tensor:
    hit = _field(result, "hit", "result", 1)
    for n, c in _RESULT_FIELDS.items():
        _field(result, n, "result", c, hit)
    for n, c in _TRUTH_FIELDS.items():
        _field(truth, n, "truth", c, hit)
    return hit


def _k(k_px) -> float:
    if isinstance(k_px, bool) or not isinstance(k_px, (int, float)) or not (math.isfinite(k_px) and k_px > 0):
        raise ValueError(f"k_px: must be a finite number > 0, got {k_px!r}")
    return float(k_px)


def _origin(gbuffer, like: torch.Tensor) -> torch.Tensor:
    """View-space ray origins ``(B, 3, H, W)`` float64 from ``gbuffer.position`` (or ``view_z``)."""
    if gbuffer is None:
        raise ValueError("gbuffer: classify needs the G-buffer (position or view_z) to tell a punch-through "
                         "(the pass's hit behind the true hit along the ray)")
    pos = getattr(gbuffer, "position", None)
    if pos is None and getattr(gbuffer, "view_z", None) is not None:
        cam = gbuffer.camera
        pos = cam.uv_to_view(cam.uv_grid(torch.float64, gbuffer.view_z.device)[None], gbuffer.view_z.double())
    if pos is None:
        raise ValueError("gbuffer: missing channel(s) position (or view_z); classify needs the ray origins")
    if pos.shape[0] != like.shape[0] or pos.shape[-2:] != like.shape[-2:]:
        raise ValueError(f"gbuffer: batch and image size must match result.hit {tuple(like.shape)}, "
                         f"got {tuple(pos.shape)}")
    return pos.double()


def _shape_at(shape_id: torch.Tensor, pixel: torch.Tensor) -> torch.Tensor:
    """``shape_id`` at the pixel containing ``pixel`` (continuous ``(px, py)``, clamped to the image)."""
    B, _, H, W = shape_id.shape
    px = torch.nan_to_num(pixel[:, 0].double(), nan=-1.0).floor().clamp(0, W - 1).long()
    py = torch.nan_to_num(pixel[:, 1].double(), nan=-1.0).floor().clamp(0, H - 1).long()
    flat = shape_id.reshape(B, H * W).long()
    return flat.gather(1, (py * W + px).reshape(B, -1)).reshape(B, 1, H, W)


# ------------------------------------------------------------------------------------------ classes
def _target_masks(truth: Any, valid: torch.Tensor) -> dict[int, torch.Tensor]:
    th = truth.hit.bool() & valid
    on = truth.on_screen.bool()
    back = truth.back_face.bool()
    vis = truth.visible.bool()
    return {OFF_SCREEN_TARGET: th & ~on, BACK_FACE_TARGET: th & on & back,
            OCCLUDED_TARGET: th & on & ~back & ~vis, -1: th & on & ~back & vis, -2: valid & ~th}


def _valid(truth: Any, gbuffer, reflective: Optional[torch.Tensor], like: torch.Tensor) -> torch.Tensor:
    valid = truth.valid.bool()
    mask = getattr(gbuffer, "mask", None) if gbuffer is not None else None
    if mask is not None:
        valid = valid & _mask_arg(mask, like, "gbuffer.mask")
    if reflective is not None:
        valid = valid & _mask_arg(reflective, like, "reflective")
    return valid


def classify(result: Any, truth: Any, gbuffer=None, k_px: float = 1.5, *,
             reflective: Optional[torch.Tensor] = None) -> tuple[torch.Tensor, dict[int, str]]:
    r"""Label every pixel of an SSR pass against the exact mirror reflection (see the module docstring).

    Args:
        result: the pass's :class:`~ssbench.passes.ssr_common.SSRResult`; its *raw* ``hit``, ``hit_pixel``
            and ``hit_view`` are compared (fades play no part).
        truth: a ``ReflectionReference`` (``valid``, ``hit``, ``hit_view``, ``hit_pixel``, ``on_screen``,
            ``visible``, ``back_face``, optionally ``hit_shape``) of the same size.
        gbuffer: the G-buffer the pass read: ``position`` (or ``view_z``) gives the ray origins for the
            punch-through test; ``shape_id`` (optional) sharpens it; ``mask`` (optional) limits the pixels.
        k_px: hit-pixel tolerance :math:`k` in pixels for :data:`CORRECT`.
        reflective: optional :math:`(B, 1, H, W)` bool: only these pixels are reflective (e.g. the pixels a
            pass marches); the others become :data:`NOT_REFLECTIVE`.

    Returns:
        ``(classes, names)``: :math:`(B, 1, H, W)` int8 codes and :data:`CLASS_NAMES` (code → key).

    Example:
        >>> from types import SimpleNamespace as NS
        >>> b = lambda *v: torch.tensor(v).view(1, 1, 1, -1)
        >>> px = torch.tensor([[5.0, 5.0], [5.0, 5.0], [9.0, 5.0]]).T.reshape(1, 2, 1, 3)
        >>> truth = NS(valid=b(True, True, True), hit=b(True, True, True), on_screen=b(True, True, True),
        ...            visible=b(True, True, True), back_face=b(False, False, False), hit_pixel=px.clone(),
        ...            hit_view=torch.zeros(1, 3, 1, 3))
        >>> ssr = NS(hit=b(True, False, True), hit_pixel=torch.full((1, 2, 1, 3), 5.0),
        ...          hit_view=torch.zeros(1, 3, 1, 3))
        >>> gb = NS(position=torch.zeros(1, 3, 1, 3), mask=None, shape_id=None)
        >>> classes, names = classify(ssr, truth, gb)
        >>> [names[int(c)] for c in classes.flatten()]
        ['correct', 'missed', 'false_hit']
    """
    hit = _check_pair(result, truth)
    k = _k(k_px)
    valid = _valid(truth, gbuffer, reflective, hit)
    t = _target_masks(truth, valid)
    target, truth_miss = t[-1], t[-2]
    ph = result.hit.bool() & valid
    d_px = (result.hit_pixel.double() - truth.hit_pixel.double()).norm(dim=1, keepdim=True)
    near = torch.nan_to_num(d_px, nan=math.inf) <= k                       # NaN never counts as close
    wrong = target & ph & ~near
    punch = wrong & _behind(result, truth, gbuffer, hit, wrong)

    classes = torch.zeros_like(hit, dtype=torch.int8)                      # NOT_REFLECTIVE
    for code, m in ((TRUE_MISS, truth_miss & ~ph), (FALSE_HIT, truth_miss & ph), (FALSE_HIT, wrong & ~punch),
                    (PUNCH_THROUGH, punch), (MISSED, target & ~ph), (CORRECT, target & ph & near),
                    (OFF_SCREEN_TARGET, t[OFF_SCREEN_TARGET]), (OCCLUDED_TARGET, t[OCCLUDED_TARGET]),
                    (BACK_FACE_TARGET, t[BACK_FACE_TARGET])):
        classes[m] = code
    return classes, dict(CLASS_NAMES)


def _behind(result: Any, truth: Any, gbuffer, like: torch.Tensor, where: torch.Tensor) -> torch.Tensor:
    r"""The pass's hit lies farther along the true ray than the true hit (and on another shape, when known).

    With origin :math:`P`, true hit :math:`X` and pass hit :math:`\hat X`:
    :math:`t = \lVert X - P\rVert`, :math:`\hat t = (\hat X - P)\cdot (X - P)/t`; behind means :math:`\hat t > t`.
    """
    if not bool(where.any()):
        return torch.zeros_like(where)
    P = _origin(gbuffer, like)
    X, Xh = truth.hit_view.double(), result.hit_view.double()
    t = (X - P).norm(dim=1, keepdim=True)
    d = (X - P) / t.clamp_min(1e-300)
    th = ((Xh - P) * d).sum(1, keepdim=True)
    behind = torch.nan_to_num(th, nan=-math.inf) > t
    sid = getattr(gbuffer, "shape_id", None)
    tshape = getattr(truth, "hit_shape", None)
    if sid is not None and isinstance(tshape, torch.Tensor):
        behind = behind & (_shape_at(sid, result.hit_pixel) != tshape.long())
    return behind


def truth_classes(truth: Any, gbuffer=None, *, reflective: Optional[torch.Tensor] = None) -> torch.Tensor:
    """The classes a perfect screen-space pass would get: :data:`CORRECT` on visible targets, the three target
    labels, :data:`TRUE_MISS` and :data:`NOT_REFLECTIVE` (the report's truth hit map). :math:`(B, 1, H, W)` int8.

    Example:
        >>> from types import SimpleNamespace as NS
        >>> b = lambda *v: torch.tensor(v).view(1, 1, 1, -1)
        >>> truth = NS(valid=b(True, True, True, False), hit=b(True, True, False, False),
        ...            on_screen=b(True, False, False, False), visible=b(True, False, False, False),
        ...            back_face=b(False, False, False, False))
        >>> [CLASS_NAMES[int(c)] for c in truth_classes(truth).flatten()]
        ['correct', 'off_screen_target', 'true_miss', 'not_reflective']
    """
    for n in ("valid", "hit", "on_screen", "visible", "back_face"):
        _field(truth, n, "truth", 1, truth.valid)
    valid = _valid(truth, gbuffer, reflective, truth.valid)
    t = _target_masks(truth, valid)
    classes = torch.zeros_like(truth.valid, dtype=torch.int8)
    for code, m in ((TRUE_MISS, t[-2]), (CORRECT, t[-1]), (OFF_SCREEN_TARGET, t[OFF_SCREEN_TARGET]),
                    (OCCLUDED_TARGET, t[OCCLUDED_TARGET]), (BACK_FACE_TARGET, t[BACK_FACE_TARGET])):
        classes[m] = code
    return classes


# ------------------------------------------------------------------------------------------ fractions
def _check_classes(classes: torch.Tensor) -> None:
    checks.check_tensor(classes, "classes")
    checks.check_shape(classes, ["B", "1", "H", "W"], "classes")
    if classes.is_floating_point() or classes.dtype == torch.bool:
        raise TypeError(f"classes: expected an integer dtype, got {classes.dtype}")


def class_counts(classes: torch.Tensor) -> dict[str, int]:
    """Pixel count of every class, by key (all batch items pooled)."""
    _check_classes(classes)
    return {key: int((classes == code).sum()) for code, key in CLASS_NAMES.items()}


def class_fractions(classes: torch.Tensor, hit: Optional[torch.Tensor] = None) -> dict[str, float]:
    r"""Share of each class among the *reflective* pixels (all codes but :data:`NOT_REFLECTIVE`).

    Keys: every :data:`CLASS_NAMES` key but ``not_reflective`` (fractions of the reflective pixels, summing to
    1), ``reflective`` (share of the image that is reflective), ``reflective_pixels`` (their count, as a
    float), ``unfixable`` (the three target classes together) and, when the pass's raw ``hit`` is given,
    ``<target class>_pass_hit``: reflective share where the target is unfixable *and* the pass still
    reported a hit. Fractions are ``nan`` when no pixel is reflective.

    Example:
        >>> c = torch.tensor([0, 1, 1, 2, 5, 8], dtype=torch.int8).view(1, 1, 1, 6)
        >>> f = class_fractions(c, hit=torch.tensor([0, 1, 1, 0, 1, 0], dtype=torch.bool).view(1, 1, 1, 6))
        >>> f["correct"], f["missed"], f["unfixable"], f["off_screen_target_pass_hit"], f["reflective"]
        (0.4, 0.2, 0.2, 0.2, 0.8333333333333334)
    """
    _check_classes(classes)
    if hit is not None:
        _mask_arg(hit, classes, "hit")
    refl = classes != NOT_REFLECTIVE
    n = int(refl.sum())
    frac = (lambda m: int(m.sum()) / n) if n else (lambda m: math.nan)
    out: dict[str, float] = {key: frac(classes == code) for code, key in CLASS_NAMES.items()
                             if code != NOT_REFLECTIVE}
    out["unfixable"] = frac(refl & ((classes == OFF_SCREEN_TARGET) | (classes == OCCLUDED_TARGET)
                                    | (classes == BACK_FACE_TARGET)))
    if hit is not None:
        for code in UNFIXABLE:
            out[f"{CLASS_NAMES[code]}_pass_hit"] = frac((classes == code) & hit)
    out["reflective"] = n / classes.numel() if classes.numel() else math.nan
    out["reflective_pixels"] = float(n)
    return out


def termination_fractions(termination: torch.Tensor, mask: Optional[torch.Tensor] = None) -> dict[str, float]:
    """Share of each termination reason (``ssr_common.TERMINATION_NAMES``, spaces → ``_``) over ``mask``."""
    from ..passes.ssr_common import TERMINATION_NAMES
    checks.check_shape(termination, ["B", "1", "H", "W"], "termination")
    m = torch.ones_like(termination, dtype=torch.bool) if mask is None else _mask_arg(mask, termination, "mask")
    n = int(m.sum())
    return {name.replace(" ", "_"): (int(((termination == code) & m).sum()) / n if n else math.nan)
            for code, name in TERMINATION_NAMES.items()}


# ------------------------------------------------------------------------------------------ hit error
def hit_error_maps(result: Any, truth: Any) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Per-pixel hit error where both the pass and the truth hit, ``nan`` elsewhere.

    Returns ``(pixels, view)``, each :math:`(B, 1, H, W)` float64:
    :math:`\lVert \hat p - p\rVert_2` in pixels and :math:`\lVert \hat X - X\rVert_2` in view (scene) units.
    """
    _check_pair(result, truth)
    both = result.hit.bool() & truth.hit.bool()
    px = (result.hit_pixel.double() - truth.hit_pixel.double()).norm(dim=1, keepdim=True)
    vw = (result.hit_view.double() - truth.hit_view.double()).norm(dim=1, keepdim=True)
    nan = torch.full_like(px, math.nan)
    return torch.where(both, px, nan), torch.where(both, vw, nan)


def _stats(x: torch.Tensor, prefix: str) -> dict[str, float]:
    x = x[torch.isfinite(x)]
    if x.numel() == 0:
        return {f"{prefix}_{s}": math.nan for s in ("mean", "median", "p95", "max")}
    return {f"{prefix}_mean": float(x.mean()), f"{prefix}_median": float(x.median()),
            f"{prefix}_p95": float(torch.quantile(x, 0.95)), f"{prefix}_max": float(x.max())}


def hit_error(result: Any, truth: Any, mask: Optional[torch.Tensor] = None) -> dict[str, float]:
    """Hit-position error statistics over the pixels of ``mask`` where both the pass and the truth hit.

    Use ``mask = (classes == CORRECT) | (classes == FALSE_HIT) | (classes == PUNCH_THROUGH)`` for the
    correct-and-false-hit pairs, or ``classes == CORRECT`` for the precision of the correct hits.

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
        m = m & _mask_arg(mask, px, "mask")
    out = {"n": float(m.sum())}
    out.update(_stats(px[m], "px"))
    out.update(_stats(vw[m], "view"))
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
    mask = _mask_arg(mask, rad, "mask")
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


# ------------------------------------------------------------------------------------------ pictures
def _hex(rgb) -> str:
    return "#" + "".join(f"{int(round(255 * c)):02x}" for c in rgb)


def class_rgb(classes: torch.Tensor, hit: Optional[torch.Tensor] = None, index: int = 0) -> np.ndarray:
    """``(H, W, 3)`` uint8 class map of batch item ``index`` in :data:`CLASS_COLORS`.

    With the pass's raw ``hit``, unfixable-target pixels where the pass still reported a hit are stippled
    (every other pixel of a checkerboard mixed halfway to white).
    """
    _check_classes(classes)
    c = classes[index, 0].cpu().numpy().astype(np.int64)
    lut = np.zeros((max(CLASS_COLORS) + 1, 3))
    for code, rgb in CLASS_COLORS.items():
        lut[code] = rgb
    rgb = lut[np.clip(c, 0, len(lut) - 1)]
    if hit is not None:
        h = _mask_arg(hit, classes, "hit")[index, 0].cpu().numpy()
        yy, xx = np.indices(c.shape)
        stip = h & np.isin(c, UNFIXABLE) & ((yy + xx) % 2 == 0)
        rgb[stip] = 0.5 * rgb[stip] + 0.5
    return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)


def legend_entries(codes=None) -> list[dict]:
    """Legend rows ``{"code", "key", "label", "color" (hex), "description"}`` for ``codes`` (default: all)."""
    codes = list(CLASS_NAMES) if codes is None else list(codes)
    unknown = [c for c in codes if c not in CLASS_NAMES]
    if unknown:
        raise ValueError(f"codes: unknown class code(s) {unknown}; known: {sorted(CLASS_NAMES)}")
    return [{"code": c, "key": CLASS_NAMES[c], "label": CLASS_LABELS[c], "color": _hex(CLASS_COLORS[c]),
             "description": CLASS_DESCRIPTIONS[c]} for c in codes]


def legend_handles(codes=None) -> list:
    """``matplotlib.patches.Patch`` handles for ``ax.legend(handles=...)`` (default: all classes)."""
    from matplotlib.patches import Patch
    return [Patch(facecolor=e["color"], edgecolor="none", label=e["label"]) for e in legend_entries(codes)]
