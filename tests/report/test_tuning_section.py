"""The report's tuning section: a tiny real run, the template, and notes instead of crashes."""
import os
import re
import sys

import pytest

from ssbench.report import build
from ssbench.report import render
from ssbench.report.tuning_section import HELD_OUT, METHODS, TRAIN, build_tuning_section, summary_md

TINY = dict(width=32, height=24, rays=8, points=3, rounds=1, steps=1, use_cache=True, progress=False)


def _render(tuning: dict) -> str:
    import jinja2
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(build.__file__),
                                                                         "templates")),
                             autoescape=True, undefined=jinja2.StrictUndefined)
    return env.get_template("tuning_section.html.j2").render(tuning=tuning, fmt=render.fmt)


@pytest.mark.slow
def test_section_tunes_both_methods_and_renders(tmp_path):
    out = build_tuning_section(str(tmp_path), **TINY)
    assert out["available"] and out["notes"] == [] and out["seconds"] > 0 and out["size"] == "32×24"
    assert [b["method"] for b in out["methods"]] == list(METHODS)
    assert len(out["rows"]) == len(METHODS) * (len(TRAIN) + len(HELD_OUT))
    for b in out["methods"]:
        assert float(b["train_tuned"]) <= float(b["train_default"])
        assert b["improved"] == (b["held_tuned_value"] < b["held_default_value"])
        assert ("beats" if b["improved"] else "does NOT beat") in b["verdict"]
        assert (tmp_path / "tuning" / f"{b['method']}.json").is_file()
    rows = {(r["method"], r["scene"]): r for r in out["rows"]}
    assert rows[("gtao", "stairs")]["split"] == "held_out" and rows[("hbao", "crease")]["split"] == "train"
    assert f"{rows[('gtao', 'stairs')]['rmse_cos_tuned']:.4f}" == out["methods"][1]["scenes"][3]["tuned"]
    text = _render(out)
    assert 'id="tuning-hbao"' in text and 'id="tuning-gtao"' in text and out["methods"][0]["verdict"] in text
    # tables sit in a wrapping flex box, never in the 130-px thumbnail grid (.row), where they overlapped
    assert text.count('<div class="tables">') == len(METHODS) and not re.search(r'class="row">\s*<table', text)
    md = summary_md(out)
    assert "## Tuning" in md and out["methods"][1]["verdict"] in md
    assert [g["method"] for g in out["glance"]] == list(METHODS)


def test_a_failing_method_becomes_a_note(tmp_path, monkeypatch):
    import ssbench.tune as T
    real = T.tune

    def flaky(method, *a, **k):
        if method == "hbao":
            raise RuntimeError("tuner exploded")
        return real(method, *a, **k)

    monkeypatch.setattr(T, "tune", flaky)
    out = build_tuning_section(str(tmp_path), **TINY)
    assert out["available"] and [b["method"] for b in out["methods"]] == ["gtao"]
    assert any("hbao skipped" in n and "tuner exploded" in n for n in out["notes"])
    assert "tuner exploded" in _render(out) and "tuner exploded" in summary_md(out)


def test_unimportable_tuner_and_failing_ground_truth_are_notes(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ssbench.tune", None)                       # import fails
    out = build_tuning_section(str(tmp_path), **TINY)
    assert not out["available"] and "not importable" in out["note"]
    assert "not importable" in _render(out) and "not importable" in summary_md(out)
    monkeypatch.undo()
    import ssbench.tune as T

    def boom(*a, **k):
        raise RuntimeError("no backend")

    monkeypatch.setattr(T, "prepare_cases", boom)
    out = build_tuning_section(str(tmp_path), **TINY)
    assert not out["available"] and "ground truth failed" in out["note"] and "no backend" in out["note"]
    monkeypatch.setattr(T, "prepare_cases", None)                               # not even callable
    out = build_tuning_section(str(tmp_path), width=32, height=24, progress=False)
    assert not out["available"] and out["note"]


def test_tuning_size():
    from ssbench.report.tuning_section import tuning_size
    assert tuning_size(640, 360) == (80, 45) and tuning_size(32, 24) == (32, 24)
