"""Rendering a report run's pages from its metadata, computing nothing: the sweep explorers, ``index.html`` and
``summary.md``. :func:`ssbench.report.build.build_report` computes the sections and then calls
:func:`write_pages`; :func:`render_run` (``ssbench report --from RUN``) reads a finished run's ``meta.json`` and
does the same."""
from __future__ import annotations

import json
import os

from ..io import write_atomic
from . import summary

__all__ = ["fmt", "templates", "render_index", "explorer_pages", "write_pages", "render_run", "write_text"]

#: a table cell's text (``–`` for None/NaN); the templates get it as ``fmt``
fmt = summary.fmt


def write_text(path: str, text: str) -> None:
    """Write ``text`` to ``path`` atomically (a temporary file beside it, renamed), with the usual mode."""
    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
    write_atomic(path, ".tmp", write)


def templates():
    """The report's jinja2 environment (``templates/``; autoescape, strict undefined)."""
    import jinja2
    return jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(__file__), "templates")),
                              autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
                              lstrip_blocks=True)


def render_index(tpl_env, meta: dict) -> str:
    """``index.html``; a section whose template is missing or fails to render becomes a note instead."""
    for key, title in summary.SECTIONS:
        sec = meta[key]
        if not sec.get("available"):
            continue
        try:
            tpl_env.get_template(f"{key}_section.html.j2").render(**{key: sec}, meta=meta, fmt=fmt)
        except Exception as e:                               # e.g. a template still being written
            note = f"{title} section could not be shown: {type(e).__name__}: {e}"
            meta[key] = {**sec, "available": False, "note": note}
            meta["glance"] = summary.glance(meta)
    return tpl_env.get_template("index.html.j2").render(meta=meta, fmt=fmt, sections=summary.SECTIONS)


def explorer_pages(run_dir: str, tpl_env, meta: dict) -> None:
    """The speed section's sweep explorers (:mod:`.explorer`); never raises (a failure is a note)."""
    try:
        from .explorer import write_pages
        write_pages(run_dir, meta.get("speed") or {}, tpl_env, meta)
    except Exception as e:                                   # noqa: BLE001 - the report must not crash
        meta.setdefault("speed", {}).setdefault("notes", []).append(
            f"sweep explorers not written: {type(e).__name__}: {e}")


def write_pages(run_dir: str, meta: dict) -> None:
    """The sweep explorers, then ``index.html`` (it links only explorers that exist) and ``summary.md``."""
    tpl_env = templates()
    explorer_pages(run_dir, tpl_env, meta)
    html = render_index(tpl_env, meta)
    write_text(os.path.join(run_dir, "index.html"), html)
    write_text(os.path.join(run_dir, "summary.md"), summary.summary_md(meta)
               + "".join(meta[k].get("summary_md", "") for k, _ in summary.SECTIONS))


def render_run(run_dir: str) -> str:
    """Re-render ``index.html`` and ``summary.md`` of a finished run from its ``meta.json``, computing nothing
    (no rendering, no ground truth, no pass): for a changed template or summary. Rows, images and ``meta.json``
    are left as they are. A section the run does not hold (an older run) shows as a note. Returns the path of
    ``index.html``."""
    import importlib
    with open(os.path.join(run_dir, "meta.json"), encoding="utf-8") as f:
        meta = json.load(f)
    for key, title in summary.SECTIONS:
        sec = meta.get(key)
        if not isinstance(sec, dict):
            meta[key] = {"available": False, "note": f"{title} section not in this run.", "notes": [],
                         "summary_md": ""}
        elif sec.get("available"):
            try:                                             # today's summary of the stored section
                sec["summary_md"] = importlib.import_module(f"{__package__}.{key}_section").summary_md(sec)
            except Exception:                                # keep the one written with the run
                pass
    meta["glance"] = summary.glance(meta)
    meta.setdefault("rows_files", {})
    write_pages(run_dir, meta)
    return os.path.join(run_dir, "index.html")
