"""build_report: run dir + latest copy, relative image links that resolve, metadata, summary.md, AO section."""
import json
import os
import re

import pytest

from ssbench.report.build import PREVIEW_ROW, build_report, git_state, refresh_latest

SCENES = ["sphere_on_plane", "crease"]


@pytest.fixture(autouse=True)
def _cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("reports")
    mp = pytest.MonkeyPatch()
    mp.setenv("SSBENCH_CACHE_DIR", str(root / "cache"))
    try:
        index = build_report(str(root / "reports"), scenes=SCENES, width=48, height=36, spp=4, progress=False)
    finally:
        mp.undo()
    return root / "reports", index


@pytest.mark.slow
@pytest.mark.mitsuba
def test_run_dir_and_latest(report):
    root, index = report
    run_dir = os.path.dirname(index)
    assert os.path.isfile(index) and os.path.dirname(run_dir) == str(root)
    assert re.fullmatch(r"\d{8}-\d{6}(-\d+)?", os.path.basename(run_dir))
    latest = root / "latest"
    for d in (run_dir, latest):
        for f in ("index.html", "summary.md", "meta.json"):
            assert os.path.isfile(os.path.join(d, f)), (d, f)
    published = {".latest.lock", os.readlink(latest)}                    # latest -> .latest@<token>/
    assert not [n for n in os.listdir(root) if n.startswith(".") and n not in published]   # no temporaries


@pytest.mark.slow
@pytest.mark.mitsuba
def test_latest_images_resolve(report):
    import matplotlib.image as mimage
    latest = report[0] / "latest"
    html = (latest / "index.html").read_text()
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]+)"', html)
    assert len([s for s in srcs if not s.startswith(("img/ao/", "img/ssr/"))]) == len(SCENES) * (1 + len(PREVIEW_ROW))
    for src in srcs:
        assert not os.path.isabs(src) and "://" not in src
        path = latest / src
        assert path.is_file() and src.endswith(".png"), src
    assert mimage.imread(str(latest / srcs[0])).shape[:2] == (36, 48)
    for name in SCENES:
        assert name in html


@pytest.mark.slow
@pytest.mark.mitsuba
def test_metadata(report):
    latest = report[0] / "latest"
    meta = json.loads((latest / "meta.json").read_text())
    html = (latest / "index.html").read_text()
    summary = (latest / "summary.md").read_text()
    commit = git_state()["commit"]
    assert meta["git"]["commit"] == commit and commit in html and commit in summary
    variant = meta["environment"]["variant"]
    assert variant in ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb") and variant in html and variant in summary
    assert [s["name"] for s in meta["scenes"]] == SCENES
    for s in meta["scenes"]:
        assert s["timings"]["gbuffer_s"] > 0 and s["timings"]["color_s"] > 0
        assert f"| {s['name']} |" in summary
    for key in ("torch", "mitsuba", "drjit", "kornia", "numpy", "python", "torch_threads", "drjit_threads",
                "node", "cpu_count"):
        assert key in meta["environment"]
    assert meta["total_s"] > 0 and meta["width"] == 48 and meta["spp"] == 4
    on_disk = sum(f.stat().st_size for f in (latest / "img").rglob("*") if f.is_file()) / 1e6
    assert meta["images_mb"] == pytest.approx(on_disk) and on_disk > 0          # the page weight it states
    assert f"{meta['images_mb']:.1f} MB" in html and "page weight (images)" in summary


@pytest.mark.slow
@pytest.mark.mitsuba
def test_previews_from_the_cache_keep_their_recorded_times(tmp_path, monkeypatch):
    from ssbench.report.build import render_scene
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))
    _, cold = render_scene("crease", 32, 24, spp=4)
    _, warm = render_scene("crease", 32, 24, spp=4)
    _, fresh = render_scene("crease", 32, 24, spp=4, use_cache=False)
    assert not cold["gbuffer_cached"] and not cold["color_cached"] and cold["color_s"] > 0
    assert warm["gbuffer_cached"] and warm["color_cached"]
    assert warm["gbuffer_s"] == cold["gbuffer_s"] and warm["color_s"] == cold["color_s"]   # recorded, not re-timed
    assert not fresh["color_cached"] and fresh["color_s"] > 0


