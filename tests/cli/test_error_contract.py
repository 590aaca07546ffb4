"""The CLI contract: every bad argument, output path or environment exits non-zero with exactly one
``ssbench: error: …`` line naming the argument or file — never a traceback — checked in subprocesses."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow

SMALL = ["--width", "16", "--height", "12"]


def _run(args, tmp_path, env=None, timeout=120):
    e = dict(os.environ, SSBENCH_CACHE_DIR=str(tmp_path / "cache"), MPLBACKEND="Agg")
    e.pop("SSBENCH_DEBUG", None)
    e.update(env or {})
    r = subprocess.run([sys.executable, "-m", "ssbench", *args], capture_output=True, text=True, env=e,
                       cwd=tmp_path, timeout=timeout)
    return r.returncode, r.stderr


def _one_error_line(rc, err, *needles):
    assert rc != 0, err
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith("ssbench: error:")]
    assert len(lines) == 1, err
    for n in needles:
        assert n in lines[0], (n, lines[0])


def test_huge_render_is_refused_naming_the_size(tmp_path):                   # was a Dr.Jit RuntimeError
    rc, err = _run(["render", "sphere_on_plane", "--width", "100000", "--height", "100000", "--out", "o"], tmp_path)
    _one_error_line(rc, err, "--width/--height", "--force")
    assert not (tmp_path / "o").exists()                                       # refused before any output


@pytest.mark.parametrize("cmd", [["ao", "sphere_on_plane", "--method", "hbao", "--rays", "8", *SMALL],
                                 ["render", "sphere_on_plane", "--spp", "2", *SMALL]])
@pytest.mark.parametrize("where", ["a_file", "/proc/nope", "/dev/null/x"])
def test_bad_out_is_a_usage_error(cmd, where, tmp_path):                     # were FileExistsError & co.
    (tmp_path / "a_file").write_text("x")
    rc, err = _run(cmd + ["--out", where], tmp_path)
    _one_error_line(rc, err, "--out", where)


def test_report_out_under_dev_null(tmp_path):
    rc, err = _run(["report", "--out", "/dev/null/x"], tmp_path)
    _one_error_line(rc, err, "--out", "/dev/null/x")


@pytest.mark.parametrize("cache", ["a_file", "a_file/below"])
def test_unusable_cache_dir_runs_uncached_with_a_warning(cache, tmp_path):
    (tmp_path / "a_file").write_text("x")
    rc, err = _run(["ao", "sphere_on_plane", "--method", "hbao", "--rays", "8", *SMALL, "--json"], tmp_path,
                   env={"SSBENCH_CACHE_DIR": str(tmp_path / cache)})
    assert rc == 0, err
    assert "Traceback" not in err and "ssbench: warning: ssbench cache: cannot write" in err


@pytest.mark.parametrize("args,needle", [
    (["ao", "sphere_on_plane", "--method", "hbao", "--rays", "100000000000"], "--rays"),
    (["ssr", "reflective_floor", "--method", "dda", "--spp", "100000000000"], "--spp"),
    (["implicit", "sphere", "--frames", "100000"], "--frames"),
    (["render", "sphere_on_plane", "--width", "9000", "--height", "9000", "--out", "o"], "--width/--height"),
])
def test_resource_guards(args, needle, tmp_path):                            # --rays 1e11 ran without end
    rc, err = _run(args, tmp_path)
    _one_error_line(rc, err, needle, "--force")


def test_non_utf8_scene_names_file_and_line(tmp_path):                     # said only 'argument SCENE: utf-8'
    (tmp_path / "s.yaml").write_bytes(b"name: s\n# caf\xe9\ncamera: {}\n")
    rc, err = _run(["render", "s.yaml", "--out", "o"], tmp_path)
    _one_error_line(rc, err, "s.yaml:2:", "not UTF-8")


def test_non_mapping_field_says_list_not_a_class_name(tmp_path):           # said 'got _LineList'
    (tmp_path / "s.yaml").write_text(
        "name: s\ncamera: {eye: [0, 1, 5], target: [0, 0, 0], up: [0, 1, 0], fovy: 45, width: 8, height: 6, "
        "near: 0.1, far: 10}\nshapes: [{id: f, type: rectangle, size: [2, 2]}]\nrender: [1, 2]\n")
    rc, err = _run(["render", "s.yaml", "--out", "o"], tmp_path)
    _one_error_line(rc, err, "render", "expected a mapping, got a list")
    assert "_LineList" not in err


def test_unexpected_exception_is_one_line(tmp_path, monkeypatch, capsys):
    """Anything the commands do not foresee still ends in one line (in-process: a command that raises)."""
    from ssbench import cli
    monkeypatch.setitem(cli._COMMANDS, "scenes", lambda args: (_ for _ in ()).throw(RuntimeError("boom\nmore")))
    assert cli.main(["scenes"]) == 1
    err = capsys.readouterr().err
    assert err.strip() == "ssbench: error: RuntimeError: boom (set SSBENCH_DEBUG=1 for the traceback)"


@pytest.mark.parametrize("args,needle", [
    (["sweep", "nope.yaml"], "nope.yaml"),
    (["tune", "nope"], "METHOD"),
    (["tune", "hbao", "--scenes", "nope"], "--scenes"),
    (["report", "--compare", "a", "b"], "RUN_A"),
    (["report", "--from", "nope"], "RUN"),
    (["info", "--bogus"], "--bogus"),
    (["ssr", "nope", "--method", "dda"], "SCENE"),
    (["implicit", "nope"], "SCENE"),
    (["implicit", "sphere", "--size", "0x5"], "--size"),
    (["ao", "sphere_on_plane", "--method", "hbao", "--param", "radius=-1"], "radius"),
    (["ao", "sphere_on_plane", "--method", "hbao", "--param", "nope=1"], "nope"),
    (["implicit", "sphere", "--gif"], "--gif"),
])
def test_bad_arguments_of_every_command(args, needle, tmp_path):
    rc, err = _run(args, tmp_path)
    _one_error_line(rc, err, needle)
