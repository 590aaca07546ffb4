"""The time section on a real (small) run: every AO method's flicker and ghosting, raw and accumulated, the error
plot and the animation; a method that fails becomes a note; the template renders what the section returns."""
import re

import jinja2
import pytest

from ssbench.report import render
from ssbench.report import time_section as T

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]


@pytest.fixture(scope="module")
def section(tmp_path_factory):
    run = tmp_path_factory.mktemp("time")
    return run, T.build_time_section(str(run), 48, 36, progress=False)


def test_every_ao_method_has_a_row_and_the_pictures_exist(section):
    from ssbench.passes import AO_METHODS
    run, sec = section
    assert sec["available"] and not sec["notes"]
    from ssbench.passes import SSR_METHODS
    assert [r["method"] for r in sec["rows"] if r["kind"] == "time"] == list(AO_METHODS)
    assert [r["method"] for r in sec["rows"] if r["kind"] == "time_ssr"] == list(SSR_METHODS)
    from ssbench.passes import IMPLICIT_METHODS
    from ssbench.report.time_implicit import SCENES
    assert [(r["scene"], r["method"]) for r in sec["rows"] if r["kind"] == "time_implicit"] == [
        (s, m) for s in SCENES for m in IMPLICIT_METHODS]
    for r in sec["rows"]:
        assert r["flicker"] > 0 and r["flicker_accumulated"] > 0
        if r["kind"] == "time_implicit":
            assert r["error_txaa"] < r["error_raw"], r
            continue
        assert r["ghosting"] == r["ghosting"]                                        # not NaN
        if r["kind"] == "time":
            assert r["ghosting_moving"] == r["ghosting_moving"] and r["ghosting_moving_camera_only"] == \
                r["ghosting_moving_camera_only"]
    for f in ("error.png", "gtao.gif", "moving_gtao.gif", "txaa.png"):
        assert (run / "img" / "time" / f).is_file(), f
    from PIL import Image
    with Image.open(run / "img" / "time" / "gtao.gif") as gif:
        assert gif.n_frames == T.FRAMES and gif.size == (2 * 48 + 4, 36)


def test_template_and_summary_render_the_rows(section):
    _, sec = section
    env = jinja2.Environment(loader=jinja2.PackageLoader("ssbench.report", "templates"), autoescape=True,
                             undefined=jinja2.StrictUndefined)
    html = env.get_template("time_section.html.j2").render(time=sec, fmt=render.fmt)
    assert re.findall(r'<img[^>]*src="([^"]+)"', html) == ["img/time/error.png", "img/time/gtao.gif",
                                                          "img/time/moving_gtao.gif", "img/time/txaa.png"]
    assert all(r["method"] in html for r in sec["rows"])
    md = T.summary_md(sec)
    assert "## Time" in md and md.count("\n| ") >= len(sec["rows"]) + 3


def test_a_failing_method_is_a_note(tmp_path, monkeypatch):
    import ssbench.evaluate as E

    def broken(*a, **k):
        raise RuntimeError("no frames here")
    monkeypatch.setattr(E, "ao_frames", broken)
    monkeypatch.setattr(E, "ssr_frames", broken)
    monkeypatch.setattr(E, "implicit_frames", broken)
    sec = T.build_time_section(str(tmp_path), 16, 12, progress=False)
    assert not sec["available"] and all("no frames here" in n for n in sec["notes"])
    assert "no AO method" in T.summary_md(sec) or "Time" in T.summary_md(sec)


def test_the_report_page_shows_the_time_section(tmp_path):
    """Through build_report and the page renderer (which renders each section template under its own key)."""
    import json
    from ssbench.report.build import build_report
    index = build_report(str(tmp_path / "reports"), scenes=["sphere_on_plane"], width=32, height=24, spp=2,
                         progress=False, ao=False, ssr=False, implicit=False, speed=False, tuning=False,
                         calibration=False, time_axis=True)
    meta = json.loads((tmp_path / "reports" / "latest" / "meta.json").read_text())
    assert meta["time"]["available"], meta["time"].get("note")
    html = open(index, encoding="utf-8").read()
    assert 'id="time"' in html and "img/time/error.png" in html and "img/time/gtao.gif" in html
