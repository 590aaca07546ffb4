"""SSR metrics: per-pixel classification of a screen-space reflection pass against the exact mirror reflection,
summary metrics and pictures. This module is the public import path; the code lives in:

* :mod:`ssbench.metrics.ssr_classify` — :func:`classify` (every pixel gets exactly one label, SSR article §4,
  Figs. 14–16) and :func:`truth_classes` (the labels of a perfect screen-space pass).
  Its module docstring holds the table defining each class and the precedence of the three target labels;
* :mod:`ssbench.metrics.ssr_classes` — the class codes (:data:`NOT_REFLECTIVE`, :data:`CORRECT`,
  :data:`MISSED`, :data:`FALSE_HIT`, :data:`PUNCH_THROUGH`, :data:`OFF_SCREEN_TARGET`, :data:`OCCLUDED_TARGET`,
  :data:`BACK_FACE_TARGET`, :data:`TRUE_MISS`, :data:`MISPLACED_HIT`, :data:`UNFIXABLE_HIT`), :data:`CLASS_NAMES`, :data:`CLASS_LABELS`,
  :data:`CLASS_DESCRIPTIONS`, :data:`CLASS_COLORS`, :data:`UNFIXABLE`, and the pictures: :func:`class_rgb`,
  :func:`legend_entries`, :func:`legend_handles`;
* :mod:`ssbench.metrics.ssr_scores` — metrics: :func:`class_counts`, :func:`class_fractions`,
  :func:`hit_error` and :func:`hit_error_maps` (pixels and view units over the pixels where both hit),
  :func:`color_error` (MAE, RMSE, PSNR, ꟻLIP of the faded and the raw reflection colour against the
  path-traced radiance along the mirror ray, via :mod:`ssbench.metrics.image`), :func:`color_error_map`,
  :func:`termination_fractions`;
* :mod:`ssbench.metrics._ssr_checks` — the shared argument checks (private).

The ground truth is used duck-typed: any object with the ``ReflectionReference`` fields works (tests use
stubs). Bad input raises ``ValueError``/``TypeError`` naming the argument.
"""
from __future__ import annotations

# private helpers are re-exported too: callers reach some of them through this module (e.g. ``ssr.k_px_arg``)
from ._ssr_checks import (RESULT_FIELDS, TRUTH_FIELDS, check_classes, check_pair, field_of, k_px_arg,  # noqa: F401
                          mask_arg)
from .ssr_classes import (BACK_FACE_TARGET, CLASS_COLORS, CLASS_DESCRIPTIONS, CLASS_LABELS, CLASS_NAMES, CORRECT,
                          FALSE_HIT, MISSED, NOT_REFLECTIVE, OCCLUDED_TARGET, OFF_SCREEN_TARGET, PUNCH_THROUGH,
                          TRUE_MISS, UNFIXABLE, MISPLACED_HIT, UNFIXABLE_HIT, WRONG_OUTPUT, hex_colour,  # noqa: F401
                          class_rgb, legend_entries, legend_handles)
from .ssr_classify import behind_origin, ray_origin, shape_at, target_masks, valid_pixels, classify, truth_classes  # noqa: F401
from .ssr_scores import (summary_stats, class_counts, class_fractions, color_error, color_error_map,  # noqa: F401
                         hit_error, hit_error_maps, termination_fractions)

__all__ = ["classify", "truth_classes", "class_fractions", "class_counts", "hit_error", "hit_error_maps",
           "color_error", "color_error_map", "termination_fractions", "class_rgb", "legend_entries",
           "legend_handles", "NOT_REFLECTIVE", "CORRECT", "MISSED", "FALSE_HIT", "PUNCH_THROUGH",
           "OFF_SCREEN_TARGET", "OCCLUDED_TARGET", "BACK_FACE_TARGET", "TRUE_MISS", "CLASS_NAMES",
           "CLASS_LABELS", "CLASS_DESCRIPTIONS", "CLASS_COLORS", "UNFIXABLE", "MISPLACED_HIT", "UNFIXABLE_HIT",
           "WRONG_OUTPUT"]
