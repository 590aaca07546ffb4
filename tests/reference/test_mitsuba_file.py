"""Mitsuba 3 scene files loaded by Mitsuba itself: camera, G-buffer, every pass and every reference on them."""
import json
import math
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest
import torch

from ssbench import scenes
from ssbench.passes import AO_METHODS, SSR_METHODS, ao_method, ssr_method
from ssbench.reference import backend
from ssbench.reference.gbuffer import gbuffer
from ssbench.reference.mitsuba_file import SceneNote, load_xml, objects
from ssbench.scenes import SceneError

from tests.reference import mitsuba_scene_files as files

pytestmark = pytest.mark.mitsuba


@pytest.fixture(scope="module")
def mi():
    return backend.mitsuba()


@pytest.fixture(scope="module")
def built(tmp_path_factory, mi):
    root = tmp_path_factory.mktemp("mitsuba_files")
    out = {}
    for name, build in (("cbox", files.cornell_box), ("pile", files.mesh_pile), ("matrix", files.matrix_sensor)):
        (root / name).mkdir()
        out[name] = build(root / name)
    return out


def load_quiet(path, defines=()):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneNote)
        return scenes.load(path, defines)


def reprojection_px(gb) -> float:
    """Largest distance, in pixels, between a hit's projected G-buffer position and its own pixel centre."""
    cam = gb.camera
    px = cam.view_to_pixel(gb.position.double())
    centre = cam.uv_to_pixel(cam.uv_grid(torch.float64).unsqueeze(0))
    return float((px - centre).abs().amax(1, keepdim=True)[gb.mask].max())


@pytest.mark.parametrize("name", ["cbox", "pile", "matrix"])
def test_positions_reproject_to_their_pixel_centres(built, name):
    sc = load_quiet(built[name])
    gb = gbuffer(sc, use_cache=False)
    assert (gb.camera.width, gb.camera.height) == {"cbox": (96, 72), "pile": (80, 60), "matrix": (72, 54)}[name]
    assert gb.mask.float().mean() > 0.5
    assert reprojection_px(gb) <= 1e-3
    hit_ids = set(gb.shape_id[gb.mask].tolist())
    assert len(hit_ids) >= {"cbox": 7, "pile": 60, "matrix": 4}[name]
    assert all(0 <= i < len(sc.shapes) for i in hit_ids)


