"""On-disk cache of reference renders, keyed by a content hash; corrupt entries are detected and recomputed.

Location: ``$SSBENCH_CACHE_DIR`` or ``~/.cache/ssbench``. Set ``SSBENCH_CACHE=0`` to bypass it. A key hashes
the scene content, camera, channels, spp, seed, the backend variant and the Mitsuba/Dr.Jit versions, so a
changed input never reads a stale entry. Each entry is one ``.npz`` holding its arrays plus a SHA-256 of their
bytes; it is written to a temporary file and renamed, so a crash never leaves a half-written entry.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
import warnings
from dataclasses import asdict, is_dataclass
from typing import Any, Optional

import numpy as np

from . import backend


def cache_dir() -> str:
    return os.environ.get("SSBENCH_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "ssbench")


def enabled() -> bool:
    return os.environ.get("SSBENCH_CACHE", "1").strip().lower() not in ("0", "false", "off", "no")


def _jsonable(x: Any) -> Any:
    if is_dataclass(x):
        return asdict(x)
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    return x


def make_key(kind: str, *parts: Any) -> str:
    """Content hash of ``parts`` plus the backend variant and library versions."""
    info = backend.choice()
    mi = backend.mitsuba()
    import drjit as dr
    blob = json.dumps([kind, _jsonable(list(parts)), info.variant, mi.__version__, dr.__version__],
                      sort_keys=True, default=str)
    return f"{kind}-{hashlib.sha256(blob.encode()).hexdigest()[:32]}"


def _digest(arrays: dict[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for k in sorted(arrays):
        a = np.ascontiguousarray(arrays[k])
        h.update(k.encode()), h.update(str(a.dtype).encode()), h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def path_for(key: str) -> str:
    return os.path.join(cache_dir(), key[-2:], key + ".npz")


def load(key: str, meta: Optional[dict] = None) -> Optional[dict[str, np.ndarray]]:
    """The arrays stored under ``key``, or ``None`` when absent, disabled or corrupt (then it is removed).

    ``meta``: a dict to receive the entry's stored metadata (e.g. ``"seconds"``, the original render time)."""
    if not enabled():
        return None
    p = path_for(key)
    if not os.path.isfile(p):
        return None
    try:
        with np.load(p, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files if k != "__meta__"}
            stored = json.loads(bytes(z["__meta__"]).decode())
        if stored.get("sha256") != _digest(arrays):
            raise ValueError("checksum mismatch")
        if meta is not None:
            meta.update(stored)
        return arrays
    except Exception as e:  # truncated zip, bad checksum, unreadable JSON ...
        warnings.warn(f"ssbench cache: corrupt entry {p} ({e}); recomputing", RuntimeWarning, stacklevel=2)
        try:
            os.remove(p)
        except OSError:
            pass
        return None


def store(key: str, arrays: dict[str, np.ndarray], meta: Optional[dict] = None) -> None:
    """Write ``arrays`` atomically under ``key``."""
    if not enabled():
        return
    p = path_for(key)
    m = dict(meta or {}, sha256=_digest(arrays))
    payload = dict(arrays, __meta__=np.frombuffer(json.dumps(m).encode(), dtype=np.uint8))
    try:
        os.makedirs(os.path.dirname(p), exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(p), suffix=".tmp")
    except OSError as e:                     # a file where the folder should be, no permission, disk full ...
        _warn_unwritable(e)
        return
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **payload)
        os.replace(tmp, p)
    except OSError as e:
        if os.path.exists(tmp):
            os.remove(tmp)
        _warn_unwritable(e)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


_WARNED: set = set()


def _warn_unwritable(e: OSError) -> None:
    """One warning per cache folder: the run goes on uncached (results are the same, only slower next time)."""
    d = cache_dir()
    if d not in _WARNED:
        _WARNED.add(d)
        warnings.warn(f"ssbench cache: cannot write to {d} ({e.strerror or e}); running uncached "
                      f"(set SSBENCH_CACHE_DIR to a writable folder, or SSBENCH_CACHE=0)", RuntimeWarning,
                      stacklevel=3)
