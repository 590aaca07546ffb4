"""The peer runtime without a browser or network: ``ensure_three``'s install with a stand-in ``npm`` on ``PATH``
(it lands whole or not at all, also when another process finishes first or an older install was left incomplete),
and ``run_pass``'s reading of the page Chromium prints."""
import json
import os
import stat

import pytest

from ssbench.peer import PeerUnavailable
from ssbench.peer import runtime
from ssbench.peer.runtime import THREE_VERSION, ensure_three

# a stand-in for `npm ci`: writes node_modules/three/package.json at the version it is told, into the working folder;
# FAKE_NPM_ALSO names a folder it fills first (another process's finished install), FAKE_NPM_FAIL makes it fail
FAKE_NPM = """#!/bin/sh
if [ -n "$FAKE_NPM_ALSO" ]; then
  mkdir -p "$FAKE_NPM_ALSO/node_modules/three"
  printf '{"version": "%s", "by": "other"}' "$FAKE_NPM_VERSION" > "$FAKE_NPM_ALSO/node_modules/three/package.json"
fi
if [ -n "$FAKE_NPM_FAIL" ]; then echo "npm ERR! no registry" >&2; exit 1; fi
mkdir -p node_modules/three
printf '{"version": "%s", "by": "us"}' "$FAKE_NPM_VERSION" > node_modules/three/package.json
"""


@pytest.fixture
def fake_npm(tmp_path, monkeypatch):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    npm = bin_dir / "npm"
    npm.write_text(FAKE_NPM)
    npm.chmod(npm.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    monkeypatch.setenv("FAKE_NPM_VERSION", THREE_VERSION)
    monkeypatch.delenv("FAKE_NPM_ALSO", raising=False)
    monkeypatch.delenv("FAKE_NPM_FAIL", raising=False)
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache" / "peer" / f"three-{THREE_VERSION}"


def by(folder) -> str:
    return json.loads((folder / "node_modules" / "three" / "package.json").read_text())["by"]


def leftovers(folder) -> list:
    return sorted(p.name for p in folder.parent.iterdir() if p.name != folder.name)


def test_installs_once_into_the_cache_and_leaves_no_partial_folder(fake_npm, monkeypatch):
    assert ensure_three() == fake_npm and by(fake_npm) == "us"
    assert (fake_npm / "package-lock.json").exists() and leftovers(fake_npm) == []
    monkeypatch.setenv("FAKE_NPM_FAIL", "1")                           # installed: npm is not run again
    assert ensure_three() == fake_npm


def test_a_failed_install_raises_and_leaves_nothing(fake_npm, monkeypatch):
    monkeypatch.setenv("FAKE_NPM_FAIL", "1")
    with pytest.raises(PeerUnavailable, match="npm ci of three.*no registry"):
        ensure_three()
    assert not fake_npm.exists() and leftovers(fake_npm) == []


def test_another_process_finishing_first_keeps_its_install(fake_npm, monkeypatch):
    monkeypatch.setenv("FAKE_NPM_ALSO", str(fake_npm))
    assert ensure_three() == fake_npm and by(fake_npm) == "other"
    assert leftovers(fake_npm) == []


def test_an_incomplete_or_outdated_install_is_replaced(fake_npm):
    (fake_npm / "node_modules" / "three").mkdir(parents=True)          # interrupted: no package.json
    (fake_npm / "stale").write_text("x")
    assert ensure_three() == fake_npm and by(fake_npm) == "us" and not (fake_npm / "stale").exists()
    (fake_npm / "node_modules" / "three" / "package.json").write_text('{"version": "0.0.1", "by": "old"}')
    assert ensure_three() == fake_npm and by(fake_npm) == "us" and leftovers(fake_npm) == []


def test_no_npm_says_so(fake_npm, monkeypatch):
    monkeypatch.setattr(runtime.shutil, "which", lambda name: None)
    with pytest.raises(PeerUnavailable, match="no npm on PATH"):
        ensure_three()


def test_run_pass_returns_a_writable_image_in_ssbench_rows(monkeypatch, tmp_path):
    """The page's result, parsed without a browser (a stand-in for Chromium's ``--dump-dom`` output): rows flipped
    back to ssbench order by default, GL order with ``flip_rows=False``, writable either way (``torch.from_numpy``
    warned of a read-only array), and a page that failed is an error naming the shader."""
    import base64
    import subprocess

    import numpy as np

    gl = np.arange(2 * 3 * 4, dtype=np.float32).reshape(2, 3, 4)                 # rows bottom-up, as GL reads back
    page = {"text": "OK r170 0 " + base64.b64encode(gl.tobytes()).decode("ascii")}

    def chromium(cmd, **kw):
        return subprocess.CompletedProcess(cmd, 0, stdout=f'<pre id="out">{page["text"]}</pre>', stderr="")
    monkeypatch.setattr(runtime, "find_chromium", lambda: "/stand-in/chromium")
    monkeypatch.setattr(runtime, "ensure_three", lambda: tmp_path)
    monkeypatch.setattr(runtime.subprocess, "run", chromium)
    p = runtime.ShaderPass("three/addons/shaders/SSAOShader.js", "SSAOShader", width=3, height=2)
    out = runtime.run_pass(p)
    assert out.flags.writeable and out.flags.c_contiguous and np.array_equal(out, gl[::-1])
    raw = runtime.run_pass(p, flip_rows=False)
    assert raw.flags.writeable and np.array_equal(raw, gl)
    page["text"] = "ERROR shader did not compile"
    with pytest.raises(RuntimeError, match="SSAOShader: ERROR shader did not compile"):
        runtime.run_pass(p)
