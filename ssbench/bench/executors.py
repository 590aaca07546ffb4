"""Where the configurations of a sweep run: in this process (:class:`LocalExecutor`, the default) or on a Dask
cluster (:class:`DaskExecutor`: a ``dask.distributed`` ``LocalCluster`` of worker processes, or the scheduler
address of an existing cluster). No scheduler of our own: Dask does the scheduling.

Both are context managers (a Dask one may be entered once around several sweeps: they share its cluster)
with one method, ``imap_unordered(fn, items, **kwargs)``, yielding
``(item, result, exception)`` as each call finishes (``exception`` is ``None`` on success; on a worker lost
mid-task Dask's error comes back here). The runner writes rows in the driving process, so the row store never
needs a shared filesystem; workers need ``ssbench`` installed (and, for the GT cache, ``SSBENCH_CACHE_DIR``).
A ``LocalCluster`` starts worker processes with ``spawn``: a script that uses it needs the usual
``if __name__ == "__main__":`` guard.
"""
from __future__ import annotations

import logging
import os
import secrets
from typing import Any, Callable, Iterable, Iterator, Optional

__all__ = ["LocalExecutor", "DaskExecutor", "make_executor", "EXECUTORS"]

EXECUTORS = ("local", "dask")


def pinned_backend_env() -> dict:
    """Environment that makes worker processes use this process's Mitsuba variant (and libLLVM): one variant
    per sweep, and no CUDA probe in each worker when this process found none."""
    from ..reference import backend
    c = backend.choice()
    env = {"SSBENCH_VARIANT": c.variant}
    if c.variant != "cuda_ad_rgb":
        env["SSBENCH_NO_CUDA"] = "1"
    if c.libllvm:
        env["SSBENCH_LLVM_CANDIDATES"] = c.libllvm
    return env


class LocalExecutor:
    """Sequential, in-process execution (exceptions are returned, ``KeyboardInterrupt`` propagates)."""

    name = "local"

    def __enter__(self) -> "LocalExecutor":
        return self

    def __exit__(self, *exc) -> None:
        return None

    def describe(self) -> dict:
        return {"kind": "local", "workers": 1, "pid": os.getpid()}

    def imap_unordered(self, fn: Callable, items: Iterable, **kwargs) -> Iterator[tuple[Any, Any, Optional[BaseException]]]:
        for item in items:
            try:
                yield item, fn(item, **kwargs), None
            except Exception as e:             # noqa: BLE001 - handed to the caller, which records it
                yield item, None, e


class DaskExecutor:
    """Run on ``dask.distributed``: a new ``LocalCluster`` (``workers`` processes, one thread each, default
    ``min(4, cpu count)``, pinned to this process's Mitsuba variant by :func:`pinned_backend_env`) or the
    existing cluster at ``address`` (``tcp://host:8786``; rows record each worker's ``variant``).

    Each task's key is ``ssbench-<config_id>-<token>``, so the dashboard names the configuration.
    """

    name = "dask"

    def __init__(self, address: Optional[str] = None, workers: Optional[int] = None, threads_per_worker: int = 1):
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers: must be a positive integer, got {workers!r}")
        if address is not None and workers is not None:
            raise ValueError("workers: give either an address of an existing cluster or a worker count, not both")
        self.address, self.workers, self.threads_per_worker = address, workers, threads_per_worker
        self.client = self.cluster = None
        self._depth = 0                 # nested ``with`` blocks share one client (run_sweep enters it again)

    def __enter__(self) -> "DaskExecutor":
        self._depth += 1
        if self.client is not None:
            return self
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError as e:                       # pragma: no cover - a declared dependency
            raise ImportError("executor: the Dask executor needs dask[distributed] "
                              "(pip install 'dask[distributed]')") from e
        if self.address:
            self.client = Client(self.address)
        else:
            n = self.workers or max(1, min(4, os.cpu_count() or 1))
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=self.threads_per_worker, processes=True,
                                        dashboard_address=":0", silence_logs=logging.WARNING,
                                        env=pinned_backend_env())
            self.client = Client(self.cluster)
        return self

    def __exit__(self, *exc) -> None:
        self._depth -= 1
        if self._depth > 0:
            return
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        self.client = self.cluster = None

    def describe(self) -> dict:
        info = self.client.scheduler_info() if self.client is not None else {}
        return {"kind": "dask", "address": self.address or (self.cluster.scheduler_address if self.cluster else None),
                "local_cluster": self.cluster is not None, "workers": len(info.get("workers", {})),
                "threads_per_worker": self.threads_per_worker}

    def imap_unordered(self, fn: Callable, items: Iterable, **kwargs) -> Iterator[tuple[Any, Any, Optional[BaseException]]]:
        if self.client is None:
            raise RuntimeError("DaskExecutor: use it as a context manager (with DaskExecutor() as ex: ...)")
        from dask.distributed import as_completed
        items = list(items)
        if not items:
            return
        token = secrets.token_hex(4)
        keys = [f"ssbench-{getattr(it, 'config_id', i)}-{token}" for i, it in enumerate(items)]
        futures = self.client.map(fn, items, key=keys, **kwargs)
        which = {f.key: it for f, it in zip(futures, items)}
        for fut in as_completed(futures):
            item = which[fut.key]
            if fut.status == "finished":
                yield item, fut.result(), None
            else:
                try:
                    exc = fut.exception()
                except BaseException as e:              # noqa: BLE001 - e.g. a cancelled future
                    exc = e
                yield item, None, exc
            fut.release()


def make_executor(kind: str = "local", *, workers: Optional[int] = None, address: Optional[str] = None):
    """An executor by name: ``"local"`` or ``"dask"`` (an ``address`` implies ``"dask"``)."""
    if address and kind == "local":
        kind = "dask"
    if kind == "local":
        if workers not in (None, 1):
            raise ValueError(f"workers: the local executor runs one configuration at a time, got {workers}; "
                             f"use executor 'dask' for parallel workers")
        return LocalExecutor()
    if kind == "dask":
        return DaskExecutor(address=address, workers=workers)
    raise ValueError(f"executor: unknown executor {kind!r}; known: {', '.join(EXECUTORS)}")
