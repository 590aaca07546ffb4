r"""Per-pixel classification of an SSR pass against the exact mirror reflection.

A screen-space reflection pass (:class:`~ssbench.passes.ssr.common.SSRResult`) reports, per pixel, whether its
march found a hit and where (``hit``, ``hit_pixel``, ``hit_view``). The ground truth
(``ssbench.reference.reflections`` → ``ReflectionReference``) traces the exact mirror ray of the same pixel
in the full scene and says where it really lands and whether a depth buffer *could* hold that point
(``on_screen``, ``visible``, ``back_face``). :func:`classify` compares the two and gives every pixel exactly
one label (SSR article §4, Figs. 14–16):

============================ ==== ==========================================================================
class                        code definition (``k`` = ``k_px``; the pass hit is the *raw* hit, before fades)
============================ ==== ==========================================================================
:data:`NOT_REFLECTIVE`       0    no mirror ray: background (``truth.valid`` False, ``gbuffer.mask`` False) or
                                  outside the optional ``reflective`` mask.
:data:`CORRECT`              1    visible target (below) and the pass hit within ``k`` px of the true hit
                                  pixel: :math:`\lVert \hat p - p \rVert_2 \le k`.
:data:`MISSED`               2    visible target and the pass found nothing (no hit, whatever the
                                  termination: off screen, max distance, out of steps, behind camera).
:data:`FALSE_HIT`            3    *wrong surface*: the pass hit but the truth misses everything, or the truth
                                  has a visible target and the pass hit more than ``k`` px away on another shape
                                  (no punch-through; without ``gbuffer.shape_id`` every far hit counts here).
:data:`MISPLACED_HIT`        9    *right surface, off by more than k px*: visible target, the pass hit the
                                  shape the truth hit (``gbuffer.shape_id`` at the pass's hit pixel equals
                                  ``truth.hit_shape``) more than ``k`` px away: a coarse stride or a missing
                                  refinement, not a wrong occluder.
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
:data:`UNFIXABLE_HIT`        10   an off-screen, back-face or occluded target (below) where the pass still
                                  returned a hit: the colour it shows is necessarily wrong.
============================ ==== ==========================================================================

A *visible target* is ``truth.hit & on_screen & ~back_face & visible``. The three **target** labels
(off-screen, back-face, occluded; checked in that order) are what no screen-space method can fix (SSR article §4):
where the pass rightly returns nothing they keep their label; where it still returns a hit — which can only be
a wrong colour — the pixel is :data:`UNFIXABLE_HIT`, an error class.
:func:`~ssbench.metrics.ssr_scores.class_fractions` splits it by target with ``targets=truth_classes(...)``.

The ground truth is used duck-typed: any object with the ``ReflectionReference`` fields works (tests use
stubs). Bad input raises ``ValueError``/``TypeError`` naming the argument.
"""
from __future__ import annotations

import math
from typing import Any, Optional

import torch

from ..rays import length
from ._ssr_checks import check_pair, field_of, k_px_arg, mask_arg
from .ssr_classes import (BACK_FACE_TARGET, CLASS_NAMES, CORRECT, FALSE_HIT, MISPLACED_HIT, MISSED,
                          OCCLUDED_TARGET, OFF_SCREEN_TARGET, PUNCH_THROUGH, TRUE_MISS, UNFIXABLE_HIT)

__all__ = ["classify", "truth_classes"]


# ------------------------------------------------------------------------------------------ geometry
def ray_origin(gbuffer, like: torch.Tensor) -> torch.Tensor:
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


def shape_at(shape_id: torch.Tensor, pixel: torch.Tensor) -> torch.Tensor:
    """``shape_id`` at the pixel containing ``pixel`` (continuous ``(px, py)``, clamped to the image)."""
    B, _, H, W = shape_id.shape
    px = torch.nan_to_num(pixel[:, 0].double(), nan=-1.0).floor().clamp(0, W - 1).long()
    py = torch.nan_to_num(pixel[:, 1].double(), nan=-1.0).floor().clamp(0, H - 1).long()
    flat = shape_id.reshape(B, H * W).long()
    return flat.gather(1, (py * W + px).reshape(B, -1)).reshape(B, 1, H, W)


# ------------------------------------------------------------------------------------------ classes
def target_masks(truth: Any, valid: torch.Tensor) -> dict[int, torch.Tensor]:
    th = truth.hit.bool() & valid
    on = truth.on_screen.bool()
    back = truth.back_face.bool()
    vis = truth.visible.bool()
    return {OFF_SCREEN_TARGET: th & ~on, BACK_FACE_TARGET: th & on & back,
            OCCLUDED_TARGET: th & on & ~back & ~vis, -1: th & on & ~back & vis, -2: valid & ~th}