def test_refresh_latest_replaces_previous_copy(tmp_path):
    root = tmp_path / "r"
    for run, text in (("a", "first"), ("b", "second")):
        os.makedirs(root / run / "img")
        (root / run / "index.html").write_text(text)
        (root / run / "img" / f"{run}.png").write_text(run)
        refresh_latest(str(root / run), str(root))
        assert (root / "latest" / "index.html").read_text() == text
    assert sorted(os.listdir(root / "latest" / "img")) == ["b.png"]         # a full copy, not a merge
    assert sorted(n for n in os.listdir(root) if not n.startswith(".")) == ["a", "b", "latest"]
    # latest -> .latest@<b>; the previous copy .latest@<a> is kept until the next swap (readers mid-page)
    assert os.path.islink(root / "latest") and len([n for n in os.listdir(root) if n.startswith(".latest@")]) == 2


def test_unknown_scene_is_rejected_before_rendering(tmp_path):
    with pytest.raises(ValueError, match="scenes: unknown"):
        build_report(str(tmp_path / "x"), scenes=["nope"])
    assert not (tmp_path / "x").exists()


def test_git_state_outside_a_repo(tmp_path):
    assert git_state(str(tmp_path)) == {"commit": "unknown", "dirty": None}


# ------------------------------------------------------------------------------------------ AO section
@pytest.mark.slow
@pytest.mark.mitsuba
def test_ao_section_in_the_report(report):
    import matplotlib.image as mimage
    latest = report[0] / "latest"
    meta = json.loads((latest / "meta.json").read_text())
    html = (latest / "index.html").read_text()
    ao = meta["ao"]
    assert "Ambient occlusion" in html and "Ambient occlusion" in (latest / "summary.md").read_text()
    if not ao["available"]:                                                # passes still being written
        assert ao["note"] and ao["note"] in html
        return
    assert [s["name"] for s in ao["scenes"]] == SCENES                     # the report's own scene list
    assert {(r["scene"], r["method"]) for r in ao["rows"]} == {(s, m) for s in SCENES for m in ao["methods"]}
    for r in ao["rows"]:
        assert r["width"] == 48 and r["height"] == 36 and r["radius"] == 0.5 and r["nonfinite"] == 0
    srcs = [s for s in re.findall(r'<img[^>]*\ssrc="([^"]+)"', html) if s.startswith("img/ao/")]
    per_method = sum(5 + (r["weighting"] != "cosine") + 2 for r in ao["rows"])   # AO, errors, ꟻLIP, residual,
    #                                                                      spectrum
    for r in ao["rows"]:                                                   # + the A/B compare: method over its GT
        pair = re.findall(rf'<img class="b" src="img/ao/{r["scene"]}/gt_{r["weighting"]}\.png"[^>]*>\s*'
                          rf'<div class="a-wrap"><img class="a" src="img/ao/{r["scene"]}/{r["method"]}\.png"', html)
        assert len(pair) == 1, (r["scene"], r["method"])
    bars = [s for s in srcs if s.startswith("img/ao/colorbar_")]           # error, noise, ꟻLIP scales per scene
    assert len(bars) == 3 * len(SCENES) and set(bars) == set(ao["colorbars"].values())
    assert len(srcs) == len(SCENES) * 11 + per_method                      # GT x5, oracle, 2 regions, 3 bars
    bar = mimage.imread(str(latest / ao["colorbars"]["error"]))
    assert bar.shape[1] > 3 * bar.shape[0] and bar[..., :3].std() > 0.1    # a wide, coloured bar
    for src in srcs:
        assert (latest / src).is_file(), src
    assert mimage.imread(str(latest / srcs[0])).shape[:2] == (36, 48)
    for m in ao["methods"]:
        assert f"<strong>{m}</strong>" in html


