"""The calibration section renders what the experiments return, and a failing experiment becomes a note."""
import re

import jinja2
import pytest

from ssbench.analysis.calibration import Response
from ssbench.report import render
from ssbench.report import calibration_section as C


def _fake_experiments(use_cache):
    good = [Response("banding", "kernel_size", "s", "rotation off", (4, 16, 64), (0.06, 0.03, 0.02),
                     (0.002, 0.002, 0.001), "falls", 8, "fake"),
            Response("banding", "kernel_size", "s", "wrong way", (4, 16, 64), (0.01, 0.03, 0.02), (0, 0, 0),
                     "falls", 1, "fake")]
    quality = [Response("flicker", "quality", "s", "gtao", ("low", "high"), (0.02, 0.004), (0, 0), "falls", 1, "f")]

    def boom():
        raise RuntimeError("no Mitsuba here")
    return [("banding", "Banding", "falls", lambda: good), ("flicker", "Flicker", "falls", lambda: quality),
            ("broken", "Broken", "rises", boom)]


def test_section_with_stub_experiments(tmp_path, monkeypatch):
    monkeypatch.setattr(C, "_experiments", _fake_experiments)
    monkeypatch.setattr(C, "_flicker_methods", lambda use_cache: [
        {"kind": "flicker", "scene": "s", "method": "m", "frames": 8, "radius": 1.0, "flicker": 0.01,
         "flicker_jitter": 0.002}])
    sec = C.build_calibration_section(str(tmp_path), progress=False)
    assert sec["available"] and sec["passed"] == 2 and sec["total"] == 3
    assert any("Broken" in n and "no Mitsuba here" in n for n in sec["notes"])
    curves = sec["experiments"][0]["curves"]
    assert [c["ok"] for c in curves] == [True, False] and curves[0]["ratio"] == "3.00 ± 0.18"   # 3·hypot(.002/.06, .001/.02)
    assert curves[1]["ratio"] == "0.50"                                    # no error bars: no ±
    assert (tmp_path / "img" / "calibration" / "banding.png").is_file()
    rows = sec["rows"]
    assert [r["kind"] for r in rows] == ["response"] * 3 + ["flicker"]
    assert rows[0]["x"] == [4, 16, 64] and rows[0]["monotone"] is True
    env = jinja2.Environment(loader=jinja2.PackageLoader("ssbench.report", "templates"), autoescape=True,
                             undefined=jinja2.StrictUndefined)
    html = env.get_template("calibration_section.html.j2").render(calibration=sec, fmt=render.fmt)
    assert "How each metric was calibrated" in html and "wrong way" in html and "no Mitsuba here" in html
    assert re.findall(r'<img[^>]*src="([^"]+)"', html) == ["img/calibration/banding.png",
                                                          "img/calibration/flicker.png"]
    md = C.summary_md(sec)
    assert "2 of 3 response curves" in md and "| m | 0.0100 | 0.0020 |" in md and "| no |" in md


def test_unavailable_section_says_why(tmp_path, monkeypatch):
    monkeypatch.setattr(C, "_experiments", lambda use_cache: [("x", "X", "rises", lambda: 1 / 0)])
    monkeypatch.setattr(C, "_flicker_methods", lambda use_cache: [])
    sec = C.build_calibration_section(str(tmp_path), progress=False)
    assert not sec["available"] and "failed" in sec["note"] and "ZeroDivisionError" in sec["notes"][0]
    assert "failed" in C.summary_md(sec)
