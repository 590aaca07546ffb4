"""The SSR pixel classes: codes, keys, labels, one-line descriptions, fixed colours, and the pictures drawn
from them (class maps and legends).

The definition of each class, and how :func:`~ssbench.metrics.ssr_classify.classify` assigns them, is in the
docstring of :mod:`ssbench.metrics.ssr_classify`. Public import path: :mod:`ssbench.metrics.ssr`.
"""
from __future__ import annotations

import numpy as np
import torch

from ._ssr_checks import check_classes

__all__ = ["NOT_REFLECTIVE", "CORRECT", "MISSED", "FALSE_HIT", "PUNCH_THROUGH", "OFF_SCREEN_TARGET",
           "OCCLUDED_TARGET", "BACK_FACE_TARGET", "TRUE_MISS", "MISPLACED_HIT", "UNFIXABLE_HIT", "WRONG_OUTPUT",
           "CLASS_NAMES", "CLASS_LABELS",
           "CLASS_DESCRIPTIONS", "CLASS_COLORS", "UNFIXABLE", "class_rgb", "legend_entries", "legend_handles"]

NOT_REFLECTIVE = 0     #: no mirror ray (background / not reflective)
CORRECT = 1            #: pass hit within k px of the visible true hit
MISSED = 2             #: visible true hit, pass found nothing
FALSE_HIT = 3          #: pass hit on the wrong surface (another shape than the true hit's), or where the truth misses
PUNCH_THROUGH = 4      #: pass hit behind the visible true hit (passed a thin occluder)
OFF_SCREEN_TARGET = 5  #: true hit outside the screen / frustum
OCCLUDED_TARGET = 6    #: true hit hidden from the camera
BACK_FACE_TARGET = 7   #: true hit on a back face
TRUE_MISS = 8          #: truth and pass both miss
MISPLACED_HIT = 9      #: pass hit on the right surface (the true hit's shape), but > k px from the true hit
UNFIXABLE_HIT = 10     #: unfixable target (off-screen, occluded, back-face) and the pass still returned a hit

#: code → short key (row keys, file names)
CLASS_NAMES: dict[int, str] = {NOT_REFLECTIVE: "not_reflective", CORRECT: "correct", MISSED: "missed",
                               FALSE_HIT: "false_hit", PUNCH_THROUGH: "punch_through",
                               OFF_SCREEN_TARGET: "off_screen_target", OCCLUDED_TARGET: "occluded_target",
                               BACK_FACE_TARGET: "back_face_target", TRUE_MISS: "true_miss",
                               MISPLACED_HIT: "misplaced_hit", UNFIXABLE_HIT: "unfixable_hit"}
#: code → human label
CLASS_LABELS: dict[int, str] = {NOT_REFLECTIVE: "not reflective", CORRECT: "correct hit", MISSED: "missed hit",
                                FALSE_HIT: "false hit", PUNCH_THROUGH: "punch-through",
                                OFF_SCREEN_TARGET: "off-screen target", OCCLUDED_TARGET: "occluded target",
                                BACK_FACE_TARGET: "back-face target", TRUE_MISS: "true miss",
                                MISPLACED_HIT: "misplaced hit", UNFIXABLE_HIT: "hit on unfixable target"}
#: code → one-line definition (legends, report)
CLASS_DESCRIPTIONS: dict[int, str] = {
    NOT_REFLECTIVE: "background: no mirror ray",
    CORRECT: "pass hit within k px of the visible true hit",
    MISSED: "true hit visible on screen, pass found nothing",
    FALSE_HIT: "pass hit on the wrong surface (another shape than the true hit's), or where the truth misses",
    PUNCH_THROUGH: "pass hit behind the true hit: it passed the thin occluder the truth hit",
    OFF_SCREEN_TARGET: "true hit outside the screen or frustum (no screen-space fix)",
    OCCLUDED_TARGET: "true hit hidden from the camera by another surface (no screen-space fix)",
    BACK_FACE_TARGET: "true hit on a surface facing away from the camera (no screen-space fix)",
    TRUE_MISS: "truth and pass both miss (sky)",
    MISPLACED_HIT: "pass hit on the right surface (the true hit's shape) but more than k px from the true hit",
    UNFIXABLE_HIT: "target off-screen, occluded or back-facing, yet the pass returned a hit: a wrong colour",
}
#: code → linear-free display RGB in [0, 1] (fixed across figures)
CLASS_COLORS: dict[int, tuple[float, float, float]] = {
    NOT_REFLECTIVE: (0.0, 0.0, 0.0), CORRECT: (0.16, 0.70, 0.27), MISSED: (0.20, 0.45, 0.95),
    FALSE_HIT: (0.89, 0.12, 0.12), PUNCH_THROUGH: (0.92, 0.25, 0.86), OFF_SCREEN_TARGET: (0.98, 0.84, 0.12),
    OCCLUDED_TARGET: (0.98, 0.52, 0.05), BACK_FACE_TARGET: (0.10, 0.80, 0.82), TRUE_MISS: (0.50, 0.50, 0.50),
    MISPLACED_HIT: (0.99, 0.62, 0.56), UNFIXABLE_HIT: (0.50, 0.05, 0.25)}
#: the three labels no screen-space method can fix (SSR article §4)
UNFIXABLE = (OFF_SCREEN_TARGET, OCCLUDED_TARGET, BACK_FACE_TARGET)
#: the classes where the pass returned a colour that is wrong (what a user sees as a bad reflection)
WRONG_OUTPUT = (FALSE_HIT, MISPLACED_HIT, PUNCH_THROUGH, UNFIXABLE_HIT)


# ------------------------------------------------------------------------------------------ pictures
def hex_colour(rgb) -> str:
    return "#" + "".join(f"{int(round(255 * c)):02x}" for c in rgb)


def class_rgb(classes: torch.Tensor, index: int = 0) -> np.ndarray:
    """``(H, W, 3)`` uint8 class map of batch item ``index`` in :data:`CLASS_COLORS`."""
    check_classes(classes)
    c = classes[index, 0].cpu().numpy().astype(np.int64)
    lut = np.zeros((max(CLASS_COLORS) + 1, 3))
    for code, rgb in CLASS_COLORS.items():
        lut[code] = rgb
    rgb = lut[np.clip(c, 0, len(lut) - 1)]
    return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)


def legend_entries(codes=None) -> list[dict]:
    """Legend rows ``{"code", "key", "label", "color" (hex), "description"}`` for ``codes`` (default: all)."""
    codes = list(CLASS_NAMES) if codes is None else list(codes)
    unknown = [c for c in codes if c not in CLASS_NAMES]
    if unknown:
        raise ValueError(f"codes: unknown class code(s) {unknown}; known: {sorted(CLASS_NAMES)}")
    return [{"code": c, "key": CLASS_NAMES[c], "label": CLASS_LABELS[c], "color": hex_colour(CLASS_COLORS[c]),
             "description": CLASS_DESCRIPTIONS[c]} for c in codes]


def legend_handles(codes=None) -> list:
    """``matplotlib.patches.Patch`` handles for ``ax.legend(handles=...)`` (default: all classes)."""
    from matplotlib.patches import Patch
    return [Patch(facecolor=e["color"], edgecolor="none", label=e["label"]) for e in legend_entries(codes)]