def _stub_ao(monkeypatch, fail_scene=None):
    """Stub method registry + reference so the AO section runs in a blink without Mitsuba."""
    import dataclasses
    import sys
    import types

    import torch

    from ssbench import passes, reference
    from ssbench.camera import Camera
    from ssbench.gbuffer import GBuffer

    @dataclasses.dataclass(frozen=True)
    class P:
        radius: float = 0.3

    mod = types.ModuleType("ssbench_report_stub_ao")

    def stub(gbuffer, params, *, generator=None, debug=False):
        return passes.AOResult(torch.where(gbuffer.mask, 0.5, 1.0))

    stub.__module__ = mod.__name__
    mod.stub, mod.P, mod.REQUIRES = stub, P, ("view_z", "mask")
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setattr(passes, "AO_METHODS", {"stub": f"{mod.__name__}:stub:P",
                                               "missing": "ssbench_no_such_module:f:P"})
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, 16, 12, 0.1, 100.0)
    mask = torch.ones(1, 1, 12, 16, dtype=torch.bool)
    z = torch.full((1, 1, 12, 16), -5.0)
    z[..., 8:] = -9.0

    def gbuffer(scene, w=None, h=None, channels=None, **k):
        if getattr(scene, "name", scene) == fail_scene:
            raise RuntimeError("renderer exploded")
        return GBuffer(cam, view_z=z, position=cam.uv_to_view(cam.uv_grid()[None], z), mask=mask,
                       normal=torch.tensor([0.0, 0.0, 1.0]).view(1, 3, 1, 1).expand(1, 3, 12, 16).contiguous())

    def gt(*a, weighting="cosine", **k):
        return reference.AOReference(torch.full((1, 1, 12, 16), 0.75), torch.zeros(1, 1, 12, 16), weighting,
                                     0.5, 4)

    monkeypatch.setattr(reference, "gbuffer", gbuffer)
    monkeypatch.setattr(reference, "ambient_occlusion",
                        lambda sc, g, r, rays=256, weighting="cosine", seed=0, **k: gt(weighting=weighting))
    monkeypatch.setattr(reference, "screen_space_oracle",
                        lambda g, r, rays=256, weighting="cosine", seed=0, **k: gt(weighting=weighting))


def _render_section(ao: dict) -> str:
    import jinja2

    from ssbench.report import build, render
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(build.__file__),
                                                                         "templates")),
                             autoescape=True, undefined=jinja2.StrictUndefined)
    return env.get_template("ao_section.html.j2").render(ao=ao, fmt=render.fmt)


def test_ao_section_with_stubs(tmp_path, monkeypatch):
    from ssbench.report.ao_section import build_ao_section, summary_md
    _stub_ao(monkeypatch, fail_scene="stairs")
    ao = build_ao_section(str(tmp_path), ["crease", "stairs"], 16, 12, radius=0.5, rays=4, progress=False)
    assert ao["available"] and ao["methods"] == ["stub"] and [s["name"] for s in ao["scenes"]] == ["crease"]
    assert any("missing skipped" in n for n in ao["notes"])                # an unimportable pass is a note
    assert any("stairs skipped" in n and "renderer exploded" in n for n in ao["notes"])
    row = ao["rows"][0]
    assert row["radius"] == 0.5 and row["params"] == {"radius": 0.5}       # the report's radius, shared
    assert row["over_darkening_cos"] == pytest.approx(2.0) and row["rmse_cos"] == pytest.approx(0.25)
    html = _render_section(ao)
    assert "<strong>stub</strong>" in html and "missing skipped" in html and "renderer exploded" in html
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]+)"', html)
    assert len(srcs) == 8 + 5 + 3 + 2 and all((tmp_path / s).is_file() for s in srcs)   # cosine: one error map;
    #                                                                      ꟻLIP map; 3 bars; the compare pair
    assert "| stub | 0.2500" in summary_md(ao)


def test_ao_section_skips_without_the_reference(tmp_path, monkeypatch):
    from ssbench import reference
    from ssbench.report.ao_section import build_ao_section, summary_md
    monkeypatch.delattr(reference, "ambient_occlusion")
    ao = build_ao_section(str(tmp_path), ["crease"], 16, 12, progress=False)
    assert not ao["available"] and "reference AO is not importable" in ao["note"]
    import html
    assert html.escape(ao["note"]).replace("&#x27;", "&#39;") in _render_section(ao) and ao["note"] in summary_md(ao)
    assert not os.listdir(tmp_path)


def test_ao_section_skips_without_passes(tmp_path, monkeypatch):
    from ssbench import passes
    from ssbench.report.ao_section import build_ao_section
    monkeypatch.setattr(passes, "AO_METHODS", {"gone": "ssbench_no_such_module:f:P"})
    ao = build_ao_section(str(tmp_path), ["crease"], 16, 12, progress=False)
    assert not ao["available"] and "no AO method is importable" in ao["note"]
    assert any("gone skipped" in n for n in ao["notes"])
    assert "no AO method is importable" in _render_section(ao)


