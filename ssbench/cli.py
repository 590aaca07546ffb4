"""The ``ssbench`` command: ``info``, ``scenes``, ``render`` and ``report``.

``main(argv)`` returns the exit status instead of exiting, so it can be called in-process; user errors print
``ssbench: error: ...`` to stderr (exit status 2 for bad arguments, 1 for a failed run) without a traceback
(set ``SSBENCH_DEBUG=1`` to get the traceback of a ``ValueError``/``KeyError`` instead).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Optional, Sequence

from .gbuffer import CHANNELS


class _UsageError(Exception):
    def __init__(self, message: str, status: int = 2):
        super().__init__(message)
        self.status = status


class _Parser(argparse.ArgumentParser):
    """argparse that reports errors as ``ssbench: error: ...`` and raises instead of exiting."""

    def error(self, message: str):  # type: ignore[override]
        self.print_usage(sys.stderr)
        raise _UsageError(message)


def _positive(name: str):
    def parse(s: str) -> int:
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a positive integer, got {s!r}") from None
        if v <= 0:
            raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
        return v
    parse.__name__ = name
    return parse


def _non_negative(s: str) -> int:
    try:
        v = int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {s!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {v}")
    return v


def _channels(s: str) -> tuple[str, ...]:
    chans = tuple(dict.fromkeys(c.strip() for c in s.split(",") if c.strip()))
    unknown = [c for c in chans if c not in CHANNELS]
    if unknown or not chans:
        raise argparse.ArgumentTypeError(f"unknown or empty channel list {list(unknown or chans)}; "
                                         f"known channels: {','.join(CHANNELS)}")
    return chans


def _scene_list(s: str) -> list[str]:
    from .scenes import catalog
    names = [n.strip() for n in s.split(",") if n.strip()]
    unknown = [n for n in names if n not in catalog.CATALOG]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown or empty scene list {unknown or names}; built-in scenes: "
                                         f"{', '.join(catalog.names())}")
    return names


def _parser() -> _Parser:
    from . import __version__
    p = _Parser(prog="ssbench", description="Screen-space rendering passes vs Mitsuba 3 ground truth.")
    p.add_argument("--version", action="version", version=f"ssbench {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    q = sub.add_parser("info", help="versions, threads and the chosen Mitsuba variant / libLLVM")
    q.add_argument("--json", action="store_true", help="print JSON")
    q = sub.add_parser("scenes", help="list the built-in scenes")
    q.add_argument("--json", action="store_true", help="print JSON")
    q = sub.add_parser("render", help="render a scene's reference G-buffer to EXR + PNG files")
    q.add_argument("scene", metavar="SCENE", help="catalog name or scene file (.yaml, .toml, .xml)")
    q.add_argument("--out", required=True, metavar="DIR", help="output directory")
    q.add_argument("--width", type=_positive("width"), help="image width (default: the scene camera's)")
    q.add_argument("--height", type=_positive("height"), help="image height (default: the scene camera's)")
    q.add_argument("--spp", type=_positive("spp"), default=64, help="colour samples per pixel (default 64)")
    q.add_argument("--seed", type=_non_negative, default=0, help="colour seed (default 0)")
    q.add_argument("--channels", type=_channels, default=tuple(CHANNELS),
                   help=f"comma-separated channels (default: all of {','.join(CHANNELS)})")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the render cache")
    q = sub.add_parser("report", help="render the built-in scenes into an HTML report")
    q.add_argument("--out", default="reports", metavar="DIR", help="reports root (default: reports)")
    q.add_argument("--width", type=_positive("width"), default=320)
    q.add_argument("--height", type=_positive("height"), default=240)
    q.add_argument("--spp", type=_positive("spp"), default=64)
    q.add_argument("--seed", type=_non_negative, default=0)
    q.add_argument("--scenes", type=_scene_list, default=None, help="comma-separated subset of the catalog")
    q.add_argument("--cache", action="store_true", help="use the render cache (timings then measure the cache)")
    return p


# ------------------------------------------------------------------------------------------ commands
def _cmd_info(args) -> int:
    from .report.build import environment
    env = environment()
    if args.json:
        print(json.dumps(env, indent=2))
        return 0
    llvm = f"{env['libllvm']} (major {env['libllvm_major']})" if env["libllvm"] else "none"
    lines = [("ssbench", env["ssbench"]), ("python", f"{env['python']} ({env['python_executable']})"),
             ("torch", f"{env['torch']} ({env['torch_threads']} threads)"), ("kornia", env["kornia"]),
             ("numpy", env["numpy"]), ("mitsuba variant", f"{env['variant']} ({env['backend_reason']})"),
             ("libLLVM", llvm), ("mitsuba", env["mitsuba"]),
             ("drjit", f"{env['drjit']} ({env['drjit_threads']} threads)"),
             ("machine", f"{env['node']}, {env['processor']}, {env['cpu_count']} CPUs")]
    for k, v in lines:
        print(f"{k:<16} {v}")
    print("probe attempts:")
    for cand, outcome in env["probe"]:
        print(f"  {cand}: {outcome}")
    return 0


def _cmd_scenes(args) -> int:
    from .scenes import catalog
    desc = catalog.describe()
    if args.json:
        print(json.dumps([{"name": n, "description": d} for n, d in desc.items()], indent=2))
        return 0
    width = max(len(n) for n in desc)
    print(f"{'name':<{width}}  description")
    print(f"{'-' * width}  {'-' * 11}")
    for n, d in desc.items():
        print(f"{n:<{width}}  {d}")
    return 0


def _load_scene(arg: str):
    from .scenes import SceneError, catalog, load
    try:
        return load(arg)
    except SceneError as e:
        raise _UsageError(f"argument SCENE: {e}") from None
    except (KeyError, ValueError, FileNotFoundError, OSError) as e:
        why = e.args[0] if e.args else str(e)
        if arg not in catalog.CATALOG and not os.path.exists(arg):
            why = f"{arg!r} is neither a built-in scene nor an existing scene file"
        raise _UsageError(f"argument SCENE: {why}; built-in scenes: {', '.join(catalog.names())}") from None


def _cmd_render(args) -> int:
    from . import io
    from .reference import backend
    from .report.build import render_scene
    sc = _load_scene(args.scene)
    t_start = time.perf_counter()
    info = backend.info()                                    # probe + import Mitsuba outside the timings
    backend_init_s = time.perf_counter() - t_start
    g, timings = render_scene(sc, args.width, args.height, args.channels, spp=args.spp, seed=args.seed,
                              use_cache=not args.no_cache)
    t0 = time.perf_counter()
    os.makedirs(args.out, exist_ok=True)
    files = []
    for ch in args.channels:
        t = getattr(g, ch)
        io.write_exr(os.path.join(args.out, f"{ch}.exr"), t[0])
        io.preview_png(os.path.join(args.out, f"{ch}.png"), ch, t, mask=g.mask, camera=g.camera)
        files += [f"{ch}.exr", f"{ch}.png"]
    timings["write_s"] = time.perf_counter() - t0
    timings["backend_init_s"] = backend_init_s
    timings["total_s"] = time.perf_counter() - t_start
    from dataclasses import asdict
    meta = {"scene": sc.name, "scene_arg": args.scene, "description": sc.description,
            "camera": asdict(g.camera), "channels": list(args.channels), "spp": args.spp, "seed": args.seed,
            "use_cache": not args.no_cache, "timings": timings, "backend": info, "files": files}
    tmp = os.path.join(args.out, ".meta.json.tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(meta, f, indent=2, default=str)
        f.write("\n")
    os.replace(tmp, os.path.join(args.out, "meta.json"))
    print(f"{sc.name} {g.width}x{g.height}: G-buffer {timings['gbuffer_s']:.3f} s"
          + (f", colour {timings['color_s']:.3f} s" if timings["color_s"] is not None else "")
          + f"; wrote {len(files) + 1} files to {args.out}")
    return 0


def _cmd_report(args) -> int:
    from .report.build import build_report
    index = build_report(args.out, scenes=args.scenes, width=args.width, height=args.height, spp=args.spp,
                         seed=args.seed, use_cache=args.cache)
    print(f"report: {index}")
    print(f"latest: {os.path.join(os.path.abspath(args.out), 'latest', 'index.html')}")
    return 0


_COMMANDS = {"info": _cmd_info, "scenes": _cmd_scenes, "render": _cmd_render, "report": _cmd_report}


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the ``ssbench`` command line; returns the exit status."""
    try:
        args = _parser().parse_args(argv)
        return _COMMANDS[args.command](args)
    except SystemExit as e:                                  # --help / --version
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    except _UsageError as e:
        print(f"ssbench: error: {e}", file=sys.stderr)
        return e.status
    except (ValueError, KeyError) as e:                      # SceneError is a ValueError
        if os.environ.get("SSBENCH_DEBUG"):
            raise
        msg = e.args[0] if isinstance(e, KeyError) and e.args else e
        print(f"ssbench: error: {msg}", file=sys.stderr)
        return 1
    except BrokenPipeError:                                  # e.g. `ssbench scenes | head`
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        return 141
    except KeyboardInterrupt:
        print("ssbench: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