def test_the_rebuilt_scene_hits_what_mitsuba_hits_through_the_files_own_sensor(built, mi):
    """Mitsuba's own load of the file, traced through its own sensor, against our G-buffer: same shapes, same
    points (the camera recovered from a <matrix> reproduces Mitsuba's rays)."""
    import drjit as dr
    sc = load_quiet(built["matrix"])
    gb = gbuffer(sc, use_cache=False)
    orig = mi.load_file(str(built["matrix"]), optimize=False)
    W, H = gb.camera.width, gb.camera.height
    idx = dr.arange(mi.UInt32, W * H)
    pos = mi.Point2f((mi.Float(idx % W) + 0.5) / W, (mi.Float(idx // W) + 0.5) / H)
    ray, _ = orig.sensors()[0].sample_ray(0.0, 0.0, pos, mi.Point2f(0.5, 0.5))
    si = orig.ray_intersect(ray)
    hit = si.is_valid().torch().bool().reshape(H, W)
    assert torch.equal(hit, gb.mask[0, 0])
    names = [s.id() for s in orig.shapes()]
    want = torch.tensor([names.index(n) if n in names else -1 for n in [sh.id for sh in sc.shapes]])
    rid = np.asarray(dr.reinterpret_array(mi.UInt32, si.shape).numpy())
    table = {int(r): k for k, r in enumerate(dr.reinterpret_array(mi.UInt32, orig.shapes_dr()).numpy())}
    theirs = torch.tensor([table.get(int(r), -1) for r in rid]).reshape(H, W)
    ours = gb.shape_id[0, 0].long()
    assert torch.equal(torch.where(hit, want[ours.clamp_min(0)], -1), torch.where(hit, theirs, -1)), (names, want)
    pw = torch.stack([si.p.x.torch(), si.p.y.torch(), si.p.z.torch()]).double().reshape(3, H, W)
    ours_w = gb.camera.view_to_world(gb.position[0].double(), dim=0)
    assert float((pw - ours_w).abs().amax(0)[hit].max()) < 1e-4


def test_cornell_box_materials_notes_and_defaults(built):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sc = scenes.load(built["cbox"], {"res": "128", "max_depth": "3"})
    notes = [str(w.message) for w in caught if w.category is SceneNote]
    assert notes == list(dict(sc.extra)["notes"])
    for word in ("focus_distance", "sampler", "rfilter", "pixel_format", "integrator"):
        assert any(word in n for n in notes), (word, notes)
    cam = sc.camera
    assert (cam.width, cam.height) == (128, 72)                        # -D res=128 over the $res default
    assert cam.fovy_deg == pytest.approx(39.3077, abs=1e-4)              # fov_axis smaller = y at 128x72
    assert cam.eye == pytest.approx((0.0, 0.0, 4.1), abs=1e-6) and sc.max_depth == 3
    mats = {s.id: s.material for s in sc.shapes}
    assert mats["redwall"].albedo == pytest.approx((0.570068, 0.0430135, 0.0443706), abs=1e-6)
    assert (mats["redwall"].roughness, mats["redwall"].metallic) == (1.0, 0.0)
    assert mats["tallbox"].albedo == pytest.approx((0.7, 0.7, 0.2), abs=1e-6)
    assert (mats["tallbox"].roughness, mats["tallbox"].metallic) == pytest.approx((0.3, 0.5))
    assert load_quiet(built["cbox"]).content_hash() != sc.content_hash()


def test_textured_albedo_is_looked_up_at_each_hit(built):
    sc = load_quiet(built["matrix"])
    gb = gbuffer(sc, use_cache=False)
    on = gb.shape_id[0, 0] == sc.shape_index("poster")
    texels = torch.unique(gb.albedo[0][:, on].T, dim=0)
    srgb = lambda c: ((c / 255 + 0.055) / 1.055) ** 2.4                                      # noqa: E731
    expected = torch.tensor([[srgb(c) for c in rgb] for rgb in files.STRIPES], dtype=torch.float32)
    assert texels.shape == (2, 3)
    assert torch.allclose(texels.sort(0).values, expected.sort(0).values, atol=1e-3)
    crate = gb.albedo[0][:, gb.shape_id[0, 0] == sc.shape_index("crate")]
    assert torch.allclose(crate, torch.tensor([[0.3], [0.5], [0.7]]), atol=1e-6)     # a constant, by table


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cbox", "pile", "matrix"])
def test_every_ao_and_ssr_method_and_reference_runs(built, name):
    from ssbench import evaluate
    sc = load_quiet(built[name])
    for method in AO_METHODS:
        row = evaluate.ao(sc, method, width=48, height=36, rays=16, repeats=1, use_cache=False)
        assert row["nonfinite"] == 0 and 0.0 <= row["rmse_flavour"] <= 1.0, (method, row["rmse_flavour"])
        fn, params_cls, _ = ao_method(method)
        assert fn is not None and params_cls is not None
    for method in SSR_METHODS:
        row = evaluate.ssr(sc, method, width=48, height=36, spp=2, repeats=1, use_cache=False)
        assert row["nonfinite"] == 0 and row["reflective_pixels"] > 0, (method, row)
        assert math.isfinite(row["rmse_raw"]) and 0.0 <= row["frac_correct"] <= 1.0, (method, row)
        assert ssr_method(method)[0] is not None


def test_colour_uses_the_files_own_emitters(built):
    """The envmap is the only light of the pile: background pixels are its radiance (the upper or the darker
    lower half of the map, as the pixel's ray points)."""
    sc = load_quiet(built["pile"])
    gb = gbuffer(sc, channels=("mask", "color"), spp=4, use_cache=False)
    clear = torch.nn.functional.max_pool2d(gb.mask.float(), 3, 1, 1)[0, 0] == 0    # no geometry next to it either
    sky = gb.color[0][:, clear]                                         # (the colour is filtered over the pixel)
    assert sky.shape[1] > 10
    upper = torch.tensor([[0.6], [0.7], [0.9]])
    near = lambda ref: (sky - ref).abs().amax(0) < 2e-3                                     # noqa: E731
    assert float((near(upper) | near(0.25 * upper)).float().mean()) > 0.9      # the map's texels themselves
    assert bool(((sky >= 0.25 * upper - 2e-3) & (sky <= upper + 2e-3)).all())     # and between them (filtered)
    cbox = load_quiet(built["cbox"])
    g2 = gbuffer(cbox, 256, 192, channels=("mask", "shape_id", "color"), spp=4, use_cache=False)
    on = (g2.shape_id == cbox.shape_index("light")).float()
    inside = -torch.nn.functional.max_pool2d(-on, 3, 1, 1)[0, 0] == 1                # away from the lamp's edge
    lamp, radiance = g2.color[0][:, inside], torch.tensor([[18.387], [13.9873], [6.75357]])
    assert lamp.shape[1] > 0                               # its emission, plus what its diffuse face reflects
    assert bool(((lamp >= radiance * 0.999) & (lamp <= radiance * 1.15)).all()), lamp


def test_mitsubas_own_errors_come_back_as_one_line(tmp_path):
    p = tmp_path / "bad.xml"
    p.write_text('<scene version="3.0.0">\n  <shape type="torus"/>\n</scene>\n')
    with pytest.raises(SceneError) as e:
        load_xml(p)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{p}: Mitsuba could not load the scene") and "torus" in msg
    p.write_text('<scene version="3.0.0"><shape type="sphere"/></scene>')
    with pytest.raises(SceneError, match="no sensor"):
        load_xml(p)


def test_a_changed_file_is_refused_until_loaded_again(tmp_path, built):
    folder = tmp_path / "copy"
    shutil.copytree(built["cbox"].parent, folder)
    sc = load_quiet(folder / "cbox.xml")
    objects(sc.mitsuba)
    with open(folder / "meshes" / "floor.obj", "a") as f:
        f.write("# edited\n")
    with pytest.raises(SceneError, match="changed since it was loaded"):
        objects(sc.mitsuba)


@pytest.mark.parametrize("axis,w,h,tan_ratio", [("x", 80, 60, 60 / 80), ("y", 80, 60, 1.0),
                                                ("smaller", 60, 90, 90 / 60), ("larger", 60, 90, 1.0),
                                                ("diagonal", 80, 60, 60 / 100)])
def test_fov_axis_becomes_the_vertical_fov(tmp_path, axis, w, h, tan_ratio):
    p = tmp_path / "fov.xml"
    p.write_text(f'<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="50"/>'
                 f'<string name="fov_axis" value="{axis}"/><film type="hdrfilm"><integer name="width" value="{w}"/>'
                 f'<integer name="height" value="{h}"/></film></sensor><shape type="sphere"/></scene>')
    cam = load_quiet(p).camera
    assert math.tan(math.radians(cam.fovy_deg) / 2) == pytest.approx(math.tan(math.radians(25)) * tan_ratio,
                                                                     rel=1e-5)


def test_cli_runs_a_mitsuba_file_with_overrides_and_prints_notes_as_one_line_each(built):
    r = subprocess.run([sys.executable, "-m", "ssbench", "ao", str(built["cbox"]), "-D", "res=64", "--method",
                        "gtao", "--width", "32", "--height", "24", "--rays", "8", "--repeats", "1", "--json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    notes = [line for line in r.stderr.splitlines() if line.startswith("ssbench: note: ")]
    assert any("focus_distance" in n for n in notes), r.stderr
    assert "Traceback" not in r.stderr
    assert json.loads(r.stdout)["method"] == "gtao"
    r = subprocess.run([sys.executable, "-m", "ssbench", "ao", str(built["cbox"]), "-D", "res=abc", "--method",
                        "gtao"], capture_output=True, text=True, timeout=600)
    lines = r.stderr.strip().splitlines()
    assert r.returncode != 0 and lines[-1].startswith("ssbench: error: ") and "Traceback" not in r.stderr


@pytest.mark.slow
def test_report_adds_the_users_scene_files_to_its_sections(built, tmp_path):
    from ssbench.report.build import build_report
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneNote)
        index = build_report(str(tmp_path / "reports"), scenes=["sphere_on_plane"], width=48, height=36, spp=2,
                             ao_rays=8, ssr_spp=2, progress=False, implicit=False, speed=False, tuning=False,
                             calibration=False, extra_scenes=[built["cbox"], built["pile"], built["matrix"]])
    meta = json.loads((tmp_path / "reports" / "latest" / "meta.json").read_text())
    names = ["sphere_on_plane", "cbox", "pile", "matrix"]
    assert [s["name"] for s in meta["scenes"]] == names
    assert [u["file"] for u in meta["user_scenes"]] == [str(built[k].resolve()) for k in ("cbox", "pile", "matrix")]
    for section in ("ao", "ssr"):
        assert [s["name"] for s in meta[section]["scenes"]] == names, (section, meta[section]["notes"])
        assert not any("skipped" in n for n in meta[section]["notes"]), meta[section]["notes"]
    html = open(index, encoding="utf-8").read()
    assert all(f"img/ao/{n}/" in html and f"img/ssr/{n}/" in html for n in names[1:])


def test_user_scene_names_never_shadow_the_catalog(built, tmp_path):
    from ssbench.report.build import user_scenes
    shutil.copytree(built["matrix"].parent / "parts", tmp_path / "parts")
    clash = tmp_path / "fence.xml"                                      # named like a catalog scene
    clash.write_text(built["matrix"].read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneNote)
        got = user_scenes([clash, built["matrix"], built["matrix"]], ["fence", "stairs"])
    assert [s.name for s in got] == ["file_fence", "matrix", "file_matrix"]
