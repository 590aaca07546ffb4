"""Fair comparison by tuning: fit each AO method's continuous parameters to a fixed ray-traced ground truth on
training scenes, then report default vs tuned error on held-out scenes (XeGTAO's auto-tune protocol: fit to
ray-traced AO, then compare; ``ssbench/REFERENCES.md``).

* :mod:`ssbench.tune.space` — which parameters are tunable (:data:`SPACES`; with a blur also its ``blur_*`` ones,
  :data:`BLUR_SPACES`), their ranges, the baseline;
* :mod:`ssbench.tune.core` — the cases (G-buffer + ground truth, computed once) and the :class:`Objective`
  (mean RMSE, budget rejection, history);
* :mod:`ssbench.tune.grid` — grid narrowing (:func:`grid_narrow`);
* :mod:`ssbench.tune.gradient` — autograd probing and Adam steps through the torch pass;
* :mod:`ssbench.tune.tuner` — :func:`tune`, the whole procedure;
* :mod:`ssbench.cli._tune_cmd` — ``ssbench tune METHOD ...``.
"""
from __future__ import annotations

from .core import Case, Objective, apply_blur, median_timer, prepare_cases
from .gradient import RefineResult, inject, probe, refine
from .grid import GridResult, grid_narrow
from .space import BLUR_DEFAULTS, BLUR_SPACES, SPACES, Tunable, baseline, resolve_space, tunable_names
from .tuner import WEIGHTINGS, TuneResult, tune

__all__ = ["tune", "TuneResult", "WEIGHTINGS", "SPACES", "BLUR_SPACES", "BLUR_DEFAULTS", "apply_blur", "Tunable", "tunable_names", "resolve_space", "baseline",
           "Case", "prepare_cases", "Objective", "median_timer", "grid_narrow", "GridResult", "inject", "probe",
           "refine", "RefineResult"]
