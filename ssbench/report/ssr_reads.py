"""The SSR section's equal-reads table: every marcher with the same depth-read budget per ray
(:mod:`ssbench.analysis.equal_reads`), per scene: correct / missed / false hits / punch-through and the reads
actually made. Nothing here raises into the report: a failing run becomes a note."""
from __future__ import annotations

from typing import Iterable

from .ao_section import fmt

__all__ = ["reads_rows", "reads_tables"]


def reads_rows(scene, gbuffer, truth, notes: list, *, budgets: Iterable[int] = None, **run_kw) -> list[dict]:
    """:func:`~ssbench.analysis.equal_reads.equal_read_rows` on one scene, each row tagged ``setting="reads"``;
    a failure is appended to ``notes`` and gives no rows."""
    from ..analysis.equal_reads import READ_BUDGETS, equal_read_rows
    try:
        rows = equal_read_rows(scene, gbuffer, truth, budgets=READ_BUDGETS if budgets is None else budgets,
                               progress=False, **run_kw)
    except Exception as e:                                        # the report goes on without the table
        notes.append(f"equal reads: {type(e).__name__}: {e}")
        return []
    return [{**r, "setting": "reads"} for r in rows]


def reads_tables(rows: list[dict]) -> list[dict]:
    """Template data, one table per scene: ``{"scene", "budgets", "rows": [{"method", "cells"}]}``, each cell
    ``correct / missed / false / punch-through`` with the mean reads."""
    rows = [r for r in rows if r.get("setting") == "reads"]
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == scene]
        budgets = sorted({r["budget"] for r in mine})
        methods = list(dict.fromkeys(r["method"] for r in mine))
        table = []
        for m in methods:
            cells = []
            for b in budgets:
                r = next((r for r in mine if r["method"] == m and r["budget"] == b), None)
                cells.append(None if r is None else {
                    "text": " / ".join(fmt(r.get(k), "{:.1%}") for k in ("frac_correct", "frac_missed",
                                                                        "frac_false_hit", "frac_punch_through")),
                    "reads": fmt(r.get("reads_mean"), "{:.1f}")})
            table.append({"method": m, "cells": cells})
        out.append({"scene": scene, "budgets": budgets, "rows": table})
    return out
