"""The lessons: every ``lessons/NN_*.py`` (jupytext percent, the source) is in sync with its ``.ipynb``, and every
notebook runs headless at the small size within its time budget, ending with its own asserts.

Regenerate the notebooks after editing a lesson with ``make lessons-sync``.
"""
from __future__ import annotations

import difflib
import resource
import time
from pathlib import Path

import jupytext
import nbformat
import pytest

ROOT = Path(__file__).resolve().parents[2]
LESSONS_DIR = ROOT / "lessons"
LESSONS = sorted(LESSONS_DIR.glob("[0-9][0-9]_*.py"))
BUDGET_S = 120                       # CPU seconds per lesson, kernel start included
WALL_S = 2 * BUDGET_S                # the wall-clock limit: two test workers may share the cores
SYNC_HINT = "run `make lessons-sync` (python lessons/_sync.py) and commit the .py and the .ipynb together"
IDS = [p.stem for p in LESSONS]


def _cells(nb) -> list[tuple[str, str]]:
    return [(c.cell_type, c.source) for c in nb.cells]


def test_every_lesson_is_a_pair():
    assert len(LESSONS) >= 6, f"expected the lessons 01-06 in {LESSONS_DIR}, found {[p.name for p in LESSONS]}"
    for py in LESSONS:
        assert py.with_suffix(".ipynb").exists(), f"{py.name} has no notebook: {SYNC_HINT}"
    for nb in LESSONS_DIR.glob("[0-9][0-9]_*.ipynb"):
        assert nb.with_suffix(".py").exists(), f"{nb.name} has no .py source (the .py is the source of truth)"


@pytest.mark.parametrize("py", LESSONS, ids=IDS)
def test_notebook_matches_source(py):
    """Same cells, same types, same sources: the .ipynb is the .py as jupytext reads it."""
    source = jupytext.read(py)
    notebook = nbformat.read(py.with_suffix(".ipynb"), as_version=4)
    expected, actual = _cells(source), _cells(notebook)
    for i, (e, a) in enumerate(zip(expected, actual)):
        if e != a:
            lines = difflib.unified_diff(a[1].splitlines(), e[1].splitlines(), ".ipynb", ".py", n=1, lineterm="")
            pytest.fail(f"{py.stem}: cell {i} ({e[0]} in the .py, {a[0]} in the .ipynb) differs; {SYNC_HINT}\n"
                        + "\n".join(list(lines)[:20]))
    assert len(expected) == len(actual), (f"{py.stem}: {len(expected)} cells in the .py, {len(actual)} in the "
                                          f".ipynb; {SYNC_HINT}")


@pytest.mark.parametrize("py", LESSONS, ids=IDS)
def test_notebook_is_stored_clean(py):
    """No outputs or execution counts in the repository (small diffs), and a kernel plain Jupyter knows."""
    notebook = nbformat.read(py.with_suffix(".ipynb"), as_version=4)
    dirty = [i for i, c in enumerate(notebook.cells)
             if c.cell_type == "code" and (c.get("outputs") or c.get("execution_count") is not None)]
    assert not dirty, f"{py.stem}: cells {dirty} hold outputs; {SYNC_HINT}"
    assert notebook.metadata.get("kernelspec", {}).get("name") == "python3", f"{py.stem}: kernelspec must be python3"


def test_markdown_is_not_swallowing_code():
    """A markdown cell never contains a code-cell marker (jupytext would fold the code into the text)."""
    for py in LESSONS:
        for cell_type, src in _cells(jupytext.read(py)):
            if cell_type == "markdown":
                assert "# %%" not in src, f"{py.stem}: a markdown cell contains '# %%'"


@pytest.mark.slow
@pytest.mark.timeout(WALL_S + 60)
@pytest.mark.parametrize("py", LESSONS, ids=IDS)
def test_lesson_runs_headless(py, monkeypatch):
    """Execute the committed notebook with nbclient at SSBENCH_LESSON_SIZE=small; every cell must pass, within
    the budget of CPU seconds of its kernel (CPU time, not wall time: `make test` runs a second test worker beside
    it, which slows the wall clock but not the lesson's own work; the kernel runs one torch thread there)."""
    from nbclient import NotebookClient

    monkeypatch.setenv("SSBENCH_LESSON_SIZE", "small")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    notebook = nbformat.read(py.with_suffix(".ipynb"), as_version=4)
    client = NotebookClient(notebook, timeout=WALL_S, kernel_name="python3",
                            resources={"metadata": {"path": str(LESSONS_DIR)}})
    before, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
    client.execute()                                   # raises CellExecutionError with the cell's traceback
    wall, after = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)    # the kernel's, once reaped
    assert 0 < cpu < BUDGET_S, f"{py.stem} took {cpu:.0f} s of CPU ({wall:.0f} s wall), over its {BUDGET_S} s budget"
    last_code = [c for c in notebook.cells if c.cell_type == "code"][-1]
    assert "assert" in last_code.source, f"{py.stem}: the last code cell must be the lesson's asserts"
