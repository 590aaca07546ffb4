"""The row store of a sweep: one file per finished row, written atomically, plus run metadata and tables.

Layout of a sweep's output folder::

    rows/<config_id>.json    one finished row each: written to a temporary file, fsynced, then renamed
    runs/<run_id>.json       metadata of each invocation (commit, versions, variant, threads, machine, ...)
    metadata.json            the latest run's metadata
    sweep.json               the sweep as run: name, effect, source, sha256, the configurations
    rows.jsonl, rows.parquet the consolidated table, in sweep order (rows.csv when pyarrow is missing)

A rename is atomic, so a ``kill -9`` at any moment leaves each row either absent or whole (at worst a stray
``.*.tmp`` file, ignored and removed later); a row's file name is its ``config_id``, so a re-run can neither
duplicate nor half-write a row. ``rows/`` is the truth: the consolidated tables are rewritten at the end of
each run (a killed run leaves the previous ones, and its ``runs/<run_id>.json`` says ``"status": "running"``).
Two invocations on one folder at once at worst compute a configuration twice; the later rename wins.
Rows are strict JSON (RFC 8259): a non-finite number is written as ``null`` and its place recorded in the
row's ``"nonfinite"`` field (``{"rmse": "nan", "params.radius": "inf"}``), so :meth:`ssbench.bench.rowstore.RowStore.read_row` gives
back the same floats, and pandas/pyarrow/jq read the files as they are. A row file that does not parse is
moved aside to ``rows/<config_id>.json.corrupt-<time>`` (with a warning naming it) and recomputed.

Fields that differ between two runs of the same configuration are :data:`TIMING_FIELDS` (wall times) and
:data:`METADATA_FIELDS`; :func:`stable` drops them, :func:`canonical_json` compares what is left.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import secrets
from typing import Any, Sequence

from .timing import TIMING_FIELDS as _PASS_TIMING

__all__ = ["TIMING_FIELDS", "json_default", "write_text_atomic", "write_tables", "METADATA_FIELDS", "is_volatile", "stable", "canonical_json",
           "new_run_id", "run_metadata", "tidy_columns", "encode_row", "decode_row", "dumps_row"]

#: wall-time fields: the evaluation's own, the per-config wall time, and :mod:`ssbench.bench.timing`'s numbers
TIMING_FIELDS = ("seconds", "seconds_runs", "blur_seconds", "gt_seconds", "gt_seconds_cos", "gt_seconds_flavour",
                 "gt_seconds_oracle", "elapsed_s") + tuple(f for f in _PASS_TIMING
                                                           if f not in ("threads", "floor_samples",
                                                                        "timing_min_run_time", "timing_processes",
                                                                        "timing_error"))
#: per-run metadata copied into every row (the full record is ``runs/<run_id>.json``)
METADATA_FIELDS = ("run_id", "git_commit", "git_dirty", "variant")


def is_volatile(key: str) -> bool:
    """Whether a row field may differ between runs of the same configuration (timing or metadata)."""
    return key in TIMING_FIELDS or key in METADATA_FIELDS or key.startswith("gt_seconds")


def stable(row: dict) -> dict:
    """``row`` without its volatile fields (:func:`is_volatile`)."""
    return {k: v for k, v in row.items() if not is_volatile(k)}


def json_default(x: Any) -> Any:
    """``json.dumps``' ``default`` for rows: tensors and arrays as lists, sets and tuples as lists, else ``str``."""
    if hasattr(x, "tolist"):                        # torch / numpy values
        return x.tolist()
    if isinstance(x, (set, frozenset, tuple)):
        return list(x)
    return str(x)


NONFINITE = "nonfinite"


def encode_row(row: dict) -> dict:
    """``row`` with every non-finite float (at any depth of dicts) replaced by ``None`` and listed under
    :data:`NONFINITE` by its dotted path; :func:`decode_row` undoes it.

    Example:
        >>> encode_row({"a": float("nan"), "p": {"r": float("-inf")}, "b": 1.0})
        {'a': None, 'p': {'r': None}, 'b': 1.0, 'nonfinite': {'a': 'nan', 'p.r': '-inf'}}
    """
    marks: dict[str, str] = {}

    def walk(x, path):
        if isinstance(x, float) and x != x:
            marks[path] = "nan"
            return None
        if isinstance(x, float) and x in (float("inf"), float("-inf")):
            marks[path] = "inf" if x > 0 else "-inf"
            return None
        if isinstance(x, dict):
            return {k: walk(v, f"{path}.{k}" if path else str(k)) for k, v in x.items()}
        if hasattr(x, "tolist") and not isinstance(x, (list, tuple)):
            return walk(x.tolist(), path)
        if isinstance(x, (list, tuple)):       # (non-finite list items become null without a mark)
            return [None if isinstance(v, float) and not (v == v and abs(v) != float("inf")) else walk(v, path)
                    for v in x]
        return x

    out = walk({k: v for k, v in row.items() if k != NONFINITE}, "")
    if marks:
        out[NONFINITE] = marks
    return out


def decode_row(row: dict) -> dict:
    """Inverse of :func:`encode_row`: put the marked non-finite floats back."""
    marks = row.pop(NONFINITE, None) or {}
    for path, kind in marks.items():
        *head, last = path.split(".")
        d = row
        for k in head:
            d = d.get(k) if isinstance(d, dict) else None
        if isinstance(d, dict) and d.get(last) is None:
            d[last] = float(kind)
    return row


