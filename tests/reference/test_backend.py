"""Variant choice: probes run in subprocesses, so a libLLVM that aborts the process cannot take us down."""
import glob
import json
import os
import subprocess
import sys

import pytest

from ssbench.reference import backend

pytestmark = pytest.mark.slow

CHOOSE = ("import json, warnings\n"
          "warnings.simplefilter('always')\n"
          "from ssbench.reference import backend\n"
          "with warnings.catch_warnings(record=True) as w:\n"
          "    mi = backend.mitsuba()\n"
          "c = backend.choice()\n"
          "print(json.dumps({'variant': c.variant, 'libllvm': c.libllvm, 'tried': c.tried,\n"
          "                  'warnings': [str(x.message) for x in w]}))\n")


def choose(**env) -> dict:
    e = {k: v for k, v in os.environ.items() if k not in ("DRJIT_LIBLLVM_PATH", "SSBENCH_VARIANT")}
    e.update(SSBENCH_NO_CUDA="1", **env)
    r = subprocess.run([sys.executable, "-c", CHOOSE], env=e, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def _llvm(major: int):
    for p in sorted(glob.glob(f"/usr/lib/*-linux-gnu/libLLVM-{major}.so*")) + \
            sorted(glob.glob(f"/usr/lib/*-linux-gnu/libLLVM.so.{major}*")):
        return p
    return None


def test_llvm_major_parsing():
    assert backend.llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1") == 15
    assert backend.llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1") == 19
    assert backend.llvm_major("/usr/lib/x86_64-linux-gnu/libLLVM-14.0.6.so.1") == 14
    assert backend.llvm_major("/opt/homebrew/opt/llvm@18/lib/libLLVM.dylib") == 18


def test_broken_libraries_fall_back_to_scalar_with_one_warning():
    bad = ["/nonexistent/libLLVM-99.so"]
    if _llvm(15):
        bad.insert(0, _llvm(15))                # aborts the process on dr.minimum (SIGABRT)
    out = choose(SSBENCH_LLVM_CANDIDATES=os.pathsep.join(bad))
    assert out["variant"] == "scalar_rgb"
    assert [t[0] for t in out["tried"] if t[0] != "cuda_ad_rgb"] == bad
    assert all(t[1] != "ok" for t in out["tried"])
    slow = [w for w in out["warnings"] if "scalar_rgb" in w]
    assert len(slow) == 1 and "libllvm19" in slow[0] and "\n" not in slow[0]


@pytest.mark.skipif(_llvm(19) is None, reason="libLLVM 19 not installed")
def test_survives_aborting_llvm_and_picks_the_working_one():
    cands = [p for p in (_llvm(15), "/nonexistent/libLLVM-99.so", _llvm(19)) if p]
    out = choose(SSBENCH_LLVM_CANDIDATES=os.pathsep.join(cands))
    assert out["variant"] == "llvm_ad_rgb" and out["libllvm"] == _llvm(19)
    if _llvm(15):
        assert out["tried"][1][1].startswith("rc=")           # the 15 probe died, we did not


def test_forced_variant_and_bad_override():
    out = choose(SSBENCH_VARIANT="scalar_rgb")
    assert out["variant"] == "scalar_rgb"
    e = dict(os.environ, SSBENCH_VARIANT="gpu_please")
    r = subprocess.run([sys.executable, "-c", CHOOSE], env=e, capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "SSBENCH_VARIANT" in r.stderr


def test_an_adopted_choice_replaces_the_probe(monkeypatch):
    monkeypatch.setattr(backend, "_CHOICE", None)
    monkeypatch.setattr(backend, "_MI", None)
    monkeypatch.setattr(backend, "probe", lambda *a, **k: pytest.fail("an adopted choice must not probe"))
    given = backend.BackendChoice("scalar_rgb", None, "chosen by the parent")
    backend.adopt(given)
    assert backend.choice() is given
    monkeypatch.setattr(backend, "_MI", object())                    # Mitsuba already runs that variant
    with pytest.raises(RuntimeError, match="already runs variant 'scalar_rgb'"):
        backend.adopt(backend.BackendChoice("llvm_ad_rgb", "/x/libLLVM.so.19"))
