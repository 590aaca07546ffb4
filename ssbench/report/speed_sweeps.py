"""Running the speed section's sweeps: embedded sweep files (``---``-separated documents), sweeps given as
objects, dicts or paths, fresh runs into the report folder, and the pooled raw rows (JSON lines + Parquet).

The embedded files (``sweeps/<effect>.yaml``) name no method: each document says ``grids: <purpose>`` and gets,
for every method of its effect, the grids that method's module declares as ``SPEED_GRIDS[<purpose>]``
(:func:`declared_methods`); a new method's module joins the report's sweeps by declaring them."""
from __future__ import annotations

import os
import re


def declared_methods(effect: str, purpose: str) -> dict:
    """``{method: grids}`` of every method of ``effect`` whose module declares ``SPEED_GRIDS[purpose]``, in
    registry order (the ``methods:`` block a ``grids: <purpose>`` document stands for).

    Example:
        >>> declared_methods("ssr", "cost")["dda_supercover"]
        [{'max_steps': [32, 128]}]
    """
    from ..bench import get_effect
    from ..passes import declared
    eff = get_effect(effect)
    out = {}
    for name in eff.method_names():
        grids = (declared(eff.method(name)[0], "SPEED_GRIDS", None) or {}).get(purpose)
        if grids:
            out[name] = grids
    return out


def load_embedded(path: str, size: tuple, seed: int) -> list:
    """The sweep documents of ``path`` (``---``-separated) with ``resolution`` = ``size`` and ``seeds`` = [seed],
    ``grids: <purpose>`` replaced by the declared ``methods`` (:func:`declared_methods`); ``file:line`` in
    errors point into the file."""
    from ..bench import SweepError
    from ..bench.config import sweep_from_dict
    from ..scenes.files import read_yaml
    with open(path, encoding="utf-8") as f:
        lines = f.read().splitlines(keepends=True)
    docs, start = [], 0
    for i, ln in enumerate(lines + ["---\n"]):
        if re.fullmatch(r"---[ \t]*\r?\n?", ln):
            body = "".join(lines[start:i])
            if re.search(r"(?m)^[ \t]*[^#\s]", body):
                data, locate = read_yaml("\n" * start + body, path)
                data.update(resolution=list(size), seeds=[seed])
                if "grids" in data:
                    where = locate(("grids",))
                    purpose = data.pop("grids")
                    if "methods" in data:
                        raise SweepError(f"{where}: grids: give either grids or methods, not both")
                    try:
                        data["methods"] = declared_methods(data.get("effect"), purpose)
                    except (KeyError, TypeError, ValueError) as e:
                        raise SweepError(f"{locate(('effect',))}: effect: {e}") from None
                    if not data["methods"]:
                        raise SweepError(f"{where}: grids: no {data.get('effect')} method declares "
                                         f"SPEED_GRIDS[{purpose!r}]")
                docs.append(sweep_from_dict(data, locate, path, os.path.dirname(path)))
            start = i + 1
    return docs


def as_sweeps(value) -> list:
    from ..bench import Sweep, load_sweep, sweep_from_dict
    items = value if isinstance(value, (list, tuple)) else [value]
    out = []
    for v in items:
        if isinstance(v, Sweep):
            out.append(v)
        elif isinstance(v, dict):
            out.append(sweep_from_dict(v, source=f"{v.get('name', 'sweep')}.yaml"))
        else:
            out.append(load_sweep(v))
    return out


def write_rows(rows: list, base: str) -> dict:
    """``base.jsonl`` and ``base.parquet`` of ``rows`` (:func:`ssbench.bench.rows.write_tables`, the sweep
    tables' format)."""
    from ..bench.rows import write_tables
    os.makedirs(os.path.dirname(base), exist_ok=True)
    return write_tables(rows, base)


def run_sweeps(sweeps: list, run_dir: str, progress, notes: list) -> tuple[list, list]:
    """Run every sweep (fresh, into ``run_dir/sweeps/<name>``); rows pooled in order, duplicates dropped, each
    row's ``images`` (sweeps with ``images: true``) made relative to ``run_dir``."""
    from ..bench import run_sweep
    rows, seen, runs = [], set(), []
    for s in sweeps:
        res = run_sweep(s, os.path.join(run_dir, "sweeps", s.name), progress=progress, resume=False)
        notes += res.notes
        runs.append({"name": s.name, "configs": len(s), "errors": res.errors, "description": s.description})
        for r in res.rows:
            if r["config_id"] not in seen:
                seen.add(r["config_id"])
                if r.get("images"):
                    r = dict(r, images={k: v and f"sweeps/{s.name}/{v}" for k, v in r["images"].items()})
                rows.append(r)
    return rows, runs
