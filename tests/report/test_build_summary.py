"""Report plumbing without rendering: the glance table, raw rows, the speed/tuning hooks, the index template."""
import json
import math
import os
import re
import shutil
import sys
import types

import jinja2
import pytest

from ssbench.report import build, render, summary

TEMPLATES = os.path.join(os.path.dirname(build.__file__), "templates")
ENV = {"ssbench": "0.1", "python": "3.11", "torch": "2", "mitsuba": "3", "drjit": "1", "kornia": "0.9",
       "numpy": "2", "variant": "llvm_ad_rgb", "libllvm": None, "libllvm_major": None, "torch_threads": 2,
       "drjit_threads": 2, "node": "n", "processor": "p", "machine": "m", "cpu_count": 2, "platform": "linux"}


def _off(title):
    return {"available": False, "note": f"{title} section turned off.", "notes": [], "summary_md": ""}


def _meta(**sections):
    meta = {"run": "20250101-000000", "date": "2025-01-01", "width": 32, "height": 24, "spp": 4, "seed": 0,
            "use_cache": False, "git": {"commit": "abc", "dirty": False}, "environment": ENV, "backend_init_s": 0.1,
            "total_s": 1.0, "scenes": [], "preview_row": []}
    for key, title in summary.SECTIONS:
        meta[key] = sections.get(key, _off(title))
    meta["metadata_rows"] = summary.metadata_rows(meta)
    meta["glance"] = summary.glance(meta)
    meta["rows_files"] = {}
    return meta


AO = {"available": True, "note": "", "rows": [
    {"scene": "a", "method": "ssao", "rmse_cos": 0.1, "seconds": 1.0},
    {"scene": "b", "method": "ssao", "rmse_cos": 0.3, "seconds": 3.0},
    {"scene": "a", "method": "gtao", "rmse_cos": float("nan"), "seconds": 2.0}]}
SSR = {"available": True, "note": "", "rows": [
    {"scene": "f", "method": "dda", "frac_correct": 0.5, "frac_missed": 0.25, "frac_false_hit": 0.0,
     "frac_punch_through": 0.125, "frac_misplaced_hit": 0.0625, "frac_unfixable_hit": 0.03125, "seconds": 0.5}]}
IMPLICIT = {"available": True, "note": "", "frames": 40, "comparisons": [{"name": "thin_shell"}], "rows": [
    {"scene": "thin_shell", "method": "progressive", "punch_through_per_frame": [0.5, 0.01],
     "evaluations_mean": 32.0, "seconds_per_frame": 0.02},
    {"scene": "torus", "method": "sphere", "punch_through_per_frame": [0.9], "evaluations_mean": 9.0}]}


def test_glance_reads_each_section_and_notes_the_missing_ones():
    blocks = {b["key"]: b for b in summary.glance(_meta(ao=AO, ssr=SSR, implicit=IMPLICIT))}
    ao = {d["method"]: d for d in blocks["ao"]["lines"]}
    assert ao["ssao"] == {"method": "ssao", "headline": "defaults: RMSE 0.2000 vs cosine GT", "seconds": "2.000", "scenes": 2,
                          "what": "normal-oriented hemisphere SSAO (Chapman; three.js SSAOPass)"}   # its Method.title
    assert ao["gtao"]["headline"] == "defaults: RMSE – vs cosine GT"                        # NaN is not a number to show
    assert blocks["ssr"]["lines"][0]["headline"] == ("defaults: correct 50.0% · missed 25.0% · false hit 0.0% · "
                                                     "misplaced hit 6.2% · punch-through 12.5% · "
                                                     "hit on unfixable target 3.1%")
    imp = blocks["implicit"]["lines"]
    assert [d["method"] for d in imp] == ["progressive"]                         # the comparison scenes only
    assert imp[0]["headline"].startswith("punch-through 1.00% on the last of 40 frames · 32.0 evaluations/px")
    assert not blocks["speed"]["available"] and blocks["speed"]["note"] == "Speed section turned off."
    md = summary.glance_md(list(blocks.values()))
    assert "| Ambient occlusion | ssao (normal-oriented hemisphere SSAO (Chapman; three.js SSAOPass)) | defaults: RMSE 0.2000 vs cosine GT | 2.000 | 2 |" in md
    assert "| Tuning | – | Tuning section turned off. | – | – |" in md


