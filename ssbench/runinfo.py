"""What a run records about where it ran: package versions, threads, the Mitsuba backend choice, the machine
and the git state. Shared by the report (``meta.json``) and the sweeps (``runs/<run_id>.json``), so neither
reaches into the other."""
from __future__ import annotations

import os
import platform
import subprocess
import sys
from typing import Optional

__all__ = ["environment", "git_state"]

_REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _version(module: str) -> Optional[str]:
    try:
        return getattr(__import__(module), "__version__", None)
    except Exception:
        return None


def environment() -> dict:
    """Versions, threads, the Mitsuba backend choice (with its probe attempts) and the machine."""
    import torch
    from . import __version__
    from .reference import backend
    b = backend.info()
    return {"ssbench": __version__, "python": platform.python_version(), "python_executable": sys.executable,
            "torch": torch.__version__, "torch_threads": torch.get_num_threads(), "kornia": _version("kornia"),
            "numpy": _version("numpy"), "mitsuba": b["mitsuba"], "drjit": b["drjit"],
            "drjit_threads": b["drjit_threads"], "variant": b["variant"], "libllvm": b["libllvm"],
            "libllvm_major": b["libllvm_major"], "backend_reason": b["reason"],
            "probe": [list(t) for t in b["tried"]], "node": platform.node(),
            "processor": platform.processor() or platform.machine(), "machine": platform.machine(),
            "platform": platform.platform(), "cpu_count": os.cpu_count()}


def git_state(repo: str = _REPO) -> dict:
    """``{"commit": sha or "unknown", "dirty": bool or None}`` of the repository holding ssbench."""
    def git(*args: str) -> Optional[str]:
        try:
            r = subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True, timeout=20)
        except (OSError, subprocess.SubprocessError):
            return None
        return r.stdout if r.returncode == 0 else None
    sha = git("rev-parse", "HEAD")
    if not sha:
        return {"commit": "unknown", "dirty": None}
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"commit": sha.strip(), "dirty": None if status is None else bool(status.strip())}


def timing_threads(requested: Optional[int] = None) -> int:
    """Torch threads for timing a pass: ``requested``, else 1 on a machine of at most two cores (there a second
    thread shares a core with the OS and the Dr.Jit pool, and measured 7–11× slower under load), else torch's
    current count.

    Example:
        >>> timing_threads(3)
        3
        >>> timing_threads() >= 1
        True
    """
    if requested is not None:
        if isinstance(requested, bool) or not isinstance(requested, int) or requested < 1:
            raise ValueError(f"threads: expected a positive integer, got {requested!r}")
        return requested
    if (os.cpu_count() or 1) <= 2:
        return 1
    import torch
    return torch.get_num_threads()