def test_ao_section_failure_never_crashes_the_report(tmp_path, monkeypatch):
    from ssbench.report import ao_section, build

    def boom(*a, **k):
        raise RuntimeError("kaboom")
    monkeypatch.setattr(ao_section, "build_ao_section", boom)
    out = build._ao_section(str(tmp_path), None, 16, 12, True, 0.5, 4, 0, False, False)
    assert not out["available"] and "kaboom" in out["note"] and "kaboom" in out["summary_md"]
    off = build._ao_section(str(tmp_path), None, 16, 12, False, 0.5, 4, 0, False, False)
    assert not off["available"] and off["summary_md"] == ""
    assert "turned off" in _render_section(off)


# ------------------------------------------------------------------------------------------ SSR section
@pytest.mark.slow
@pytest.mark.mitsuba
def test_ssr_section_in_the_report(report):
    latest = report[0] / "latest"
    meta = json.loads((latest / "meta.json").read_text())
    html = (latest / "index.html").read_text()
    ssr = meta["ssr"]
    assert "Screen-space reflections" in html and "Screen-space reflections" in (latest / "summary.md").read_text()
    if not ssr["available"]:                                               # passes still being written
        assert ssr["note"] and ssr["note"] in html
        return
    assert [s["name"] for s in ssr["scenes"]] == SCENES
    for src in re.findall(r'<img[^>]*\ssrc="(img/ssr/[^"]+)"', html):
        assert (latest / src).is_file(), src
    for r in ssr["rows"]:
        assert r["width"] == 48 and r["nonfinite"] == 0


def _stub_ssr(monkeypatch, fail_scene=None, visits=True):
    """Stub SSR registry + reference so the SSR section runs in a blink without Mitsuba."""
    import dataclasses
    import sys
    import types

    import torch

    from ssbench import passes, reference
    from ssbench.camera import Camera
    from ssbench.gbuffer import GBuffer
    from ssbench.passes.ssr.common import HIT, MAX_DISTANCE, SSRResult

    @dataclasses.dataclass(frozen=True)
    class P:
        thickness: float = 0.1

    @dataclasses.dataclass(frozen=True)
    class Truth:
        valid: torch.Tensor
        hit: torch.Tensor
        hit_view: torch.Tensor
        hit_pixel: torch.Tensor
        on_screen: torch.Tensor
        visible: torch.Tensor
        back_face: torch.Tensor
        hit_shape: torch.Tensor
        radiance: torch.Tensor
        seconds: float = 0.1

    H, W = 12, 16
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, W, H, 0.1, 100.0)
    mask = torch.ones(1, 1, H, W, dtype=torch.bool)
    z = torch.full((1, 1, H, W), -5.0)
    full = GBuffer(cam, view_z=z, position=cam.uv_to_view(cam.uv_grid()[None], z), mask=mask,
                   normal=torch.tensor([0.0, 1.0, 0.0]).view(1, 3, 1, 1).expand(1, 3, H, W).contiguous(),
                   color=torch.full((1, 3, H, W), 0.5), shape_id=torch.zeros(1, 1, H, W, dtype=torch.int32),
                   roughness=torch.zeros(1, 1, H, W), metallic=torch.ones(1, 1, H, W))   # a mirror: all specular
    top = torch.zeros_like(mask)
    top[..., : H // 2, :] = True
    off = mask & ~top
    px = cam.pixel_centers()[None]
    truth = Truth(valid=mask, hit=mask.clone(), hit_view=full.position - 1, hit_pixel=px, on_screen=top.clone(),
                  visible=top.clone(), back_face=torch.zeros_like(mask), hit_shape=torch.ones_like(z).int(),
                  radiance=torch.full((1, 3, H, W), 0.5))
    mod = types.ModuleType("ssbench_report_stub_ssr")

    def stub(gbuffer, params, *, generator=None, debug=False):
        hit = top.clone()
        hit[..., :2, :] = False                                             # two rows missed
        hit |= off & (torch.arange(W) < 4)                                  # a hit on an off-screen target
        raw = torch.where(hit, gbuffer.color, 0.0)
        dbg = {"visits": torch.arange(H * W).reshape(1, 1, H, W) % 3} if debug and visits else {}
        return SSRResult(color=raw * 0.5, hit=hit, hit_pixel=torch.where(hit, px, -1.0),
                         hit_view=torch.where(hit, truth.hit_view, 0.0), steps=torch.ones_like(z).int(),
                         termination=torch.where(hit, HIT, MAX_DISTANCE).to(torch.int8),
                         fade=torch.full_like(z, 0.5), raw_color=raw, debug=dbg)

    stub.__module__ = mod.__name__
    mod.stub, mod.P, mod.REQUIRES = stub, P, ("view_z", "normal", "mask", "color")
    mod.DEBUG_VIEWS = {"visits": "fetches"}
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setattr(passes, "SSR_METHODS", {"stub": f"{mod.__name__}:stub:P",
                                                "missing": "ssbench_no_such_module:f:P"})
    calls = []

    def gbuffer(scene, w=None, h=None, channels=None, **k):
        calls.append(getattr(scene, "name", scene))
        if getattr(scene, "name", scene) == fail_scene:
            raise RuntimeError("renderer exploded")
        return full.select(tuple(channels))

    monkeypatch.setattr(reference, "gbuffer", gbuffer)
    monkeypatch.setattr(reference, "reflections", lambda sc, g, **k: truth, raising=False)
    return full, calls


def _render_ssr_section(ssr: dict) -> str:
    import jinja2

    from ssbench.report import build, render
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(build.__file__),
                                                                         "templates")),
                             autoescape=True, undefined=jinja2.StrictUndefined)
    return env.get_template("ssr_section.html.j2").render(ssr=ssr, fmt=render.fmt)


