"""A sweep's output folder as an object (:class:`RowStore`): rows written atomically, one file each, strays of killed
writers cleaned, corrupt rows quarantined, run metadata and the consolidated tables (layout and guarantees:
:mod:`ssbench.bench.rows`).
"""
from __future__ import annotations

import datetime as _dt
import json
import os
from typing import Any, Optional, Sequence

from .rows import decode_row, dumps_row, json_default, write_tables, write_text_atomic

__all__ = ["RowStore"]


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


class RowStore:
    """A sweep's output folder (see the module docstring).

    Example:
        >>> import tempfile
        >>> s = RowStore(tempfile.mkdtemp())
        >>> _ = s.write_row({"config_id": "abc", "x": float("nan")}); sorted(s.done_ids())
        ['abc']
        >>> s.read_row("abc")["x"]
        nan
    """

    def __init__(self, root: "str | os.PathLike"):
        self.root = os.path.abspath(os.fspath(root))
        self.rows_dir = os.path.join(self.root, "rows")
        self.runs_dir = os.path.join(self.root, "runs")
        os.makedirs(self.rows_dir, exist_ok=True)
        os.makedirs(self.runs_dir, exist_ok=True)
        self._clean_tmp()

    # ------------------------------------------------------------------ writing
    def _write_atomic(self, path: str, text: str, fsync: bool = True) -> None:
        write_text_atomic(path, text, fsync)

    def write_json(self, name: str, obj: Any) -> str:
        """Write ``obj`` as JSON to ``root/name`` atomically; returns the path."""
        path = os.path.join(self.root, name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        self._write_atomic(path, json.dumps(obj, indent=2, default=json_default) + "\n")
        return path

    def write_row(self, row: dict) -> str:
        """Write one finished row to ``rows/<config_id>.json`` atomically (replacing an older one)."""
        cid = row.get("config_id")
        if not isinstance(cid, str) or not cid or os.sep in cid or cid.startswith("."):
            raise ValueError(f"row: needs a plain string config_id, got {cid!r}")
        path = os.path.join(self.rows_dir, f"{cid}.json")
        self._write_atomic(path, dumps_row(row) + "\n")
        return path

    def _clean_tmp(self) -> None:
        """Remove temporary files left by writers that died (their pid is in the name)."""
        for d in (self.rows_dir, self.runs_dir, self.root):
            for name in os.listdir(d):
                if name.startswith(".") and name.endswith(".tmp"):
                    parts = name.split(".")
                    pid = int(parts[-3]) if len(parts) >= 4 and parts[-3].isdigit() else None
                    if pid is None or not _pid_alive(pid) or pid == os.getpid():
                        try:
                            os.remove(os.path.join(d, name))
                        except FileNotFoundError:
                            pass

    # ------------------------------------------------------------------ reading
    def done_ids(self) -> set[str]:
        """``config_id`` of every finished row (temporary files ignored)."""
        return {n[:-5] for n in os.listdir(self.rows_dir) if n.endswith(".json") and not n.startswith(".")}

    def read_row(self, cid: str) -> dict:
        """The row ``cid`` (non-finite floats restored); ``ValueError`` naming the file when it does not parse."""
        path = os.path.join(self.rows_dir, f"{cid}.json")
        with open(path, encoding="utf-8") as f:
            text = f.read()
        try:
            row = json.loads(text)
        except ValueError as e:
            raise ValueError(f"{path}: not a JSON row ({e})") from None
        if not isinstance(row, dict) or row.get("config_id") != cid:
            raise ValueError(f"{path}: not the row of {cid} (got {type(row).__name__} with config_id "
                             f"{row.get('config_id') if isinstance(row, dict) else None!r})")
        return decode_row(row)

    def quarantine_corrupt(self, ids: Optional[Sequence[str]] = None) -> list[str]:
        """Move every finished row among ``ids`` (all when None) that does not parse to
        ``<file>.corrupt-<UTC time>``, warning with its name, so that it is recomputed; returns the new paths."""
        import warnings
        moved = []
        done = self.done_ids()
        for cid in sorted(done if ids is None else set(ids) & done):
            try:
                self.read_row(cid)
            except (ValueError, UnicodeDecodeError) as e:
                src = os.path.join(self.rows_dir, f"{cid}.json")
                dst = src + ".corrupt-" + _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%S%fZ")
                os.replace(src, dst)
                warnings.warn(f"sweep row {src} is corrupt ({str(e).split(' (', 1)[-1].rstrip(')')}); moved to "
                              f"{dst} and recomputing it", RuntimeWarning, stacklevel=2)
                moved.append(dst)
        return moved

    def rows(self, ids: Optional[Sequence[str]] = None) -> list[dict]:
        """The finished rows with these ids, in this order (missing ones skipped); all when ``ids`` is None."""
        done = self.done_ids()
        ids = sorted(done) if ids is None else [i for i in ids if i in done]
        return [self.read_row(i) for i in ids]

    def read_json(self, name: str) -> Optional[Any]:
        path = os.path.join(self.root, name)
        if not os.path.isfile(path):
            return None
        with open(path, encoding="utf-8") as f:
            return json.load(f)

    # ------------------------------------------------------------------ tables
    def consolidate(self, ids: Sequence[str]) -> dict[str, str]:
        """Write ``rows.jsonl`` and ``rows.parquet`` (``rows.csv`` without pyarrow) of the rows ``ids``, in that
        order; returns ``{"jsonl": path, "parquet"|"csv": path}``."""
        return write_tables(self.rows(ids), os.path.join(self.root, "rows"))