def dumps_row(row: dict, **kw) -> str:
    """Strict JSON text of ``row`` (:func:`encode_row`; never a bare ``NaN``)."""
    return json.dumps(encode_row(row), default=json_default, allow_nan=False, **kw)


def canonical_json(row: dict) -> str:
    """Sorted strict JSON of the stable part of ``row`` (``NaN == NaN`` here, unlike in a dict comparison); a row
    read raw from a file (``null`` + ``nonfinite``) and the same row decoded give the same text."""
    import copy
    return json.dumps(stable(encode_row(decode_row(copy.deepcopy(row)))), sort_keys=True, default=json_default,
                      allow_nan=False)


def new_run_id() -> str:
    """``YYYYmmddTHHMMSSZ-<6 hex>``: sortable by time, unique across concurrent invocations."""
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ") + "-" + secrets.token_hex(3)


def _commit(tmp: str, path: str) -> None:
    """The atomic step: rename ``tmp`` over ``path``."""
    os.replace(tmp, path)


def write_text_atomic(path: str, text: str, fsync: bool = True) -> None:
    """Write ``text`` to a temporary file beside ``path`` (flushed, fsynced) and :func:`_commit` it."""
    d, base = os.path.split(path)
    tmp = os.path.join(d, f".{base}.{os.getpid()}.{secrets.token_hex(2)}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            if fsync:
                os.fsync(f.fileno())
        _commit(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def write_tables(rows: Sequence[dict], base: str) -> dict[str, str]:
    """Write ``base.jsonl`` and ``base.parquet`` (``base.csv`` without pyarrow) of ``rows``, in that order, each
    atomically; returns ``{"jsonl": path, "parquet"|"csv": path}``."""
    d, name = os.path.split(base)
    out = {"jsonl": base + ".jsonl"}
    write_text_atomic(out["jsonl"], "".join(dumps_row(r) + "\n" for r in rows))
    cols = tidy_columns(rows)
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:                                  # pragma: no cover - pyarrow is a dependency
        import csv
        import io
        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(list(cols))
        w.writerows(zip(*cols.values()))
        out["csv"] = base + ".csv"
        write_text_atomic(out["csv"], buf.getvalue())
        return out
    path = base + ".parquet"
    tmp = os.path.join(d, f".{name}.parquet.{os.getpid()}.{secrets.token_hex(2)}.tmp")
    try:
        pq.write_table(pa.table(cols) if cols else pa.table({"config_id": pa.array([], pa.string())}), tmp)
        _commit(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    out["parquet"] = path
    return out


def tidy_columns(rows: Sequence[dict]) -> dict[str, list]:
    """Column-wise rows for Parquet/CSV: ``params`` also flattened to ``param.<name>`` columns; nested values
    (dicts, lists) as JSON text; a column mixing types other than int/float/None becomes JSON text.

    Example:
        >>> tidy_columns([{"a": 1, "params": {"r": 0.5}}, {"a": 2.5, "params": {"r": 1.0, "q": "low"}}])
        {'a': [1.0, 2.5], 'params': ['{"r": 0.5}', '{"q": "low", "r": 1.0}'], 'param.r': [0.5, 1.0], 'param.q': [None, 'low']}
    """
    flat = []
    for r in rows:
        f = dict(r)
        for k, v in (r.get("params") or {}).items():
            f[f"param.{k}"] = v
        flat.append(f)
    keys: list[str] = list(dict.fromkeys(k for f in flat for k in f))
    cols: dict[str, list] = {}
    for k in keys:
        vals = [f.get(k) for f in flat]
        vals = [json.dumps(v, sort_keys=True, default=json_default) if isinstance(v, (dict, list, tuple)) else v
                for v in vals]
        kinds = {type(v) for v in vals if v is not None}
        if kinds == {int, float}:
            vals = [None if v is None else float(v) for v in vals]
        elif len(kinds) > 1:
            vals = [None if v is None else json.dumps(v, default=json_default) for v in vals]
        cols[k] = vals
    return cols


def run_metadata(*, run_id: str, sweep, executor: dict, resume: bool, out: str) -> dict:
    """Metadata of one invocation: commit (+dirty), package versions, backend variant, torch threads, machine,
    date, the sweep file's hash and the executor."""
    from .. import runinfo
    env = runinfo.environment()
    return {"run_id": run_id, "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "sweep": {"name": sweep.name, "effect": sweep.effect, "source": os.path.abspath(sweep.source)
                      if os.path.exists(sweep.source) else sweep.source, "sha256": sweep.sha256,
                      "configs": len(sweep.configs),
                      "timing": None if sweep.timing is None else vars(sweep.timing)},
            "git": runinfo.git_state(), "versions": {k: env.get(k) for k in ("ssbench", "python", "torch", "kornia", "numpy",
                                                                     "mitsuba", "drjit")},
            "backend": {"variant": env.get("variant"), "libllvm": env.get("libllvm"),
                        "reason": env.get("backend_reason"), "drjit_threads": env.get("drjit_threads")},
            "torch_threads": env.get("torch_threads"),
            "machine": {k: env.get(k) for k in ("platform", "machine", "processor", "node", "cpu_count")},
            "executor": executor, "resume": resume, "out": out, "status": "running"}

