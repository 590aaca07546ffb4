"""Choose the Mitsuba/Dr.Jit variant once per process, safely.

Order (``SSBENCH_VARIANT`` overrides it):

1. ``cuda_ad_rgb`` when a CUDA device works;
2. ``llvm_ad_rgb`` with the newest libLLVM that passes a smoke test;
3. ``scalar_rgb`` with a one-line :class:`SlowBackendWarning`.

libLLVM 15 and 16 *abort the process* (SIGABRT, not an exception) on ``dr.minimum``, and Dr.Jit reads
``DRJIT_LIBLLVM_PATH`` only when it is imported (both measured here; ``ssbench/REFERENCES.md``). So every candidate is
tried in a **subprocess** running a smoke test (``dr.minimum``, a tiny ``mi.render``, a ``ray_intersect``), and
the winner's path is put in ``DRJIT_LIBLLVM_PATH`` *before* this process imports drjit.

Candidate libraries: ``$DRJIT_LIBLLVM_PATH``, then the usual system locations (newest version first).
``SSBENCH_LLVM_CANDIDATES`` (paths joined by ``os.pathsep``) replaces that list, e.g. for tests.
``SSBENCH_NO_CUDA=1`` skips the CUDA probe.
"""
from __future__ import annotations

import glob
import os
import re
import subprocess
import sys
import warnings
from dataclasses import asdict, dataclass, field
from typing import Optional

VARIANTS = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")
MIN_LLVM = 17          # 14 is refused by Dr.Jit; 15 and 16 abort on fminimum (probe Q8). 17/18 untested.


class SlowBackendWarning(UserWarning):
    """Emitted once when only the scalar (single-ray, Python-loop) backend is available."""


@dataclass
class BackendChoice:
    variant: str
    libllvm: Optional[str] = None
    reason: str = ""
    tried: list = field(default_factory=list)        # [(candidate, outcome), ...]

    def as_dict(self) -> dict:
        return asdict(self)


_SMOKE = r"""
import sys
variant = sys.argv[1]
import drjit as dr
import mitsuba as mi
if variant.startswith('cuda') and not dr.has_backend(dr.JitBackend.CUDA):
    print('NO_CUDA'); sys.exit(3)
if variant.startswith('llvm') and not dr.has_backend(dr.JitBackend.LLVM):
    print('NO_LLVM'); sys.exit(4)
mi.set_variant(variant)
import numpy as np
scalar = variant.startswith('scalar')
x = dr.minimum(mi.Float(5.0), 2.0) if scalar else dr.minimum(mi.Float([1.0, 5.0, 3.0]), 2.0)
assert abs(float(np.sum(np.asarray(x))) - (2.0 if scalar else 5.0)) < 1e-6
scene = mi.load_dict({'type': 'scene', 'integrator': {'type': 'path'},
                      'sensor': {'type': 'perspective', 'film': {'type': 'hdrfilm', 'width': 4, 'height': 4}},
                      'ball': {'type': 'sphere', 'center': [0, 0, 5]}})
img = mi.render(scene, spp=1)
si = scene.ray_intersect(mi.Ray3f(mi.Point3f(0, 0, 0), mi.Vector3f(0, 0, 1)))
assert bool(np.all(np.asarray(si.is_valid()))) and abs(float(np.min(np.asarray(si.t))) - 4.0) < 1e-4
print('SMOKE_OK')
"""


def llvm_major(path: str) -> int:
    """Major version parsed from a libLLVM file name (after resolving links); −1 if unknown."""
    for name in (os.path.basename(path), os.path.basename(os.path.realpath(path))):
        m = re.search(r"libLLVM[-.]?(?:so\.)?(\d+)", name)
        if m:
            return int(m.group(1))
    m = re.search(r"llvm[-@]?(\d+)", path)
    return int(m.group(1)) if m else -1


def llvm_candidates() -> list[str]:
    """Candidate libLLVM paths, newest major version first, deduplicated by real path."""
    override = os.environ.get("SSBENCH_LLVM_CANDIDATES")
    if override is not None:
        return [p for p in override.split(os.pathsep) if p]
    paths = []
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        paths.append(os.environ["DRJIT_LIBLLVM_PATH"])
    patterns = ["/usr/lib/*-linux-gnu/libLLVM*.so*", "/usr/lib/llvm-*/lib/libLLVM*.so*",
                "/usr/local/lib/libLLVM*.so*", "/usr/lib64/libLLVM*.so*",
                "/opt/homebrew/opt/llvm/lib/libLLVM.dylib", "/usr/local/opt/llvm/lib/libLLVM.dylib"]
    if os.environ.get("CONDA_PREFIX"):
        patterns.append(os.path.join(os.environ["CONDA_PREFIX"], "lib", "libLLVM*.so*"))
    found = []
    for pat in patterns:
        found.extend(sorted(glob.glob(pat)))
    seen, out = set(), []
    for p in paths + sorted(found, key=llvm_major, reverse=True):
        real = os.path.realpath(p)
        if real in seen:
            continue
        seen.add(real)
        out.append(p)
    head = out[:len(paths)]
    rest = [p for p in out[len(paths):] if llvm_major(p) >= 15 or llvm_major(p) < 0]
    return head + rest


