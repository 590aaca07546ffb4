"""The ssbench command: info, scenes, render (files and values), argument errors, python -m ssbench."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from ssbench.cli import main
from ssbench.gbuffer import CHANNELS
from ssbench.scenes import catalog


@pytest.fixture(autouse=True)
def _cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))


def test_scenes_table_and_json(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    for name, desc in catalog.describe().items():
        assert name in out and desc in out
    assert main(["scenes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows] == catalog.names()


@pytest.mark.mitsuba
def test_info_text_and_json(capsys):
    assert main(["info"]) == 0
    out = capsys.readouterr().out
    for key in ("ssbench", "torch", "kornia", "numpy", "mitsuba variant", "libLLVM", "drjit", "probe attempts"):
        assert key in out
    assert main(["info", "--json"]) == 0
    env = json.loads(capsys.readouterr().out)
    assert env["variant"] in ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
    for key in ("ssbench", "python", "torch", "torch_threads", "kornia", "numpy", "mitsuba", "drjit",
                "drjit_threads", "libllvm", "libllvm_major", "probe"):
        assert key in env
    assert isinstance(env["probe"], list)


@pytest.mark.slow
@pytest.mark.mitsuba
def test_render_writes_every_channel(tmp_path, capsys):
    from ssbench.reference import backend, gbuffer
    out = tmp_path / "out"
    rc = main(["render", "sphere_on_plane", "--out", str(out), "--width", "32", "--height", "24", "--spp", "4"])
    assert rc == 0, capsys.readouterr().err
    for ch in CHANNELS:
        assert (out / f"{ch}.exr").is_file() and (out / f"{ch}.png").is_file()
    meta = json.loads((out / "meta.json").read_text())
    assert meta["scene"] == "sphere_on_plane" and meta["channels"] == list(CHANNELS)
    assert meta["camera"]["width"] == 32 and meta["spp"] == 4 and meta["seed"] == 0
    assert meta["timings"]["gbuffer_s"] > 0 and meta["backend"]["variant"]
    mi = backend.mitsuba()
    z = np.array(mi.Bitmap(str(out / "view_z.exr")))
    z = z[..., 0] if z.ndim == 3 else z
    ref = gbuffer("sphere_on_plane", 32, 24, channels=["view_z"]).view_z[0, 0].numpy()
    np.testing.assert_array_equal(z, ref)
    import matplotlib.image as mimage
    assert mimage.imread(str(out / "color.png")).shape[:2] == (24, 32)


@pytest.mark.slow
@pytest.mark.mitsuba
def test_render_channel_subset(tmp_path):
    out = tmp_path / "sub"
    assert main(["render", "crease", "--out", str(out), "--width", "16", "--height", "12",
                 "--channels", "view_z,normal"]) == 0
    assert sorted(os.listdir(out)) == ["meta.json", "normal.exr", "normal.png", "view_z.exr", "view_z.png"]


@pytest.mark.parametrize("argv, names", [
    (["render", "sphere_on_plane", "--out", "X", "--channels", "view_z,bogus"], ["--channels", "bogus"]),
    (["render", "sphere_on_plane", "--out", "X", "--width", "0"], ["--width"]),
    (["render", "sphere_on_plane", "--out", "X", "--height", "-3"], ["--height"]),
    (["render", "sphere_on_plane", "--out", "X", "--spp", "many"], ["--spp"]),
    (["render", "no_such_scene", "--out", "X"], ["SCENE", "no_such_scene", "sphere_on_plane", "cornell_box"]),
    (["render", "sphere_on_plane"], ["--out"]),
    (["report", "--scenes", "sphere_on_plane,nope"], ["--scenes", "nope"]),
    (["frobnicate"], ["frobnicate"]),
])
def test_bad_arguments_name_the_argument(tmp_path, capsys, argv, names):
    argv = [str(tmp_path / "o") if a == "X" else a for a in argv]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2
    assert "ssbench: error:" in err and "Traceback" not in err
    for n in names:
        assert n in err
    assert not (tmp_path / "o").exists()


def test_bad_scene_file_is_a_user_error(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\ncamera: 3\n")
    rc = main(["render", str(bad), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "ssbench: error: argument SCENE" in err and "Traceback" not in err


def test_help_returns_zero(capsys):
    assert main(["--help"]) == 0
    assert "render" in capsys.readouterr().out


@pytest.mark.slow
def test_python_dash_m_scenes(tmp_path):
    env = dict(os.environ, SSBENCH_CACHE_DIR=str(tmp_path / "cache"))
    r = subprocess.run([sys.executable, "-m", "ssbench", "scenes"], capture_output=True, text=True, env=env,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert "sphere_on_plane" in r.stdout and "cornell_box" in r.stdout


# ------------------------------------------------------------------------------------------ ssbench ao
import dataclasses  # noqa: E402
import types  # noqa: E402

import torch  # noqa: E402

from ssbench import reference  # noqa: E402
from ssbench.cli import parse_value  # noqa: E402
from ssbench.passes import AO_METHODS, AOResult  # noqa: E402


@dataclasses.dataclass(frozen=True)
class _StubParams:
    radius: float = 0.5
    num_steps: int = 4
    jitter: bool = True
    mode: str = "depth"

    def __post_init__(self):
        if not self.radius > 0:
            raise ValueError(f"radius: must be a number > 0, got {self.radius!r}")


@pytest.fixture
def stub_ao(monkeypatch):
    """A stub AO method ('stub') and a stub reference, so `ssbench ao` runs without Mitsuba."""
    from ssbench.camera import Camera
    from ssbench.gbuffer import GBuffer
    mod = types.ModuleType("ssbench_cli_stub_ao")
    seen = []

    def stub(gbuffer, params, *, generator=None, debug=False):
        seen.append(params)
        return AOResult(torch.where(gbuffer.mask, 0.6, 1.0))

    stub.__module__ = mod.__name__
    mod.stub, mod.StubParams, mod.REQUIRES = stub, _StubParams, ("view_z", "mask")
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setitem(AO_METHODS, "stub", f"{mod.__name__}:stub:StubParams")
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, 8, 6, 0.1, 100.0)
    mask = torch.ones(1, 1, 6, 8, dtype=torch.bool)
    mask[..., 0, :] = False
    z = torch.where(mask, -5.0, -100.0)
    g = GBuffer(cam, view_z=z, position=cam.uv_to_view(cam.uv_grid()[None], z), mask=mask,
                normal=torch.where(mask, torch.tensor([0.0, 0.0, 1.0]).view(1, 3, 1, 1), 0.0))

    def gt(*a, weighting="cosine", **k):
        return reference.AOReference(torch.where(mask, 0.8, 1.0), torch.zeros(1, 1, 6, 8), weighting, 0.5, 4)

    monkeypatch.setattr(reference, "gbuffer", lambda *a, **k: g)
    monkeypatch.setattr(reference, "ambient_occlusion", lambda sc, gb, r, rays=256, weighting="cosine", seed=0,
                        **k: gt(weighting=weighting))
    monkeypatch.setattr(reference, "screen_space_oracle", lambda gb, r, rays=256, weighting="cosine", seed=0,
                        **k: gt(weighting=weighting))
    return seen


@pytest.mark.parametrize("text, value", [
    ("3", 3), ("-2", -2), ("0.5", 0.5), ("1e-3", 1e-3), ("true", True), ("False", False), ("off", False),
    ("depth", "depth"), ("__import__('os').getcwd()", "__import__('os').getcwd()"), ("1,2", "1,2"),
])
def test_param_values_are_parsed_without_eval(text, value):
    out = parse_value(text)
    assert out == value and type(out) is type(value)


@pytest.mark.parametrize("argv, names", [
    (["ao", "crease"], ["--method"]),
    (["ao", "crease", "--method", "nope"], ["--method", "nope"]),
    (["ao", "no_such_scene", "--method", "stub"], ["SCENE", "no_such_scene"]),
    (["ao", "crease", "--method", "stub", "--param", "radius"], ["--param", "NAME=VALUE"]),
    (["ao", "crease", "--method", "stub", "--param", "=3"], ["--param"]),
    (["ao", "crease", "--method", "stub", "--param", "radius=nan"], ["--param", "nan"]),
    (["ao", "crease", "--method", "stub", "--param", "bogus=1"], ["--param", "bogus", "num_steps"]),
    (["ao", "crease", "--method", "stub", "--param", "num_steps=2.5"], ["--param", "num_steps", "int"]),
    (["ao", "crease", "--method", "stub", "--param", "jitter=1"], ["--param", "jitter", "bool"]),
    (["ao", "crease", "--method", "stub", "--param", "radius=yes"], ["--param", "radius", "float"]),
    (["ao", "crease", "--method", "stub", "--param", "radius=-1"], ["--param", "radius"]),
    (["ao", "crease", "--method", "stub", "--param", "num_steps=2", "--param", "num_steps=3"],
     ["--param", "num_steps", "twice"]),
    (["ao", "crease", "--method", "stub", "--radius", "0"], ["--radius"]),
    (["ao", "crease", "--method", "stub", "--radius", "1", "--param", "radius=2"], ["--radius", "radius=2.0"]),
    (["ao", "crease", "--method", "stub", "--rays", "1"], ["--rays"]),
    (["ao", "crease", "--method", "stub", "--width", "0"], ["--width"]),
    (["ao", "crease", "--method", "stub", "--weighting", "ambient"], ["--weighting", "ambient"]),
    (["ao", "crease", "--method", "stub", "--repeats", "0"], ["--repeats"]),
    (["ao", "crease", "--method", "stub", "--blur", "gauss"], ["--blur", "gauss"]),
    (["report", "--ao-rays", "1"], ["--ao-rays"]),
    (["report", "--ao-radius", "-1"], ["--ao-radius"]),
])
def test_ao_bad_arguments_name_the_argument(stub_ao, tmp_path, capsys, argv, names):
    argv = argv + ["--out", str(tmp_path / "o")]
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "ssbench: error:" in err and "Traceback" not in err
    for n in names:
        assert n in err
    assert not (tmp_path / "o").exists()
    assert not stub_ao                                                     # the pass never ran


def test_ao_prints_a_table_and_writes_files(stub_ao, tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["ao", "crease", "--method", "stub", "--param", "num_steps=8", "--param", "jitter=false",
               "--param", "radius=1", "--rays", "4", "--repeats", "1", "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert "crease" in captured.out and "stub" in captured.out and "rmse" in captured.out
    assert stub_ao[-1] == _StubParams(radius=1.0, num_steps=8, jitter=False)
    assert sorted(os.listdir(out)) == ["ao.png", "error_cos.png", "error_flavour.png", "error_oracle.png",
                                       "gt_cos.png", "gt_flavour.png", "gt_oracle.png", "row.json"]
    row = json.loads((out / "row.json").read_text())
    assert row["method"] == "stub" and row["params"]["num_steps"] == 8 and row["radius"] == 1.0
    assert row["rmse_cos"] == pytest.approx(0.2, abs=1e-6)
    import matplotlib.image as mimage
    assert mimage.imread(str(out / "error_cos.png")).shape[:2] == (6, 8)


def test_ao_json(stub_ao, capsys):
    assert main(["ao", "crease", "--method", "stub", "--radius", "2", "--repeats", "1", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["params"]["radius"] == 2.0 and row["radius_param"] == "radius" and row["weighting"] == "cosine"


def test_timed_commands_run_on_the_threads_asked_for_and_restore_them(stub_ao, capsys, monkeypatch):
    import torch
    before = torch.get_num_threads()
    assert main(["--threads", "3", "ao", "crease", "--method", "stub", "--repeats", "1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["threads"] == 3 and torch.get_num_threads() == before
    monkeypatch.setattr(os, "cpu_count", lambda: 2)                    # a 2-core machine: 1 thread by default
    torch.set_num_threads(2)
    try:
        assert main(["ao", "crease", "--method", "stub", "--repeats", "1", "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["threads"] == 1 and torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    assert main(["--threads", "0", "ao", "crease", "--method", "stub"]) == 2
    assert "ssbench: error: argument --threads" in capsys.readouterr().err


def test_ao_blur(stub_ao, capsys):
    assert main(["ao", "crease", "--method", "stub", "--repeats", "1", "--blur", "cross_bilateral"]) == 0
    out = capsys.readouterr().out
    assert "blur cross_bilateral" in out and "noise_raw" in out


@pytest.mark.slow
@pytest.mark.mitsuba
def test_ao_real_run(tmp_path, capsys):
    from ssbench.passes import ao_method
    try:
        ao_method("hbao")
    except (ImportError, AttributeError) as e:
        pytest.skip(f"hbao not importable yet: {e}")
    out = tmp_path / "o"
    rc = main(["ao", "sphere_on_plane", "--method", "hbao", "--param", "num_steps=4", "--width", "32",
               "--height", "24", "--rays", "8", "--repeats", "1", "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    row = json.loads((out / "row.json").read_text())
    assert row["params"]["num_steps"] == 4 and row["nonfinite"] == 0 and row["oracle"] is True
    assert row["compiled"] is False and row["compile_s"] == 0.0


@pytest.mark.slow
@pytest.mark.mitsuba
def test_compile_flag_runs_the_compiled_kernels_and_says_so(tmp_path, capsys, monkeypatch):
    from ssbench.passes import compiled
    monkeypatch.delenv(compiled.ENV, raising=False)
    args = ["ao", "sphere_on_plane", "--method", "crytek", "--width", "32", "--height", "24", "--rays", "8",
            "--repeats", "1"]
    assert main(args + ["--out", str(tmp_path / "e")]) == 0
    assert main(["--compile", *args, "--out", str(tmp_path / "c")]) == 0, capsys.readouterr().err
    eager, comp = (json.loads((tmp_path / d / "row.json").read_text()) for d in ("e", "c"))
    assert comp["compiled"] is True and comp["compile_s"] > 0 and compiled.ENV not in os.environ   # restored
    assert comp["rmse_cos"] == eager["rmse_cos"]                              # the same AO bits, compiled


# ------------------------------------------------------------------------------------------ ssbench ssr
from ssbench.passes import SSR_METHODS  # noqa: E402
from ssbench.passes.ssr.common import HIT, MAX_DISTANCE, NO_RAY, SSRResult  # noqa: E402


@dataclasses.dataclass(frozen=True)
class _StubSSRParams:
    thickness: float = 0.1
    pixel_stride: int = 1
    use_back_face_depth: bool = False

    def __post_init__(self):
        if not self.thickness > 0:
            raise ValueError(f"thickness: must be a number > 0, got {self.thickness!r}")


@dataclasses.dataclass(frozen=True)
class _StubTruth:
    valid: torch.Tensor
    hit: torch.Tensor
    hit_view: torch.Tensor
    hit_pixel: torch.Tensor
    on_screen: torch.Tensor
    visible: torch.Tensor
    back_face: torch.Tensor
    hit_shape: torch.Tensor
    radiance: torch.Tensor
    seconds: float = 0.5


@pytest.fixture
def stub_ssr(monkeypatch):
    """A stub SSR method ('stub') and stub reference, so `ssbench ssr` runs without Mitsuba: the truth hits
    on the left half, the pass hits the correct pixel on the top half of it."""
    from ssbench.camera import Camera
    from ssbench.gbuffer import GBuffer
    mod = types.ModuleType("ssbench_cli_stub_ssr")
    seen = []
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, 8, 6, 0.1, 100.0)
    mask = torch.ones(1, 1, 6, 8, dtype=torch.bool)
    mask[..., 0, :] = False
    z = torch.where(mask, -5.0, -100.0)
    g = GBuffer(cam, view_z=z, position=cam.uv_to_view(cam.uv_grid()[None], z), mask=mask,
                normal=torch.where(mask, torch.tensor([0.0, 1.0, 0.0]).view(1, 3, 1, 1), 0.0),
                color=torch.full((1, 3, 6, 8), 0.3), shape_id=torch.where(mask, 0, -1).int())
    left = torch.zeros_like(mask)
    left[..., :4] = True
    thit = mask & left
    px = cam.pixel_centers()[None]
    truth = _StubTruth(valid=mask, hit=thit, hit_view=torch.where(thit, g.position - 1, 0.0),
                       hit_pixel=torch.where(thit, px, -1.0), on_screen=thit, visible=thit,
                       back_face=torch.zeros_like(thit), hit_shape=torch.where(thit, 1, -1).int(),
                       radiance=torch.where(mask, 0.3, 0.0).expand(1, 3, 6, 8).contiguous())

    def stub(gbuffer, params, *, generator=None, debug=False):
        seen.append(params)
        hit = thit.clone()
        hit[..., 4:, :] = False
        term = torch.where(hit, HIT, MAX_DISTANCE).to(torch.int8)
        term[~gbuffer.mask] = NO_RAY
        raw = torch.where(hit, gbuffer.color, 0.0)
        return SSRResult(color=raw, hit=hit, hit_pixel=torch.where(hit, px, -1.0),
                         hit_view=torch.where(hit, truth.hit_view, 0.0), steps=torch.ones(1, 1, 6, 8).int(),
                         termination=term, fade=torch.ones(1, 1, 6, 8), raw_color=raw,
                         debug={"visits": torch.ones(1, 1, 6, 8, dtype=torch.int32)} if debug else {})

    stub.__module__ = mod.__name__
    mod.stub, mod.StubSSRParams, mod.REQUIRES = stub, _StubSSRParams, ("view_z", "normal", "mask", "color")
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setitem(SSR_METHODS, "stub", f"{mod.__name__}:stub:StubSSRParams")
    monkeypatch.setattr(reference, "gbuffer", lambda *a, channels=None, **k: g.select(tuple(channels)))
    monkeypatch.setattr(reference, "reflections", lambda sc, gb, **k: truth, raising=False)
    return seen


@pytest.mark.parametrize("argv, names", [
    (["ssr", "fence"], ["--method"]),
    (["ssr", "fence", "--method", "nope"], ["--method", "nope"]),
    (["ssr", "no_such_scene", "--method", "stub"], ["SCENE", "no_such_scene"]),
    (["ssr", "fence", "--method", "stub", "--param", "thickness"], ["--param", "NAME=VALUE"]),
    (["ssr", "fence", "--method", "stub", "--param", "bogus=1"], ["--param", "bogus", "pixel_stride"]),
    (["ssr", "fence", "--method", "stub", "--param", "pixel_stride=1.5"], ["--param", "pixel_stride", "int"]),
    (["ssr", "fence", "--method", "stub", "--param", "thickness=-1"], ["--param", "thickness"]),
    (["ssr", "fence", "--method", "stub", "--k-px", "0"], ["--k-px"]),
    (["ssr", "fence", "--method", "stub", "--spp", "0"], ["--spp"]),
    (["ssr", "fence", "--method", "stub", "--width", "-3"], ["--width"]),
    (["report", "--ssr-spp", "0"], ["--ssr-spp"]),
])
def test_ssr_bad_arguments_name_the_argument(stub_ssr, tmp_path, capsys, argv, names):
    rc = main(argv + ["--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "ssbench: error:" in err and "Traceback" not in err
    for n in names:
        assert n in err
    assert not (tmp_path / "o").exists() and not stub_ssr


def test_ssr_prints_a_table_and_writes_files(stub_ssr, tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["ssr", "fence", "--method", "stub", "--param", "pixel_stride=4", "--param", "thickness=0.5",
               "--repeats", "1", "--spp", "2", "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert "fence" in captured.out and "stub" in captured.out and "correct" in captured.out
    assert "punch_through" in captured.out and "hit error" in captured.out
    assert stub_ssr[-1] == _StubSSRParams(thickness=0.5, pixel_stride=4)
    assert sorted(os.listdir(out)) == ["classes.png", "color.png", "error.png", "raw_color.png", "row.json",
                                       "truth.png", "truth_classes.png", "visits.png"]
    row = json.loads((out / "row.json").read_text())
    assert row["method"] == "stub" and row["params"]["pixel_stride"] == 4 and row["spp"] == 2
    # 5 reflective rows x 8: left half truth hits (20), the pass finds rows 1-3 (12); right half sky
    assert row["frac_correct"] == pytest.approx(12 / 40) and row["frac_missed"] == pytest.approx(8 / 40)
    assert row["frac_true_miss"] == pytest.approx(0.5)
    import matplotlib.image as mimage
    assert mimage.imread(str(out / "classes.png")).shape[:2] == (6, 8)


def test_ssr_json(stub_ssr, capsys):
    assert main(["ssr", "fence", "--method", "stub", "--repeats", "1", "--k-px", "0.5", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["k_px"] == 0.5 and row["params"]["thickness"] == 0.1 and "frac_punch_through" in row


def test_ssr_unimportable_method_is_a_failed_run(stub_ssr, monkeypatch, capsys):
    monkeypatch.setitem(SSR_METHODS, "stub", "ssbench_no_such_module:f:P")
    assert main(["ssr", "fence", "--method", "stub"]) == 1
    assert "not importable" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.mitsuba
def test_ssr_real_run(tmp_path, capsys):
    from ssbench.passes import ssr_method
    try:
        ssr_method("dda")
    except (ImportError, AttributeError) as e:
        pytest.skip(f"dda not importable yet: {e}")
    out = tmp_path / "o"
    rc = main(["ssr", "reflective_floor", "--method", "dda", "--width", "32", "--height", "24", "--spp", "2",
               "--repeats", "1", "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    row = json.loads((out / "row.json").read_text())
    assert row["nonfinite"] == 0 and row["reflective_pixels"] > 0


# ------------------------------------------------------------------------------------------ ssbench implicit
@pytest.fixture
def one_thread():
    """Tiny implicit renders gain nothing from more threads, and OpenMP barriers stall on shared cores."""
    import torch
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def test_implicit_writes_pngs_and_a_gif_with_every_frame(tmp_path, capsys, one_thread):
    from PIL import Image
    out = tmp_path / "o"
    rc = main(["implicit", "thin_shell", "--frames", "4", "--steps", "32", "--size", "24x18", "--out", str(out),
               "--gif", "--fps", "5"])
    text = capsys.readouterr()
    assert rc == 0, text.err
    assert "punch-through: f1 " in text.out and "f4 " in text.out and "predicted (h = t'/N)" in text.out
    for name in ("color.png", "t.png", "evaluations.png", "classes.png", "row.json", "frames.gif"):
        assert (out / name).is_file(), name
    assert "wrote 6 files" in text.out
    gif = Image.open(out / "frames.gif")
    assert gif.n_frames == 4 and gif.size == (24, 18 + 2)                     # + the frame-counter strip
    row = json.loads((out / "row.json").read_text())
    assert row["frames"] == 4 and row["params"]["steps"] == 32 and len(row["punch_through_per_frame"]) == 4
    import matplotlib.image as mimage
    assert mimage.imread(str(out / "classes.png")).shape[:2] == (18, 24)


def test_implicit_json_and_scene_file(tmp_path, capsys, one_thread):
    import yaml

    from ssbench.implicit import catalog
    f = tmp_path / "ball.yaml"
    f.write_text(yaml.safe_dump(catalog.as_dict("sphere")))
    assert main(["implicit", str(f), "--method", "sphere", "--frames", "1", "--size", "16x12", "--json",
                 "--param", "omega=1.5", "--steps", "64"]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["scene"] == "sphere" and row["params"]["omega"] == 1.5 and row["params"]["max_steps"] == 64
    assert abs(sum(row[k] for k in row if k.startswith("frac_")) - 1) < 1e-9


@pytest.mark.parametrize("argv, status, names", [
    (["implicit", "no_such_scene"], 2, ["argument SCENE", "no_such_scene"]),
    (["implicit", "missing.yaml"], 2, ["argument SCENE", "missing.yaml"]),
    (["implicit", "torus", "--method", "raymarch"], 2, ["--method", "raymarch"]),
    (["implicit", "torus", "--size", "96by72"], 2, ["--size", "WxH"]),
    (["implicit", "torus", "--frames", "0"], 2, ["--frames"]),
    (["implicit", "torus", "--param", "stepz=3"], 2, ["--param", "stepz"]),
    (["implicit", "torus", "--param", "epsilon=-1"], 2, ["--param", "epsilon"]),
    (["implicit", "torus", "--steps", "8", "--param", "steps=9"], 2, ["--steps", "conflicts"]),
    (["implicit", "torus", "--gif"], 2, ["--gif", "--out"]),
    (["implicit", "double_root", "--method", "sphere", "--size", "8x6", "--frames", "1"], 1, ["lipschitz"]),
])
def test_implicit_bad_arguments(capsys, one_thread, argv, status, names):
    assert main(argv) == status
    err = capsys.readouterr().err
    assert "ssbench: error:" in err and "Traceback" not in err
    for n in names:
        assert n in err


def test_tune_is_a_subcommand_of_the_main_cli(capsys):
    assert main(["tune", "gtao", "--tune", "radus"]) == 1
    err = capsys.readouterr().err
    assert "argument --tune: 'radus' not tunable for gtao; tunable: radius" in err and "Traceback" not in err
    assert main(["tune", "gtoa"]) == 2 and "invalid choice: 'gtoa'" in capsys.readouterr().err
