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