def test_glance_uses_a_sections_own_lines_and_survives_a_malformed_one():
    speed = {"available": True, "glance": [{"method": "gtao", "headline": "2.1 ms at 1080p"}]}
    bad = {"available": True, "rows": ["not a row"]}
    blocks = {b["key"]: b for b in summary.glance(_meta(speed=speed, ao=bad))}
    assert blocks["speed"]["lines"] == [{"method": "gtao", "headline": "2.1 ms at 1080p", "seconds": "–",
                                         "scenes": "–", "what": "ground-truth AO, GTAO (Jimenez et al. 2016; XeGTAO)"}]
    md = summary.glance_md(list(blocks.values()))
    assert "| gtao (ground-truth AO, GTAO (Jimenez et al. 2016; XeGTAO)) | 2.1 ms at 1080p |" in md
    other = {b["key"]: b for b in summary.glance(_meta(speed={"available": True, "glance": [{"method": "banding"}]}))}
    assert other["speed"]["lines"][0]["what"] == ""                          # no declared method: no words
    assert blocks["ao"]["lines"] == [] and blocks["ao"]["note"].startswith("summary failed: AttributeError")
    assert "summary failed: AttributeError" in summary.glance_md(list(blocks.values()))


def test_rows_jsonl_is_strict_json_with_the_effect():
    import torch
    meta = _meta(ao={**AO, "rows": [{"scene": "a", "method": "m", "x": float("nan"), "y": -math.inf,
                                     "t": torch.tensor([1.5, 2.0]), "p": (1, 2)}]}, ssr=SSR)
    raw = summary.rows_jsonl(meta)
    assert sorted(raw) == ["ao", "ssr"]                                          # sections that hold rows
    line = raw["ao"].splitlines()[0]

    def reject(c):
        raise AssertionError(f"non-strict JSON constant {c}")
    row = json.loads(line, parse_constant=reject)
    assert row == {"effect": "ao", "scene": "a", "method": "m", "x": None, "y": None, "t": [1.5, 2.0], "p": [1, 2]}
    assert len(raw["ssr"].splitlines()) == 1


# ------------------------------------------------------------------------------------------ speed / tuning hooks
@pytest.mark.parametrize("key", ["speed", "tuning"])
def test_optional_section_hooks(key, tmp_path, monkeypatch):
    hook = getattr(build, f"_{key}_section")
    modname = f"ssbench.report.{key}_section"
    monkeypatch.setitem(sys.modules, modname, None)                              # import fails: ImportError
    out = hook(str(tmp_path), None, 32, 24, None, 0, False, False)
    assert not out["available"] and "ModuleNotFoundError" in out["note"] and out["note"] in out["summary_md"]
    assert out["notes"] == []
    off = hook(str(tmp_path), ["crease"], 32, 24, None, 0, False, False)         # a scene subset: off by default
    assert not off["available"] and "turned off" in off["note"] and off["summary_md"] == ""
    seen = {}
    mod = types.ModuleType(modname)

    def run(run_dir, **kw):
        seen.update(kw, run_dir=run_dir)
        return {"available": True, "note": "", "notes": [], "rows": []}
    setattr(mod, f"build_{key}_section", run)
    mod.summary_md = lambda out: f"\n## {key} ok\n"
    monkeypatch.setitem(sys.modules, modname, mod)
    monkeypatch.setattr(sys.modules["ssbench.report"], f"{key}_section", mod, raising=False)
    out = hook(str(tmp_path), ["crease"], 32, 24, True, 7, True, False)
    assert out["available"] and out["summary_md"] == f"\n## {key} ok\n"
    assert seen == {"run_dir": str(tmp_path), "width": 32, "height": 24, "seed": 7, "use_cache": True,
                    "progress": False}

    def boom(run_dir, **kw):
        raise RuntimeError("kaboom")
    setattr(mod, f"build_{key}_section", boom)
    out = hook(str(tmp_path), None, 32, 24, None, 0, False, False)
    assert not out["available"] and "kaboom" in out["note"] and "kaboom" in out["summary_md"]


