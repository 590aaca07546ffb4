"""``ssbench sweep CONFIG``: the command-line face of :func:`ssbench.bench.sweep.run_sweep`.

The main ``ssbench`` parser adds it with :func:`add_sweep_parser` and dispatches to :func:`cmd_sweep`; this
module also runs on its own: ``python -m ssbench.cli._sweep_cmd sweep CONFIG ...`` (:func:`main`).
A bad sweep file raises :class:`~ssbench.bench.config.SweepError` (a ``ValueError`` reading
``file:line: field: what is wrong``), which the ``ssbench`` command prints as ``ssbench: error: ...``.
"""
from __future__ import annotations

import argparse
import os
import sys
from typing import Optional, Sequence

__all__ = ["add_sweep_parser", "cmd_sweep", "main"]


def _workers(s: str) -> int:
    try:
        v = int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {s!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
    return v


def add_sweep_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``sweep`` sub-command to ``subparsers`` (from ``parser.add_subparsers()``); returns it.

    Its ``handler`` default is :func:`cmd_sweep` (``args.handler(args)`` runs it).
    """
    q = subparsers.add_parser(
        "sweep", help="run a sweep file (YAML/TOML): scenes x methods x parameter grids x seeds -> tidy rows",
        description="Run every configuration of a sweep file; rows go to DIR/rows/<config_id>.json as they "
                    "finish, then DIR/rows.jsonl and DIR/rows.parquet. Re-running resumes where it stopped.")
    q.add_argument("config", metavar="CONFIG", help="sweep file (.yaml, .yml or .toml)")
    q.add_argument("--out", metavar="DIR", help="output folder (default: reports/sweeps/<sweep name>)")
    q.add_argument("--executor", choices=("local", "dask"), default="local",
                   help="local: in this process, one at a time (default); dask: a Dask LocalCluster or --address")
    q.add_argument("--workers", type=_workers, metavar="N", help="Dask LocalCluster worker processes "
                   "(default min(4, CPUs))")
    q.add_argument("--address", metavar="URL", help="scheduler of an existing Dask cluster (implies --executor dask)")
    q.add_argument("--resume", action=argparse.BooleanOptionalAction, default=True,
                   help="skip configurations whose row is stored (default); --no-resume recomputes all")
    q.add_argument("--retry-errors", action="store_true", help="when resuming, run failed configurations again")
    q.add_argument("--dry-run", action="store_true", help="validate and list the configurations; run nothing")
    q.add_argument("--quiet", action="store_true", help="no progress bar")
    q.set_defaults(handler=cmd_sweep)
    return q


def cmd_sweep(args) -> int:
    """Handle ``ssbench sweep``: 0 when the sweep ran (failing configurations are rows with ``error``)."""
    from ..bench.config import load_sweep
    from ..bench.sweep import default_out, run_sweep
    sweep = load_sweep(args.config)
    out = args.out or default_out(sweep)
    if args.dry_run:
        print(f"{sweep.name}: {len(sweep)} configurations of effect {sweep.effect} "
              f"(timing {'on' if sweep.timing else 'off'}) -> {out}")
        for c in sweep.configs:
            params = ",".join(f"{k}={v}" for k, v in c.params.items()) or "defaults"
            print(f"  {c.config_id}  {c.scene} {c.method} {params} seed={c.seed} {c.width}x{c.height}")
        return 0
    from ._args import out_dir
    out_dir(out)
    executor = "dask" if args.address else args.executor
    res = run_sweep(sweep, out, executor=executor, workers=args.workers, address=args.address,
                    resume=args.resume, retry_errors=args.retry_errors, progress=not args.quiet)
    for note in res.notes:
        print(f"note: {note}", file=sys.stderr)
    print(f"{sweep.name}: {len(res.rows)} rows ({res.ran} run, {res.skipped} resumed, "
          f"{sum(bool(r.get('error')) for r in res.rows)} with errors) in {res.out}")
    for kind, path in res.tables.items():
        print(f"  {kind}: {os.path.relpath(path)}")
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m ssbench.cli._sweep_cmd sweep CONFIG ...``: the ``ssbench`` command line
    (:func:`ssbench.cli.main`); returns the exit status (1 for a bad sweep file)."""
    from . import main as ssbench_main
    return ssbench_main(argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