def valid_pixels(truth: Any, gbuffer, reflective: Optional[torch.Tensor], like: torch.Tensor) -> torch.Tensor:
    valid = truth.valid.bool()
    mask = getattr(gbuffer, "mask", None) if gbuffer is not None else None
    if mask is not None:
        valid = valid & mask_arg(mask, like, "gbuffer.mask")
    if reflective is not None:
        valid = valid & mask_arg(reflective, like, "reflective")
    return valid


def classify(result: Any, truth: Any, gbuffer=None, k_px: float = 1.5, *,
             reflective: Optional[torch.Tensor] = None) -> tuple[torch.Tensor, dict[int, str]]:
    r"""Label every pixel of an SSR pass against the exact mirror reflection (see the module docstring).

    Args:
        result: the pass's :class:`~ssbench.passes.ssr.common.SSRResult`; its *raw* ``hit``, ``hit_pixel``
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
    hit = check_pair(result, truth)
    k = k_px_arg(k_px)
    valid = valid_pixels(truth, gbuffer, reflective, hit)
    t = target_masks(truth, valid)
    target, truth_miss = t[-1], t[-2]
    ph = result.hit.bool() & valid
    d_px = length(result.hit_pixel.double() - truth.hit_pixel.double())
    near = torch.nan_to_num(d_px, nan=math.inf) <= k                       # NaN never counts as close
    wrong = target & ph & ~near
    punch = wrong & behind_origin(result, truth, gbuffer, hit, wrong)
    misplaced = wrong & ~punch & _same_shape(result, truth, gbuffer, wrong & ~punch)
    unfixable = t[OFF_SCREEN_TARGET] | t[OCCLUDED_TARGET] | t[BACK_FACE_TARGET]

    classes = torch.zeros_like(hit, dtype=torch.int8)                      # NOT_REFLECTIVE
    for code, m in ((TRUE_MISS, truth_miss & ~ph), (FALSE_HIT, truth_miss & ph),
                    (FALSE_HIT, wrong & ~punch & ~misplaced), (MISPLACED_HIT, misplaced), (PUNCH_THROUGH, punch),
                    (MISSED, target & ~ph), (CORRECT, target & ph & near),
                    (OFF_SCREEN_TARGET, t[OFF_SCREEN_TARGET]), (OCCLUDED_TARGET, t[OCCLUDED_TARGET]),
                    (BACK_FACE_TARGET, t[BACK_FACE_TARGET]), (UNFIXABLE_HIT, unfixable & ph)):
        classes[m] = code
    return classes, dict(CLASS_NAMES)


def behind_origin(result: Any, truth: Any, gbuffer, like: torch.Tensor, where: torch.Tensor) -> torch.Tensor:
    r"""The pass's hit lies farther along the true ray than the true hit (and on another shape, when known).

    With origin :math:`P`, true hit :math:`X` and pass hit :math:`\hat X`:
    :math:`t = \lVert X - P\rVert`, :math:`\hat t = (\hat X - P)\cdot (X - P)/t`; behind means :math:`\hat t > t`.
    """
    if not bool(where.any()):
        return torch.zeros_like(where)
    P = ray_origin(gbuffer, like)
    X, Xh = truth.hit_view.double(), result.hit_view.double()
    t = length(X - P)
    d = (X - P) / t.clamp_min(1e-300)
    th = ((Xh - P) * d).sum(1, keepdim=True)
    behind = torch.nan_to_num(th, nan=-math.inf) > t
    sid = getattr(gbuffer, "shape_id", None)
    tshape = getattr(truth, "hit_shape", None)
    if sid is not None and isinstance(tshape, torch.Tensor):
        behind = behind & (shape_at(sid, result.hit_pixel) != tshape.long())
    return behind


def _same_shape(result: Any, truth: Any, gbuffer, where: torch.Tensor) -> torch.Tensor:
    """The pass's hit pixel shows the shape the truth hit (False everywhere when shape ids are unknown)."""
    sid = getattr(gbuffer, "shape_id", None) if gbuffer is not None else None
    tshape = getattr(truth, "hit_shape", None)
    if sid is None or not isinstance(tshape, torch.Tensor) or not bool(where.any()):
        return torch.zeros_like(where)
    finite = torch.isfinite(result.hit_pixel.double()).all(1, keepdim=True)
    return where & finite & (shape_at(sid, result.hit_pixel) == tshape.long())


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
        field_of(truth, n, "truth", 1, truth.valid)
    valid = valid_pixels(truth, gbuffer, reflective, truth.valid)
    t = target_masks(truth, valid)
    classes = torch.zeros_like(truth.valid, dtype=torch.int8)
    for code, m in ((TRUE_MISS, t[-2]), (CORRECT, t[-1]), (OFF_SCREEN_TARGET, t[OFF_SCREEN_TARGET]),
                    (OCCLUDED_TARGET, t[OCCLUDED_TARGET]), (BACK_FACE_TARGET, t[BACK_FACE_TARGET])):
        classes[m] = code
    return classes

