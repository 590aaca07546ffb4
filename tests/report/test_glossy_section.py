"""The glossy section on a tiny run: every SSR method has a row, the figures and images exist, the template and the
summary render."""
from __future__ import annotations

import os

import jinja2

from ssbench.passes import SSR_METHODS
from ssbench.report import render
from ssbench.report.glossy_section import build_glossy_section, summary_md


def test_glossy_section_runs_and_renders(tmp_path):
    sec = build_glossy_section(str(tmp_path), 32, 24, progress=False)
    assert sec["available"] and not sec["notes"], sec["notes"]
    assert [r["method"] for r in sec["rows"]] == list(SSR_METHODS)
    assert {"glossy_stochastic", "glossy_blur"} <= set(sec["glossy_methods"])
    for rel in sec["images"].values():
        assert (tmp_path / rel).is_file(), rel
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(render.__file__), "templates")),
                             autoescape=True, undefined=jinja2.StrictUndefined)
    html = env.get_template("glossy_section.html.j2").render(glossy=sec, fmt=render.fmt)
    assert "information loss" in html and "<strong>glossy_blur</strong>" in html and "img/glossy/error.png" in html
    md = summary_md(sec)
    assert "## Glossy reflections" in md and all(f"| {m} |" in md for m in SSR_METHODS)
    off = summary_md({"available": False, "note": "off", "notes": []})
    assert "off" in off
