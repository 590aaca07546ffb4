"""The sweep explorer: knobs from rows, the page's data from a real (tiny) speed section with pictures, a page that
works offline, and — in headless Chromium — a slider that changes the image, the error map, the numbers and the
ringed point."""
import json
import re
from pathlib import Path

import pytest

from ssbench.report import render
from ssbench.report import speed_section as S
from ssbench.report.explorer import DEFAULT, explorer_data, knobs, write_pages

TINY_AO = {"name": "x_ao", "effect": "ao", "scenes": ["crease"], "resolution": [24, 18], "rays": 8, "oracle": False,
           "flip": False, "images": True, "timing": {"min_run_time": 0.002, "warmup": 0, "rounds": 3},
           "methods": {"ssao": [{"kernel_radius": 0.5, "kernel_size": [4, 8, 16]},
                                {"kernel_radius": 0.5, "kernel_size": 8, "noise_size": 2}],
                       "gtao": {"radius": 0.5, "quality": "low"}}}


def _row(cid, params, settings=None, **kw):
    return {"config_id": cid, "scene": "s", "method": "m", "width": 8, "height": 6, "seed": 0, "error": None,
            "config": {"params": params, "settings": {"threads": 1, "repeats": 1, **(settings or {})}}, **kw}


def test_knobs_are_what_varies_numbers_ascending_and_unset_parameters_default():
    rows = [_row("a", {"k": 32}), _row("b", {"k": 8}), _row("c", {"k": 16, "noise": 2}, {"blur": "box"}),
            _row("d", {"k": 16}, {"blur": None})]
    got = {k["name"]: k["values"] for k in knobs(rows)}
    assert got == {"k": ["8", "16", "32"], "noise": [DEFAULT, "2"], "blur": [DEFAULT, "box", "none"]}
    assert knobs(rows[:1]) == []                            # one configuration: nothing to slide
    assert "threads" not in got and "size" not in got     # bookkeeping and constant choices make no knob
    sized = [_row("a", {"k": 8}), dict(_row("b", {"k": 8}), width=16, height=12)]
    assert knobs(sized) == [{"name": "size", "values": ["8×6", "16×12"]}]


def test_points_carry_knobs_numbers_fronts_and_pictures_and_skip_failed_rows():
    rows = [_row("a", {"k": 8}, time_median_ms=1.0, rmse=0.3, images={"image": "p/a.png", "error": "p/a_e.png"}),
            _row("b", {"k": 32}, time_median_ms=4.0, rmse=0.1, images=None),
            _row("c", {"k": 64}, time_median_ms=float("nan"), rmse=float("inf")),
            dict(_row("d", {"k": 99}), error="ValueError: no")]
    d = explorer_data("ao", "AO", rows, [("rmse", "RMSE")], {("s", "rmse"): [rows[0], rows[1]]}, "bar.png", None)
    assert [p["id"] for p in d["points"]] == ["a", "b", "c"] and d["failed"] == 1 and d["without_images"] == 2
    a, b, c = d["points"]
    assert a["knobs"] == {"k": "8"} and d["groups"]["s|m"]["knobs"] == [{"name": "k", "values": ["8", "32", "64"]}]
    assert (a["x"], a["y"], a["front"], c["front"]) == (1.0, 0.3, True, False)
    assert c["x"] is None and c["y"] is None              # not finite: not plotted, never NaN in the page's JSON
    assert a["image"] == "p/a.png" and b["image"] is None and dict(a["numbers"])["RMSE"] == "0.3"
    json.dumps(d, allow_nan=False)


@pytest.fixture(scope="module")
def section(tmp_path_factory):
    from tests.report.test_speed_section import build_in
    run_dir = tmp_path_factory.mktemp("run")
    out = build_in(run_dir, {"ao": TINY_AO})
    meta = {"run": "test", "speed": out}
    assert write_pages(str(run_dir), out, render.templates(), meta) == ["explore_ao.html"]
    return run_dir, out


@pytest.mark.slow
@pytest.mark.mitsuba
def test_every_configuration_has_its_pictures_and_the_page_holds_them(section):
    import matplotlib.image as mimage
    run_dir, out = section
    (e,) = out["effects"]
    d = e["explorer"]
    assert len(d["points"]) == 5 and d["without_images"] == 0 and d["failed"] == 0
    for p in d["points"]:
        for key in ("image", "error_image"):
            assert mimage.imread(run_dir / p[key]).shape[:2] == (18, 24), p
    assert (run_dir / d["colorbar"]).is_file()
    assert {k["name"]: k["values"] for k in d["groups"]["crease|ssao"]["knobs"]} == {
        "kernel_size": ["4", "8", "16"], "noise_size": [DEFAULT, "2"]}
    html = (run_dir / "explore_ao.html").read_text(encoding="utf-8")
    data = json.loads(re.search(r'<script type="application/json" id="explorer-data">(.*?)</script>', html,
                                re.S).group(1))
    assert data["points"] == d["points"]
    assert not re.search(r"""(src|href)\s*=\s*["'](https?:)?//""", html), "the explorer must work offline"
    rendered = S.summary_md(out)                    # the section still summarises with the explorer in it
    assert "| crease | ssao |" in rendered


@pytest.mark.slow
@pytest.mark.mitsuba
def test_the_slider_changes_the_image_the_numbers_and_the_ringed_point_in_a_browser(section, tmp_path):
    from tests.report.test_browser import CHROMIUM, check_page
    if CHROMIUM is None:
        pytest.skip("no Chromium binary on PATH; `make browser`")
    run_dir, _ = section
    out = check_page(Path(run_dir) / "explore_ao.html", tmp_path)
    x = out.pop("explorer")
    assert out["broken"] == [] and out["errors"] == [] and out["layout"]["wide"] == [], out
    assert x["sliders"] == 2 and x["methods"] == 2 and x["points"] == 5, x
    before, after = x["before"], x["after"]
    assert before["point"] and after["point"] != before["point"], x
    assert after["image"] != before["image"] and after["error"] != before["error"], x
    assert after["image"].endswith(after["point"] + ".png") and after["ring"] != before["ring"], x
    assert after["rows"] == before["rows"] > 0
