"""The speed section: embedded sweeps parse and feed every small multiple; a tiny real run writes one raw row per
configuration, the images the page links and the tables; failures become notes."""
import dataclasses
import json
import os
import re

import pytest

from ssbench.report import build
from ssbench.report import render
from ssbench.report import speed_section as S

TINY = {
    "ao": {"name": "t_ao", "effect": "ao", "scenes": ["crease"], "resolution": [32, 24], "rays": 16, "oracle": False,
           "flip": False, "timing": {"min_run_time": 0.005, "warmup": 0},
           "methods": {"ssao": {"kernel_radius": 0.5, "kernel_size": [4, 8]}, "gtao": {"radius": 0.5,
                                                                                       "quality": "low"}}},
    "ssr": {"name": "t_ssr", "effect": "ssr", "scenes": ["reflective_floor"], "resolution": [32, 24], "spp": 2,
            "flip": False, "timing": {"min_run_time": 0.005, "warmup": 0}, "methods": {"dda": {"max_steps": [16, 64]}}},
    "implicit": {"name": "t_imp", "effect": "implicit", "scenes": ["thin_plate"], "resolution": [32, 24],
                 "frames": 2, "timing": {"min_run_time": 0.005, "warmup": 0},
                 "methods": {"fixed": {"steps": [16, 32]}, "progressive": {"steps": 8}}},
}


def _render(speed: dict) -> str:
    import jinja2
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(build.__file__),
                                                                         "templates")),
                             autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    return env.get_template("speed_section.html.j2").render(speed=speed, fmt=render.fmt)


@pytest.mark.parametrize("effect", list(S.SPECS))
def test_embedded_sweeps_parse_and_every_panel_gets_a_line_of_two_points(effect):
    from ssbench.analysis.multiples import panel_lines
    from ssbench.bench import get_effect
    sweeps = S.load_embedded(S.default_sweeps()[effect], (32, 24), 3)
    assert sweeps and all(s.effect == effect for s in sweeps)
    configs = [c for s in sweeps for c in s.configs]
    assert {(c.width, c.height, c.seed) for c in configs} == {(32, 24, 3)}
    eff = get_effect(effect)
    rows = []
    for c in configs:                                       # rows as a sweep writes them, metrics faked as 1
        p = eff.method(c.method)[1](**c.params)
        rows.append({"config_id": c.config_id, "scene": c.scene, "method": c.method, **c.settings,
                     "params": dataclasses.asdict(p), "config": c.canonical(), "error": None,
                     **{m: 1.0 for m, _ in S.SPECS[effect]["metrics"]}, "banding": 1.0, "halo_dark_flavour": 1.0,
                     "frac_missed": 1.0, "frac_false_hit": 1.0, "frac_punch_through": 1.0,
                     "punch_through_per_frame": [1.0] * c.settings.get("frames", 1)})
    for title, panels in S.figures(effect).values():
        for panel in panels:
            d = panel_lines(rows, panel)
            assert any(len(set(ln["x"])) >= 2 for ln in d["lines"]), (title, panel)


def test_a_second_document_reports_its_own_file_line(tmp_path):
    p = tmp_path / "two.yaml"
    p.write_text("name: one\neffect: ao\nscenes: [crease]\nmethods: {ssao: null}\n---\n# two\nname: two\n"
                 "effect: ao\nscenes: [crease]\nmethods:\n  ssao: {kernel_sise: 4}\n")
    from ssbench.bench import SweepError
    with pytest.raises(SweepError, match=r"two\.yaml:11:.*kernel_sise"):
        S.load_embedded(str(p), (8, 6), 0)


def test_embedded_sweeps_take_each_methods_declared_grids(tmp_path):
    from ssbench.bench import SweepError
    from ssbench.passes import AO_METHODS, ao_method, declared
    from ssbench.report.speed_sweeps import declared_methods
    cost = declared_methods("ao", "cost")
    assert list(cost) == [m for m in AO_METHODS if "cost" in (declared(ao_method(m)[0], "SPEED_GRIDS") or {})]
    sweeps = S.load_embedded(S.default_sweeps()["ao"], (16, 12), 0)
    import math
    for m, grids in cost.items():                           # every declared configuration, on every scene
        mine = [c for c in sweeps[0].configs if c.method == m]
        n = sum(math.prod(len(v) if isinstance(v, list) else 1 for v in g.values()) for g in grids)
        assert len(mine) == n * len({c.scene for c in sweeps[0].configs}), m
    head = "name: x\neffect: ao\nscenes: [crease]\n"
    p = tmp_path / "g.yaml"
    p.write_text(head + "grids: cost\nmethods: {ssao: null}\n")
    with pytest.raises(SweepError, match=r"g\.yaml:4: grids: give either grids or methods"):
        S.load_embedded(str(p), (8, 6), 0)
    p.write_text(head + "grids: nobody_declares_this\n")
    with pytest.raises(SweepError, match=r"g\.yaml:4: grids: no ao method declares SPEED_GRIDS\['nobody_declares_this'\]"):
        S.load_embedded(str(p), (8, 6), 0)


