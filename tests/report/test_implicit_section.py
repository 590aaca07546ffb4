"""The report's implicit-surface section: real runs at a tiny size, the template, notes instead of crashes."""
import html
import os
import re

import pytest

from ssbench.report import build
from ssbench.report import render
from ssbench.report.implicit_section import COMPARE_SCENES, build_implicit_section, summary_md


def _render(imp: dict) -> str:
    import jinja2
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(build.__file__),
                                                                         "templates")),
                             autoescape=True, undefined=jinja2.StrictUndefined)
    return env.get_template("implicit_section.html.j2").render(implicit=imp, fmt=render.fmt)


@pytest.fixture(scope="module")
def section(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("run")
    return run_dir, build_implicit_section(str(run_dir), 24, 18, frames=4, lipschitz_samples=2000)


@pytest.mark.slow
def test_section_renders_every_part(section):
    run_dir, imp = section
    assert imp["available"] and imp["notes"] == [] and imp["seconds"] > 0
    assert [c["name"] for c in imp["comparisons"]] == list(COMPARE_SCENES)
    text = _render(imp)
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]+)"', text)
    assert len(srcs) == 5 * len(COMPARE_SCENES) + 2 + 2 + 1                # comparisons, maps, double root, anim
    for src in srcs:
        assert (run_dir / src).is_file() and src.startswith("img/implicit/"), src
    import matplotlib.image as mimage
    assert mimage.imread(str(run_dir / imp["comparisons"][0]["images"]["fixed"])).shape[:2] == (18, 24)
    flagged = [r["scene"] for r in imp["lipschitz"] if r["overshoot"]]
    assert flagged == ["displaced_torus"] and "OVERSHOOT" in text
    assert len(imp["lipschitz"]) == 11


@pytest.mark.slow
def test_numbers_come_from_rows(section):
    _, imp = section
    rows = {(r["scene"], r["method"]): r for r in imp["rows"] if r["truth_frames"] == "all"}
    prog, fixed = rows[("thin_shell", "progressive")], rows[("thin_shell", "fixed")]
    cells = imp["comparisons"][0]["cells"]
    assert cells["progressive"]["first"] == f"{prog['punch_through_per_frame'][0]:.2%}"
    assert cells["fixed"]["last"] == f"{fixed['punch_through_per_frame'][-1]:.2%}"
    assert len(set(fixed["punch_through_per_frame"])) == 1
    anim = next(r for r in imp["rows"] if r["scene"] == "animated")
    assert imp["animated"]["spans"][0]["total"] == sum(anim["invalidated_per_frame"][11:31]) > 0
    assert imp["double_root"]["ambiguous"] == rows[("double_root", "fixed")]["truth_ambiguous_pixels"] > 0
    md = summary_md(imp)
    assert "## Implicit surfaces" in md and "displaced_torus" in md and cells["progressive"]["first"] in md
    assert "ambiguous pixels" in md and "invalidations" in md


def test_a_failing_scene_becomes_a_note(tmp_path, monkeypatch):
    from ssbench import evaluate
    real = evaluate.run_implicit

    def flaky(scene, method, *a, **k):
        if scene == "thin_plate":
            raise RuntimeError("marcher exploded")
        return real(scene, method, *a, **k)

    monkeypatch.setattr(evaluate, "run_implicit", flaky)
    imp = build_implicit_section(str(tmp_path), 16, 12, frames=2, lipschitz_samples=500)
    assert imp["available"] and [c["name"] for c in imp["comparisons"]] == ["thin_shell"]
    assert any("thin_plate skipped" in n and "marcher exploded" in n for n in imp["notes"])
    text = _render(imp)
    assert "marcher exploded" in text and "thin_shell" in text and "marcher exploded" in summary_md(imp)


def test_unavailable_slice_is_a_note(tmp_path, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "ssbench.reference.implicit", None)        # import fails
    imp = build_implicit_section(str(tmp_path), 16, 12)
    assert not imp["available"] and "not importable" in imp["note"]
    assert html.escape(imp["note"]).replace("&#x27;", "&#39;") in _render(imp)
    assert imp["note"] in summary_md(imp) and not os.listdir(tmp_path)


def test_report_hook_never_raises_and_is_off_for_a_scene_subset(tmp_path, monkeypatch):
    from ssbench.report import implicit_section

    def boom(*a, **k):
        raise RuntimeError("kaboom")
    monkeypatch.setattr(implicit_section, "build_implicit_section", boom)
    out = build._implicit_section(str(tmp_path), None, 320, 240, None, 0, False)
    assert not out["available"] and "kaboom" in out["note"] and "kaboom" in out["summary_md"]
    for scenes, enabled in ((["crease"], None), (None, False)):
        off = build._implicit_section(str(tmp_path), scenes, 320, 240, enabled, 0, False)
        assert not off["available"] and off["summary_md"] == "" and "turned off" in _render(off)


def test_report_cli_passes_no_implicit(monkeypatch, tmp_path):
    from ssbench import cli
    seen = {}

    def fake(out, **kw):
        seen.update(kw)
        return str(tmp_path / "index.html")
    monkeypatch.setattr(build, "build_report", fake)
    assert cli.main(["report", "--out", str(tmp_path), "--no-implicit"]) == 0
    assert seen["implicit"] is False
    assert cli.main(["report", "--out", str(tmp_path)]) == 0 and seen["implicit"] is None