def test_ssr_section_with_stubs(tmp_path, monkeypatch):
    from ssbench.report.ssr_section import build_ssr_section, summary_md
    full, calls = _stub_ssr(monkeypatch, fail_scene="fence")
    ssr = build_ssr_section(str(tmp_path), None, 16, 12, spp=2, progress=False)
    assert ssr["available"] and ssr["methods"] == ["stub"]
    assert [s["name"] for s in ssr["scenes"]] == ["reflective_floor"] and calls == ["reflective_floor", "fence"]
    assert any("missing skipped" in n for n in ssr["notes"])                 # an unimportable pass is a note
    assert any("fence skipped" in n and "renderer exploded" in n for n in ssr["notes"])
    row = ssr["rows"][0]
    n = 16 * 12
    assert row["frac_correct"] == pytest.approx(4 * 16 / n) and row["frac_missed"] == pytest.approx(2 * 16 / n)
    assert row["frac_off_screen_target"] + row["frac_unfixable_hit"] == pytest.approx(0.5)   # half off screen
    assert row["frac_off_screen_target_pass_hit"] == row["frac_unfixable_hit"] == pytest.approx(6 * 4 / n)
    assert row["frac_unfixable"] == pytest.approx(0.5)
    s = ssr["scenes"][0]
    assert s["truth_cells"]["correct"] == "50.0%" and s["methods"][0]["views"] == [{"key": "visits", "caption": "fetches", "max": 2}]
    html = _render_ssr_section(ssr)
    assert "<strong>stub</strong>" in html and "missing skipped" in html and "renderer exploded" in html
    assert "punch-through" in html and "back-face target" in html and "pixelZSize" in html
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]+)"', html)
    assert len(srcs) == 2 + 4 + 2 and all((tmp_path / src).is_file() for src in srcs)   # + the compare pair
    assert re.search(r'<img class="b" src="img/ssr/reflective_floor/truth.png"[^>]*>\s*<div class="a-wrap"><img class="a" '
                     r'src="img/ssr/reflective_floor/stub.png"', html)
    assert 'data-width="16" style="--w: 16; --h: 12"' in html
    assert html.count('class="ev"') == len(ssr["scenes"][0]["methods"])     # colour compares get a display exposure
    older = {**ssr, "scenes": [{k: v for k, v in sc.items() if k not in ("width", "height")} for sc in ssr["scenes"]]}
    assert 'class="compare" data-width=""' in _render_ssr_section(older)     # a run from before sizes were kept
    import matplotlib.image as mimage
    assert mimage.imread(str(tmp_path / srcs[0])).shape[:2] == (12, 16)
    assert ssr["thickness"]["rows"][0]["cells"][0] == "0.1"                  # kode80: the slab itself
    assert "| stub | 33.3% / 16.7%" in summary_md(ssr)


def test_ssr_section_reuses_report_gbuffers_and_notes_missing_visits(tmp_path, monkeypatch):
    from ssbench.report.ssr_section import build_ssr_section
    full, calls = _stub_ssr(monkeypatch, visits=False)
    ssr = build_ssr_section(str(tmp_path), ["fence"], 16, 12, progress=False, gbuffers={"fence": full})
    assert ssr["available"] and calls == []                                  # no second render
    assert any("declares debug view 'visits' but debug['visits'] is missing" in n for n in ssr["scenes"][0]["notes"])
    assert "visits (max" not in _render_ssr_section(ssr)