def test_every_artifact_panel_is_declared_by_its_method():
    from ssbench.bench import get_effect
    from ssbench.passes import declared
    for effect in S.SPECS:
        eff = get_effect(effect)
        got = [(p.method, p.param) for _, panels in S.figures(effect).values() for p in panels]
        want = [(m, sp.param) for m in eff.method_names() for sp in declared(eff.method(m)[0], "SPEED_PANELS", ())]
        assert sorted(got) == sorted(want) and got, effect


def build_in(run_dir, sweeps: dict) -> dict:
    """The speed section of ``sweeps`` built into ``run_dir``, with a ground-truth cache of its own."""
    mp = pytest.MonkeyPatch()
    mp.setenv("SSBENCH_CACHE_DIR", str(run_dir / "cache"))
    try:
        return S.build_speed_section(str(run_dir), width=320, height=240, seed=0, progress=False, sweeps=sweeps)
    finally:
        mp.undo()


@pytest.fixture(scope="module")
def section(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("run")
    return run_dir, build_in(run_dir, TINY)


@pytest.mark.slow
@pytest.mark.mitsuba
def test_section_writes_raw_rows_images_and_tables(section):
    import pyarrow.parquet as pq
    run_dir, out = section
    assert out["available"] and [e["name"] for e in out["effects"]] == ["ao", "ssr", "implicit"]
    for e in out["effects"]:
        assert e["available"], e["note"]
        n = len(S.as_sweeps(TINY[e["name"]])[0])
        lines = (run_dir / e["files"]["jsonl"]).read_text().splitlines()
        assert e["rows"] == len(lines) == n and pq.read_table(run_dir / e["files"]["parquet"]).num_rows == n
        assert {json.loads(x)["config_id"] for x in lines} == set(S.as_sweeps(TINY[e["name"]])[0].ids())
        assert e["errors"] == 0 and e["summary"] and e["equal_error"] and e["fronts"]
        assert {(s["scene"], s["method"]) for s in e["summary"]} == {(q["scene"], q["method"])
                                                                      for q in e["equal_error"]}
    text = _render(out)
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]+)"', text)
    assert len(srcs) == 3 + 2 + 1 + 1                           # error-time per effect, AO 2, SSR 1, implicit 1
    for src in srcs:
        assert src.startswith("img/speed/") and (run_dir / src).is_file(), src
    assert [g["method"] for g in out["glance"]] == ["ssao", "gtao", "dda", "fixed", "progressive"]   # registry keys
    assert all(" at 160×120, best configuration: " in g["headline"] and float(g["seconds"]) > 0 for g in out["glance"])
    worded = [g["headline"] for g in out["glance"] if " · as good as " in g["headline"]]
    assert worded and all(any(w in h for w in ("rays/px", "spp", "steps")) for h in worded), worded
    md = S.summary_md(out)
    assert "| crease | ssao |" in md and "Equal-error cost (rmse_faded" in md and "| thin_plate | fixed |" in md


@pytest.mark.slow
@pytest.mark.mitsuba
def test_the_implicit_ladder_is_the_sweeps_own_fixed_step(section):
    run_dir, out = section
    imp = next(e for e in out["effects"] if e["name"] == "implicit")
    rows = [json.loads(x) for x in (run_dir / imp["files"]["jsonl"]).read_text().splitlines()]
    (lad,) = imp["ladders"]
    by_n = dict(zip(lad["ns"], lad["errors"]))
    for r in rows:                                   # unjittered fixed step at N on the ladder: the same numbers
        if r["method"] == "fixed" and r["params"]["steps"] in by_n:
            assert by_n[r["params"]["steps"]] == S.fmt(r["punch_through_rate"], "{:.4g}")


def test_failures_become_notes(tmp_path):
    out = S.build_speed_section(str(tmp_path), width=32, height=24, progress=False,
                                sweeps={"ao": {"effect": "ao", "scenes": ["crease"], "methods": {"nope": None}},
                                        "bogus": {}, "ssr": str(tmp_path / "missing.yaml")})
    assert not out["available"] and [e["available"] for e in out["effects"]] == [False, False, False]
    notes = [e["note"] for e in out["effects"]]
    assert "unknown ao method 'nope'" in notes[0] and "unknown effect 'bogus'" in notes[1]
    assert "not found" in notes[2]
    assert "## Speed against error" in S.summary_md(out) and "Speed against error" in _render(out)