# ------------------------------------------------------------------------------------------ index template
def _env(tmp_path, with_speed_template=False):
    """The report's templates without speed/tuning ones (those may or may not exist in the tree yet)."""
    d = tmp_path / "templates"
    d.mkdir(parents=True)
    for name in ("index", "ao_section", "ssr_section", "implicit_section", "inspect_macros"):
        shutil.copy(os.path.join(TEMPLATES, f"{name}.html.j2"), d)
    if with_speed_template:
        (d / "speed_section.html.j2").write_text('<h2 id="speed">Speed</h2><p>{{ speed.answer }}</p>')
    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(d)), autoescape=True,
                              undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)


def test_index_renders_without_speed_and_tuning_templates(tmp_path):
    html = render.render_index(_env(tmp_path), _meta(ao=_off("AO")))
    for key, _ in summary.SECTIONS:
        assert f'href="#sec-{key}"' in html and f'id="sec-{key}"' in html        # the table of contents works
    for target in re.findall(r'href="#([^"]+)"', html):
        assert f'id="{target}"' in html, target
    assert "Speed section turned off." in html and "Tuning section turned off." in html


def test_index_turns_a_missing_or_broken_section_template_into_a_note(tmp_path):
    meta = _meta(speed={"available": True, "note": "", "notes": [], "answer": 42},
                 tuning={"available": True, "note": "", "notes": []})
    html = render.render_index(_env(tmp_path, with_speed_template=True), meta)
    assert "<p>42</p>" in html                                                  # the speed template was used
    assert meta["tuning"]["available"] is False and "TemplateNotFound" in meta["tuning"]["note"]
    assert "Tuning section could not be shown" in html
    meta = _meta(speed={"available": True, "note": "", "notes": []})            # no "answer": StrictUndefined
    html = render.render_index(_env(tmp_path / "2", with_speed_template=True), meta)
    assert "Speed section could not be shown: UndefinedError" in html
    assert "summary failed" not in html


def test_report_cli_passes_no_speed_and_no_tuning(monkeypatch, tmp_path):
    from ssbench import cli
    seen = {}

    def fake(out, **kw):
        seen.update(kw)
        return str(tmp_path / "index.html")
    monkeypatch.setattr(build, "build_report", fake)
    assert cli.main(["report", "--out", str(tmp_path)]) == 0
    assert seen["speed"] is None and seen["tuning"] is None
    assert cli.main(["report", "--out", str(tmp_path), "--no-speed", "--no-tuning"]) == 0
    assert seen["speed"] is False and seen["tuning"] is False and seen["implicit"] is None


def test_glance_lines_say_the_size_their_rows_ran_at():
    rows = [{"scene": s, "method": "hbao", "rmse_cos": 0.1, "seconds": 1.0, "width": 320, "height": 240}
            for s in ("a", "b")]
    blocks = {b["key"]: b for b in summary.glance(_meta(ao={"available": True, "rows": rows}))}
    assert blocks["ao"]["lines"][0]["headline"] == "at 320×240, defaults: RMSE 0.1000 vs cosine GT"
    mixed = [dict(rows[0]), dict(rows[1], width=160, height=120)]              # two sizes: none is claimed
    blocks = {b["key"]: b for b in summary.glance(_meta(ao={"available": True, "rows": mixed}))}
    assert blocks["ao"]["lines"][0]["headline"].startswith("defaults: ")
