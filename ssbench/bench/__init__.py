"""Sweeps, trustworthy timing and executors: turn evaluation rows (``ssbench.evaluate``) into data sets.

* :mod:`~ssbench.bench.config` — a sweep file (YAML/TOML) → a validated :class:`Sweep` of :class:`Config`
  (grid forms and type coercion in :mod:`~ssbench.bench.grids`);
* :mod:`~ssbench.bench.sweep` — :func:`run_sweep` (resumable, one atomic row per configuration) and
  :func:`run_config`;
* :mod:`~ssbench.bench.rows` — the row store, run metadata, volatile fields;
* :mod:`~ssbench.bench.timing` — timing in interleaved rounds with the gather floor (median, IQR, floor ratio);
* :mod:`~ssbench.bench.executors` — local and Dask executors;
* :mod:`~ssbench.bench.effects` — the effect registry (``ao``, ``ssr``; one entry per effect);
* :mod:`~ssbench.cli._sweep_cmd` — ``ssbench sweep``.
"""
from __future__ import annotations

from .config import Config, Sweep, SweepError, load_sweep, parse_sweep, sweep_from_dict
from .effects import EFFECTS, Effect, get_effect
from .rows import canonical_json, is_volatile, stable
from .rowstore import RowStore
from .sweep import SweepResult, run_config, run_sweep
from .timing import TimingSpec, agree, time_pass

__all__ = ["Config", "Sweep", "SweepError", "load_sweep", "parse_sweep", "sweep_from_dict", "EFFECTS", "Effect",
           "get_effect", "RowStore", "canonical_json", "is_volatile", "stable", "SweepResult", "run_config",
           "run_sweep", "TimingSpec", "agree", "time_pass"]