def test_ssr_section_skips_without_the_reference(tmp_path, monkeypatch):
    from ssbench import reference
    from ssbench.report.ssr_section import build_ssr_section, summary_md
    monkeypatch.delattr(reference, "reflections", raising=False)
    ssr = build_ssr_section(str(tmp_path), ["fence"], 16, 12, progress=False)
    assert not ssr["available"] and "reference reflections are not importable" in ssr["note"]
    import html
    assert html.escape(ssr["note"]).replace("&#x27;", "&#39;") in _render_ssr_section(ssr)
    assert ssr["note"] in summary_md(ssr) and not os.listdir(tmp_path)


def test_ssr_section_skips_without_passes(tmp_path, monkeypatch):
    from ssbench import passes
    from ssbench.report.ssr_section import build_ssr_section
    _stub_ssr(monkeypatch)
    monkeypatch.setattr(passes, "SSR_METHODS", {"gone": "ssbench_no_such_module:f:P"})
    ssr = build_ssr_section(str(tmp_path), ["fence"], 16, 12, progress=False)
    assert not ssr["available"] and "no SSR method is importable" in ssr["note"]
    assert any("gone skipped" in n for n in ssr["notes"])
    html = _render_ssr_section(ssr)
    assert "no SSR method is importable" in html and "gone skipped" in html


def test_ssr_section_failure_never_crashes_the_report(tmp_path, monkeypatch):
    from ssbench.report import build, ssr_section

    def boom(*a, **k):
        raise RuntimeError("kaboom")
    monkeypatch.setattr(ssr_section, "build_ssr_section", boom)
    out = build._ssr_section(str(tmp_path), None, 16, 12, True, 2, 0, False, {}, False)
    assert not out["available"] and "kaboom" in out["note"] and "kaboom" in out["summary_md"]
    off = build._ssr_section(str(tmp_path), None, 16, 12, False, 2, 0, False, {}, False)
    assert not off["available"] and off["summary_md"] == ""
    assert "turned off" in _render_ssr_section(off)


def test_report_cli_passes_no_ssr(monkeypatch, tmp_path, capsys):
    from ssbench import cli
    from ssbench.report import build
    seen = {}

    def fake(out, **kw):
        seen.update(kw)
        return str(tmp_path / "index.html")
    monkeypatch.setattr(build, "build_report", fake)
    assert cli.main(["report", "--out", str(tmp_path), "--no-ssr", "--ssr-spp", "8"]) == 0
    assert seen["ssr"] is False and seen["ssr_spp"] == 8 and seen["ao"] is True


def test_ssr_section_scores_specular_pixels_only(tmp_path, monkeypatch):
    """Rough, non-metal pixels get no SSR in a renderer, so the report must not count them as misses."""
    from ssbench import evaluate
    from ssbench.report.ssr_section import build_ssr_section
    _stub_ssr(monkeypatch, fail_scene="fence")
    seen = []
    real = evaluate.run_ssr

    def spy(*a, **k):
        seen.append(k.get("reflective"))
        return real(*a, **k)

    monkeypatch.setattr(evaluate, "run_ssr", spy)
    ssr = build_ssr_section(str(tmp_path), ["reflective_floor"], 16, 12, spp=2, progress=False)
    assert ssr["available"] and seen == ["specular"]
    assert ssr["rows"][0]["reflective"] == "specular"


@pytest.mark.slow
def test_a_run_re_renders_from_its_meta_without_computing(report, monkeypatch):
    from pathlib import Path
    from ssbench import reference
    from ssbench.cli import main
    from ssbench.report.render import render_run
    out, index = report
    run = Path(index).parent
    html, md = (run / "index.html").read_text(), (run / "summary.md").read_text()
    monkeypatch.setattr(reference, "gbuffer", lambda *a, **k: pytest.fail("render_run must not render"))
    (run / "index.html").unlink()
    (run / "summary.md").unlink()
    assert render_run(str(run)) == str(run / "index.html")
    assert (run / "index.html").read_text() == html and (run / "summary.md").read_text() == md
    meta = json.loads((run / "meta.json").read_text())
    del meta["calibration"]                                              # a run from before the section existed
    old = out / "old-run"
    old.mkdir()
    (old / "meta.json").write_text(json.dumps(meta))
    render_run(str(old))
    assert "Metric calibration section not in this run." in (old / "index.html").read_text()
    assert main(["report", "--out", str(out), "--from", "old-run"]) == 0
