"""Analyses of sweep rows (:mod:`ssbench.bench`): speed against error.

* :mod:`~ssbench.analysis.pareto` — Pareto fronts of error vs time (NaN and error rows left out, ties kept);
* :mod:`~ssbench.analysis.equal_error` — equal-error cost: the ground-truth rays / samples / steps that reach a
  method's error, and their time;
* :mod:`~ssbench.analysis.multiples` — artifact-vs-parameter small multiples;
* :mod:`~ssbench.analysis.figures` — error-vs-time scatter with the front drawn.

Importing this package imports neither Mitsuba nor matplotlib; the functions that need them import them.
"""
from __future__ import annotations

from .equal_error import EqualError, Ladder, ao_ladder, best_rows, equal_error_n, equal_error_table, \
    implicit_ladder, ssr_ladder
from .figures import error_time_figure
from .multiples import Panel, config_text, panel_lines, small_multiples, varying_keys
from .pareto import dominates, pareto_mask, pareto_rows, row_time_ms, row_value

__all__ = ["pareto_mask", "pareto_rows", "dominates", "row_time_ms", "row_value", "EqualError", "Ladder",
           "equal_error_n", "ao_ladder", "ssr_ladder", "implicit_ladder", "best_rows", "equal_error_table",
           "Panel", "panel_lines", "small_multiples", "varying_keys", "config_text", "error_time_figure"]
