"""Run a sweep: every configuration once, each finished row stored atomically at once, resumable.

:func:`run_sweep` validates the sweep (:mod:`ssbench.bench.config`), skips the configurations whose row is
already in the output folder (resume), runs the rest on an executor (:mod:`ssbench.bench.executors`) with a
tqdm bar, writes each row as it arrives (:class:`ssbench.bench.rowstore.RowStore`) and finally the consolidated
``rows.jsonl`` + ``rows.parquet`` in sweep order and the run's metadata. :func:`run_group` is the unit of
work (what a Dask worker runs): it never raises for a failing configuration, it returns rows whose
``error`` reads ``"<ExceptionType>: <message>"``. Ground truth comes from the reference layer's cache. Without
a ``timing:`` block (or with ``interleave: 0``) a group is one configuration (:func:`run_config`) and its row is
written at once; with one, ``interleave`` configurations (8 by default) are evaluated, then timed together in
randomized interleaved rounds (:mod:`ssbench.bench.interleave`), their rows written as the group ends (an
interrupted sweep re-runs the groups in flight); with ``processes: N`` each group is also timed in ``N - 1``
fresh processes and the rounds pooled (:mod:`ssbench.bench.processes`).

Row schema (one flat dict per configuration):

* ``config_id, effect, scene, method`` first; then the evaluation's own row (``ssbench.evaluate.ao``/``ssr``:
  ``params`` is the full resolved parameter dict, metrics, settings, ``seconds``...), with ``scene`` as
  written in the sweep file;
* ``error`` (``None`` or ``"Type: message"``) and ``error_traceback`` (on errors only); an error row keeps
  ``params`` (the overrides), ``seed, width, height`` and the settings;
* with a ``timing:`` block, :data:`ssbench.bench.timing.TIMING_FIELDS` (``time_median_ms, time_iqr_ms,
  floor_median_ms, floor_ratio, threads, ...``);
* with ``images: true``, ``images``: ``{"image": "img/<config_id>.png", "error": "img/<config_id>_error.png"}``
  (relative to the sweep folder; :mod:`ssbench.bench.pictures`), ``None`` plus ``images_error`` when drawing failed;
* ``config`` (the canonical configuration hashed into ``config_id``), ``elapsed_s`` (wall time of the
  configuration), ``variant`` (Mitsuba variant of the process that ran it), ``run_id, git_commit, git_dirty``
  (the invocation that wrote it; its full metadata is ``runs/<run_id>.json``).

Two runs of one configuration give equal rows except the fields :func:`ssbench.bench.rows.is_volatile` names
(timings and metadata): compare with :func:`ssbench.bench.rows.canonical_json`.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import math
import os
import time
import traceback
import zlib
from typing import Any, Optional, Union

from .config import Config, Sweep, SweepError, load_sweep
from .effects import get_effect
from .executors import make_executor
from .rows import new_run_id, run_metadata
from .rowstore import RowStore
from .timing import TIMING_FIELDS, TimingSpec

__all__ = ["run_config", "run_group", "run_sweep", "SweepResult", "default_out"]


def _variant() -> Optional[str]:
    try:
        from ..reference import backend
        return backend.choice().variant
    except Exception:                                    # noqa: BLE001 - metadata only
        return None


def _error_text(e: BaseException) -> str:
    return f"{type(e).__name__}: {e}"


def _nan_timing(config: Config, timing: TimingSpec, why: str) -> dict:
    row: dict[str, Any] = {k: math.nan for k in TIMING_FIELDS}
    row.update(time_blocks=0, floor_samples=None, threads=config.settings.get("threads", 1),
               timing_min_run_time=float(timing.min_run_time), timing_processes=0, timing_error=why)
    return row


def error_row(config: Config, exc: BaseException, timing: Optional[TimingSpec] = None,
              tb_text: Optional[str] = None) -> dict:
    """The row of a configuration that failed with ``exc``."""
    row: dict[str, Any] = {"config_id": config.config_id, "effect": config.effect, "scene": config.scene,
                           "method": config.method, "params": dict(config.params), "seed": config.seed,
                           "width": config.width, "height": config.height, **dict(config.settings),
                           "error": _error_text(exc),
                           "error_traceback": (tb_text or "".join(traceback.format_exception(exc)))[-4000:]}
    if timing is not None:
        row.update(_nan_timing(config, timing, "not timed: the evaluation failed"))
    row["config"] = config.canonical()
    return row


def evaluate_config(config: Config, timing: Optional[TimingSpec],
                    images: Optional[str] = None) -> tuple[dict, Any, int, float]:
    """``(row, bench inputs or None, threads, seconds)``: the configuration's row without timing fields (an error
    row when it fails), the inputs to time (``None`` when nothing is to be timed) and its wall time.

    With ``images`` (a folder), the effect's pictures of the evaluation go to ``images/img/<config_id>*.png``
    (:func:`ssbench.bench.pictures.write_pictures`) and the row's ``images`` names them (relative to ``images``);
    a picture that cannot be drawn leaves ``images`` ``None`` and says why in ``images_error``."""
    import torch
    effect = get_effect(config.effect)
    threads = int(config.settings.get("threads", 1))
    prev = torch.get_num_threads()
    t0 = time.perf_counter()
    inputs = None
    try:
        torch.set_num_threads(threads)
        try:
            ev = effect.run(config.scene_file or config.scene, config.method, config.params, width=config.width,
                            height=config.height, seed=config.seed, settings=config.settings)
        except Exception as e:                           # noqa: BLE001 - a failing configuration is a row
            row = error_row(config, e, timing)
        else:
            row = {"config_id": config.config_id, "effect": config.effect, "scene": config.scene,
                   "method": config.method}
            row.update({k: v for k, v in ev.row.items() if k not in row})
            row.update({k: v for k, v in config.settings.items() if k not in row})
            row["error"] = None
            if images is not None:
                _pictures(effect, ev, images, config, row)
            if timing is not None:
                try:
                    inputs = effect.bench_inputs(ev, config.method, config.params, config.seed)
                except Exception as e:                   # noqa: BLE001 - keep the evaluation's row
                    row.update(_nan_timing(config, timing, f"not timed: {_error_text(e)}"))
    finally:
        torch.set_num_threads(prev)
    return row, inputs, threads, time.perf_counter() - t0


def _pictures(effect, ev, folder: str, config: Config, row: dict) -> None:
    from .pictures import write_pictures
    try:
        spec = effect.picture_spec()
        if spec is None:
            raise ValueError(f"effect {effect.name!r} declares no pictures")
        row["images"] = write_pictures(spec, ev, folder, config.config_id)
    except Exception as e:                               # noqa: BLE001 - keep the evaluation's row
        row["images"], row["images_error"] = None, _error_text(e)


def _finish(config: Config, row: dict, seconds: float) -> dict:
    row.setdefault("config", config.canonical())
    row["elapsed_s"] = seconds
    row["variant"] = _variant()
    return row


def run_config(config: Config, timing: Optional[TimingSpec] = None, images: Optional[str] = None) -> dict:
    """Evaluate one configuration (and time it when ``timing`` is given; draw its pictures into the folder
    ``images`` when given); always returns a row.

    Torch threads are set to ``config.settings["threads"]`` for the call and restored afterwards.
    """
    return run_group([config], timing, images)[0]


def run_group(configs: list, timing: Optional[TimingSpec] = None, images: Optional[str] = None) -> list:
    """Evaluate several configurations, then (given ``timing``) time them together in randomized interleaved rounds
    (:func:`ssbench.bench.interleave.time_interleaved`; the order seeded from their ids), pooled over
    ``timing.processes`` processes (:func:`ssbench.bench.processes.time_group`); one row each, in order.

    ``elapsed_s`` is each configuration's evaluation plus an equal share of the group's timing.
    """
    from .processes import time_group
    done = [evaluate_config(c, timing, images) for c in configs]
    live = [k for k, d in enumerate(done) if d[1] is not None]
    share = 0.0
    if live:
        t0 = time.perf_counter()
        try:
            timed = time_group([(done[k][1], done[k][2], configs[k].seed) for k in live], [configs[k] for k in live],
                               timing, order_seed=zlib.crc32(" ".join(c.config_id for c in configs).encode()))
        except Exception as e:                           # noqa: BLE001 - keep the evaluations' rows
            timed = [_nan_timing(configs[k], timing, f"not timed: {_error_text(e)}") for k in live]
        share = (time.perf_counter() - t0) / len(live)
        for k, fields in zip(live, timed):
            done[k][0].update(fields)
    return [_finish(c, row, seconds + (share if k in live else 0.0))
            for k, (c, (row, _, _, seconds)) in enumerate(zip(configs, done))]


@dataclasses.dataclass
class SweepResult:
    """What :func:`run_sweep` did: the rows of the sweep (sweep order), counts and where things are."""

    out: str
    run_id: str
    rows: list
    ran: int
    skipped: int
    errors: int
    tables: dict
    notes: list


def default_out(sweep: Sweep) -> str:
    """``reports/sweeps/<sweep name>`` (relative to the working directory), so a plain re-run resumes."""
    return os.path.join("reports", "sweeps", sweep.name)


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def run_sweep(sweep: Union[Sweep, str, "os.PathLike"], out: Optional[str] = None, *,
              executor: Union[str, Any] = "local", workers: Optional[int] = None, address: Optional[str] = None,
              resume: bool = True, retry_errors: bool = False, progress: Optional[bool] = True) -> SweepResult:
    """Run every configuration of ``sweep`` (a :class:`Sweep` or a sweep file) into the folder ``out``.

    Args:
        out: output folder (default :func:`default_out`); see :mod:`ssbench.bench.rows` for its layout.
        executor: ``"local"`` (in-process, sequential), ``"dask"`` (a ``LocalCluster`` of ``workers``
            processes, or the cluster at ``address``) or an executor object.
        resume: skip configurations whose row is already stored (``False``: run all, replacing rows).
        retry_errors: with ``resume``, run again the configurations whose stored row has an ``error``.
        progress: show the tqdm bar (``None``: only on a terminal).

    Raises:
        SweepError: for an invalid sweep file, or when ``out`` holds a sweep of another effect.
    """
    from tqdm.auto import tqdm
    if not isinstance(sweep, Sweep):
        sweep = load_sweep(sweep)
    store = RowStore(out or default_out(sweep))
    prev = store.read_json("sweep.json")
    if prev and prev.get("effect") != sweep.effect:
        raise SweepError(f"out: {store.root} holds a sweep of effect {prev.get('effect')!r}, not "
                         f"{sweep.effect!r}; choose another output folder")
    ids = sweep.ids()
    skip: set[str] = set()
    notes: list[str] = []
    if resume:
        for path in store.quarantine_corrupt(ids):
            notes.append(f"corrupt row moved to {path}; recomputed")
        done = store.done_ids()
        for cid in ids:
            if cid in done:
                row = store.read_row(cid)
                if (retry_errors and row.get("error")) or (sweep.images and not row.get("error")
                                                            and not row.get("images")):
                    continue                             # re-run: failed, or stored without its pictures
                skip.add(cid)
    todo = [c for c in sweep.configs if c.config_id not in skip]
    store.write_json("sweep.json", {"name": sweep.name, "effect": sweep.effect, "source": sweep.source,
                                    "sha256": sweep.sha256, "description": sweep.description,
                                    "timing": None if sweep.timing is None else vars(sweep.timing),
                                    "images": sweep.images,
                                    "configs": [{"config_id": c.config_id, **c.canonical()} for c in sweep.configs]})
    run_id = new_run_id()
    images = os.path.abspath(store.root) if sweep.images else None
    ex = make_executor(executor, workers=workers, address=address) if isinstance(executor, str) else executor
    ran = errors = 0
    meta: dict = {}
    with ex:
        meta = run_metadata(run_id=run_id, sweep=sweep, executor=ex.describe(), resume=resume, out=store.root)
        meta.update(planned=len(ids), skipped=len(skip), todo=len(todo), retry_errors=retry_errors)
        commits = {store.read_row(c).get("git_commit") for c in sorted(skip)[:50]}
        if skip and commits - {meta["git"]["commit"]}:
            notes.append(f"resumed {len(skip)} stored rows written at other commits ({', '.join(map(str, commits))}); "
                         f"use --no-resume to recompute them at {meta['git']['commit']}")
        meta["notes"] = notes
        store.write_json(f"runs/{run_id}.json", meta)
        stamp = {"run_id": run_id, "git_commit": meta["git"]["commit"], "git_dirty": meta["git"]["dirty"]}
        bar = tqdm(total=len(ids), initial=len(skip), desc=f"sweep {sweep.name}", unit="config",
                   disable=None if progress is None else not progress)
        n = max(1, sweep.timing.interleave if sweep.timing is not None else 1)        # configurations per task
        try:
            for configs, rows_, exc in ex.imap_unordered(run_group, [todo[i:i + n] for i in range(0, len(todo), n)],
                                                         timing=sweep.timing, images=images):
                if exc is not None:                      # the task itself died (e.g. a lost Dask worker)
                    rows_ = [error_row(c, exc, sweep.timing) for c in configs]
                for row in rows_:
                    row.update(stamp)
                    store.write_row(row)
                    ran += 1
                    errors += bool(row.get("error"))
                    bar.update(1)
                bar.set_postfix(errors=errors, refresh=False)
        except BaseException:
            meta.update(status="interrupted", ran=ran, errors=errors, finished=_now())
            store.write_json(f"runs/{run_id}.json", meta)
            raise
        finally:
            bar.close()
    tables = store.consolidate(ids)
    rows = store.rows(ids)
    variants = {r.get("variant") for r in rows if r.get("run_id") == run_id} - {None}
    if variants - {meta["backend"]["variant"]}:
        notes.append(f"workers ran Mitsuba variant(s) {sorted(variants)}, this process "
                     f"{meta['backend']['variant']}: ground truths may differ between rows")
    meta.update(status="finished", ran=ran, errors=errors, rows=len(rows),
                errors_total=sum(bool(r.get("error")) for r in rows), finished=_now(),
                tables={k: os.path.basename(v) for k, v in tables.items()})
    store.write_json(f"runs/{run_id}.json", meta)
    store.write_json("metadata.json", meta)
    return SweepResult(store.root, run_id, rows, ran, len(skip), errors, tables, notes)
