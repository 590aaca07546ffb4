"""Rebuild every ``lessons/NN_*.ipynb`` from its jupytext percent source (``make lessons-sync``).

The ``.py`` is the source of truth. The notebook gets the same cells with no outputs, and cell ids derived from
each cell's content, so regenerating an unchanged lesson changes nothing and editing one cell changes one cell
of the diff (``jupytext --to ipynb`` alone draws random ids on every run). ``tests/lessons`` checks the pairs.

Usage: ``python lessons/_sync.py [lessons/NN_name.py ...]`` (default: all lessons).
"""
from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import jupytext
import nbformat

LESSONS_DIR = Path(__file__).resolve().parent


def notebook_from_source(py: Path) -> nbformat.NotebookNode:
    """The lesson as a clean notebook: jupytext's cells, stable ids, no outputs."""
    nb = jupytext.read(py)
    seen: dict[str, int] = {}
    for cell in nb.cells:
        digest = hashlib.sha1(f"{cell.cell_type}\n{cell.source}".encode()).hexdigest()[:12]
        seen[digest] = seen.get(digest, 0) + 1
        cell["id"] = digest if seen[digest] == 1 else f"{digest}-{seen[digest]}"
        if cell.cell_type == "code":
            cell["outputs"], cell["execution_count"] = [], None
    return nb


def main(paths: list[str]) -> int:
    sources = [Path(p) for p in paths] or sorted(LESSONS_DIR.glob("[0-9][0-9]_*.py"))
    for py in sources:
        target = py.with_suffix(".ipynb")
        jupytext.write(notebook_from_source(py), target, fmt="ipynb")
        print(f"{py} -> {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