def probe(variant: str, libllvm: Optional[str] = None, timeout: float = 120.0) -> tuple[bool, str]:
    """Run the smoke test for ``variant`` in a subprocess; ``(ok, outcome)`` — a crash is just ``False``."""
    env = dict(os.environ)
    env.pop("DRJIT_LIBLLVM_PATH", None)
    if libllvm:
        env["DRJIT_LIBLLVM_PATH"] = libllvm
    try:
        r = subprocess.run([sys.executable, "-c", _SMOKE, variant], env=env, capture_output=True, text=True,
                           timeout=timeout)
    except subprocess.TimeoutExpired:
        return False, "timeout"
    if r.returncode == 0 and "SMOKE_OK" in r.stdout:
        return True, "ok"
    tail = (r.stderr.strip().splitlines() or r.stdout.strip().splitlines() or [""])[-1][:160]
    return False, f"rc={r.returncode} {tail}"


def _choose() -> BackendChoice:
    forced = os.environ.get("SSBENCH_VARIANT", "").strip()
    if forced and forced not in VARIANTS:
        raise ValueError(f"SSBENCH_VARIANT: unknown variant {forced!r}; choose one of {', '.join(VARIANTS)}")
    tried = []
    if forced in ("", "cuda_ad_rgb") and os.environ.get("SSBENCH_NO_CUDA", "") not in ("1", "true"):
        ok, why = probe("cuda_ad_rgb")
        tried.append(("cuda_ad_rgb", why))
        if ok:
            return BackendChoice("cuda_ad_rgb", None, "CUDA device works", tried)
        if forced:
            raise RuntimeError(f"SSBENCH_VARIANT=cuda_ad_rgb but the CUDA smoke test failed: {why}")
    if forced in ("", "llvm_ad_rgb"):
        for cand in llvm_candidates():
            major = llvm_major(cand)
            ok, why = probe("llvm_ad_rgb", cand)
            tried.append((cand, why))
            if ok:
                return BackendChoice("llvm_ad_rgb", cand, f"libLLVM {major if major >= 0 else '?'} works", tried)
        if forced:
            raise RuntimeError("SSBENCH_VARIANT=llvm_ad_rgb but no libLLVM passed the smoke test "
                               f"(tried: {tried}); install it with: apt-get install -y libllvm19")
    return BackendChoice("scalar_rgb", None, "no working CUDA or libLLVM >= 17", tried)


_CHOICE: Optional[BackendChoice] = None
_MI = None


def adopt(c: BackendChoice) -> None:
    """Use ``c`` (a parent process's choice, already smoke-tested there) instead of probing; must come before
    :func:`mitsuba` is first called. :mod:`ssbench.bench.processes` passes its choice to its timing children."""
    global _CHOICE
    if _MI is not None and _CHOICE is not None and _CHOICE.variant != c.variant:
        raise RuntimeError(f"c: Mitsuba already runs variant {_CHOICE.variant!r} in this process, not {c.variant!r}")
    _CHOICE = c


def choice() -> BackendChoice:
    """The variant chosen for this process (probing on first call)."""
    global _CHOICE
    if _CHOICE is None:
        _CHOICE = _choose()
    return _CHOICE


def mitsuba():
    """Import Mitsuba with the chosen variant set (and ``DRJIT_LIBLLVM_PATH`` set before drjit loads)."""
    global _MI
    if _MI is not None:
        return _MI
    c = choice()
    if "drjit" in sys.modules and c.libllvm and os.environ.get("DRJIT_LIBLLVM_PATH") != c.libllvm:
        warnings.warn("drjit was imported before ssbench chose a libLLVM; DRJIT_LIBLLVM_PATH may be ignored",
                      RuntimeWarning, stacklevel=2)
    if c.libllvm:
        os.environ["DRJIT_LIBLLVM_PATH"] = c.libllvm
    else:
        os.environ.pop("DRJIT_LIBLLVM_PATH", None)
    import mitsuba as mi
    mi.set_variant(c.variant)
    if c.variant == "scalar_rgb":
        warnings.warn("ssbench: Mitsuba runs in scalar_rgb (one ray at a time, ~50x slower ground truth); "
                      "fix: apt-get install -y libllvm19 (or set DRJIT_LIBLLVM_PATH to libLLVM >= 17)",
                      SlowBackendWarning, stacklevel=2)
    _MI = mi
    return mi


def is_jit() -> bool:
    """True for the vectorised (LLVM/CUDA) variants."""
    return choice().variant != "scalar_rgb"


def info() -> dict:
    """Variant, libLLVM, versions and thread count (for ``ssbench info`` and report metadata)."""
    mi = mitsuba()
    import drjit as dr
    c = choice()
    try:
        threads = dr.thread_count()
    except Exception:  # pragma: no cover - older Dr.Jit
        threads = None
    return {"variant": c.variant, "libllvm": c.libllvm, "libllvm_major": llvm_major(c.libllvm) if c.libllvm
            else None, "reason": c.reason, "tried": c.tried, "mitsuba": mi.__version__,
            "drjit": dr.__version__, "drjit_threads": threads}
