"""The ``ssbench`` command: ``info``, ``scenes``, ``render``, ``ao``, ``ssr``, ``implicit``, ``frames``, ``sweep``,
``tune`` and ``report``.

``main(argv)`` returns the exit status instead of exiting, so it can be called in-process; user errors print
``ssbench: error: ...`` to stderr (exit status 2 for bad arguments, 1 for a failed run) without a traceback
(set ``SSBENCH_DEBUG=1`` to get the traceback instead). Any other exception, an ``OSError`` included, is
reported the same way, in one line; work above :data:`~ssbench.cli._args.LIMITS` needs ``--force``.
"""
from __future__ import annotations

import os
import sys
from typing import Optional, Sequence

from ..gbuffer import CHANNELS
from ._args import (UsageError, Parser, channels_arg, define_arg, non_negative, non_negative_float, param_arg, positive,
                    positive_float, gt_rays, scene_list, size_arg, coerce_params, parse_value)  # noqa: F401
from ._effect_cmds import cmd_ao, cmd_ssr
from ._frames_cmd import add_parser as add_frames_parser, cmd_frames
from ._implicit_cmd import cmd_implicit
from ._scene_cmds import cmd_info, cmd_render, cmd_report, cmd_scenes


def _scene_arguments(q) -> None:
    """The SCENE argument of ``render``, ``ao`` and ``ssr``, with its ``-D`` overrides."""
    q.add_argument("scene", metavar="SCENE", help="catalog name or scene file (.yaml, .toml, Mitsuba 3 .xml)")
    q.add_argument("-D", dest="defines", type=define_arg, action="append", default=[], metavar="NAME=VALUE",
                   help="override a Mitsuba scene file's $NAME parameter (repeatable), e.g. -D res=256")


def _parser() -> Parser:
    from .. import __version__
    p = Parser(prog="ssbench", description="Screen-space rendering passes vs Mitsuba 3 ground truth.")
    p.add_argument("--version", action="version", version=f"ssbench {__version__}")
    p.add_argument("--compile", action="store_true",
                   help="run the passes' kernels (AO bands, SSR march steps, glossy reuse) through torch.compile "
                        "(sets SSBENCH_COMPILE=1 for this "
                        "command and its subprocesses; compile time is kept out of the timings and reported as "
                        "compile_s)")
    p.add_argument("--threads", type=positive("threads"), default=None,
                   help="torch threads of the ao, ssr and implicit commands, whose rows carry their times "
                        "(default: 1 on a machine of at most 2 cores, else torch's own count)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True
    q = sub.add_parser("info", help="versions, threads and the chosen Mitsuba variant / libLLVM")
    q.add_argument("--json", action="store_true", help="print JSON")
    q = sub.add_parser("scenes", help="list the built-in scenes")
    q.add_argument("--json", action="store_true", help="print JSON")
    q = sub.add_parser("render", help="render a scene's reference G-buffer to EXR + PNG files")
    _scene_arguments(q)
    q.add_argument("--out", required=True, metavar="DIR", help="output directory")
    q.add_argument("--width", type=positive("width"), help="image width (default: the scene camera's)")
    q.add_argument("--height", type=positive("height"), help="image height (default: the scene camera's)")
    q.add_argument("--spp", type=positive("spp"), default=64, help="colour samples per pixel (default 64)")
    q.add_argument("--seed", type=non_negative, default=0, help="colour seed (default 0)")
    q.add_argument("--channels", type=channels_arg, default=tuple(CHANNELS),
                   help=f"comma-separated channels (default: all of {','.join(CHANNELS)})")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the render cache")
    q.add_argument("--force", action="store_true", help="run work above the size limits (ssbench/RELIABILITY.md)")
    from ..passes import AO_METHODS
    from ..reference.ao import WEIGHTINGS as AO_WEIGHTINGS
    q = sub.add_parser("ao", help="run one AO method on a scene and score it against the ray-traced GT")
    _scene_arguments(q)
    q.add_argument("--method", required=True, choices=list(AO_METHODS), help="AO method")
    q.add_argument("--param", type=param_arg, action="append", default=[], metavar="NAME=VALUE",
                   help="override a pass parameter (repeatable), e.g. --param num_steps=8")
    q.add_argument("--radius", type=positive_float, help="radius of the pass and the GT (default: the pass's)")
    q.add_argument("--weighting", choices=AO_WEIGHTINGS,
                   help="GT flavour to score against (default: the one the pass approximates)")
    q.add_argument("--blur", choices=("box", "cross_bilateral", "joint_bilateral"),
                   help="blur the pass output before scoring (noise_raw/banding_raw keep the raw AO)")
    q.add_argument("--width", type=positive("width"), default=320)
    q.add_argument("--height", type=positive("height"), default=240)
    q.add_argument("--rays", type=gt_rays, default=256, help="GT rays per pixel, >= 2 (default 256)")
    q.add_argument("--seed", type=non_negative, default=0)
    q.add_argument("--repeats", type=positive("repeats"), default=3, help="timed runs after a warm-up")
    q.add_argument("--out", metavar="DIR", help="write ao.png, gt.png, error maps and row.json here")
    q.add_argument("--json", action="store_true", help="print the row as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the render cache")
    q.add_argument("--force", action="store_true", help="run work above the size limits (ssbench/RELIABILITY.md)")
    from ..passes import SSR_METHODS
    q = sub.add_parser("ssr", help="run one SSR method on a scene and classify it against the exact reflections")
    _scene_arguments(q)
    q.add_argument("--method", required=True, choices=list(SSR_METHODS), help="SSR method")
    q.add_argument("--param", type=param_arg, action="append", default=[], metavar="NAME=VALUE",
                   help="override a pass parameter (repeatable), e.g. --param pixel_stride=4")
    q.add_argument("--width", type=positive("width"), default=320)
    q.add_argument("--height", type=positive("height"), default=240)
    q.add_argument("--spp", type=positive("spp"), default=16,
                   help="samples per pixel of the colour buffer and the mirror radiance (default 16)")
    q.add_argument("--k-px", type=positive_float, default=1.5, dest="k_px",
                   help="hit tolerance in pixels for a correct hit (default 1.5)")
    q.add_argument("--seed", type=non_negative, default=0)
    q.add_argument("--repeats", type=positive("repeats"), default=3, help="timed runs after a warm-up")
    q.add_argument("--out", metavar="DIR", help="write colour, class, visit and error maps and row.json here")
    q.add_argument("--json", action="store_true", help="print the row as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the render cache")
    q.add_argument("--force", action="store_true", help="run work above the size limits (ssbench/RELIABILITY.md)")
    from ..passes import IMPLICIT_METHODS
    q = sub.add_parser("implicit", help="ray cast an implicit-surface scene over frames, scored against the "
                                        "certified first hit")
    q.add_argument("scene", metavar="SCENE", help="implicit catalog name or scene file (.yaml, .toml)")
    q.add_argument("--method", choices=list(IMPLICIT_METHODS), default="progressive",
                   help="ray caster (default progressive)")
    q.add_argument("--frames", type=positive("frames"), default=60, help="frames to cast (default 60)")
    q.add_argument("--steps", type=positive("steps"), help="marching steps N (sphere: max_steps)")
    q.add_argument("--param", type=param_arg, action="append", default=[], metavar="NAME=VALUE",
                   help="override a method parameter (repeatable), e.g. --param epsilon=0.002")
    q.add_argument("--size", type=size_arg, metavar="WxH", help="image size (default: the scene camera's)")
    q.add_argument("--seed", type=non_negative, default=0)
    q.add_argument("--truth", choices=("all", "last", "none"), default="all",
                   help="frames scored against the reference (default all; 'last' for long animations)")
    q.add_argument("--out", metavar="DIR", help="write colour, t, evaluations and class-map PNGs and row.json")
    q.add_argument("--gif", action="store_true", help="with --out: also write the frames as frames.gif")
    q.add_argument("--fps", type=positive("fps"), default=10, help="frames per second of the GIF (10)")
    q.add_argument("--json", action="store_true", help="print the row as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the reference cache")
    q.add_argument("--force", action="store_true", help="run work above the size limits (ssbench/RELIABILITY.md)")
    add_frames_parser(sub)
    from ._sweep_cmd import add_sweep_parser
    from ._tune_cmd import add_tune_parser
    add_sweep_parser(sub)
    add_tune_parser(sub)
    q = sub.add_parser("report", help="render the built-in scenes into an HTML report")
    q.add_argument("--out", default="reports", metavar="DIR", help="reports root (default: reports)")
    q.add_argument("--width", type=positive("width"), default=640)
    q.add_argument("--height", type=positive("height"), default=360)
    q.add_argument("--spp", type=positive("spp"), default=64)
    q.add_argument("--seed", type=non_negative, default=0)
    q.add_argument("--scenes", type=scene_list, default=None, help="comma-separated subset of the catalog")
    q.add_argument("--scene", dest="extra_scenes", action="append", default=[], metavar="FILE",
                   help="add your own scene file (Mitsuba .xml, .yaml, .toml) to the previews and the AO and SSR "
                        "sections (repeatable)")
    q.add_argument("--fresh-previews", action="store_true", help="render and time the scene previews afresh (by "
                   "default they come from the render cache when there, with the times recorded when rendered)")
    q.add_argument("--no-gt-cache", action="store_true", help="trace every section's ground truth afresh (by "
                   "default the reference cache is read and written)")
    q.add_argument("--no-ao", action="store_true", help="leave out the ambient-occlusion section")
    q.add_argument("--ao-radius", type=positive_float, default=0.5, help="AO radius of the report (0.5)")
    q.add_argument("--ao-rays", type=gt_rays, default=128, help="AO GT rays per pixel (128)")
    q.add_argument("--no-ssr", action="store_true", help="leave out the screen-space reflections section")
    q.add_argument("--ssr-spp", type=positive("ssr-spp"), default=16,
                   help="samples per pixel of the SSR mirror radiance (16)")
    q.add_argument("--no-implicit", action="store_true", help="leave out the implicit-surface section")
    q.add_argument("--no-speed", action="store_true", help="leave out the speed section")
    q.add_argument("--no-tuning", action="store_true", help="leave out the tuning section")
    q.add_argument("--no-time", action="store_true",
                   help="leave out the time section (flicker, ghosting and error over frames, raw and accumulated)")
    q.add_argument("--no-glossy", action="store_true",
                   help="skip the glossy-reflections section (every SSR method on rough surfaces vs the path-traced lobe)")
    q.add_argument("--no-calibration", action="store_true",
                   help="leave out the metric calibration section (each metric against its artifact's knob)")
    q.add_argument("--screenshots", action="store_true",
                   help="also save one PNG per section, as headless Chromium shows it at 1400 px, to RUN/screenshots/ "
                        "(needs chromium on PATH; with --from: of that run)")
    q.add_argument("--from", dest="from_run", metavar="RUN",
                   help="instead of building: re-render RUN's index.html and summary.md from its meta.json, "
                        "computing nothing (a folder, a name under --out, or 'latest')")
    q.add_argument("--compare", nargs=2, metavar=("RUN_A", "RUN_B"),
                   help="instead of building: compare two runs (folders, names under --out, or 'latest')")
    q.add_argument("--rtol", type=non_negative_float, default=1e-3,
                   help="with --compare: relative tolerance of result changes (0.001)")
    q.add_argument("--time-rtol", type=non_negative_float, default=0.25,
                   help="with --compare: relative change of a time worth listing (0.25)")
    q.set_defaults(report_parser=q)
    return p



_COMMANDS = {"info": cmd_info, "scenes": cmd_scenes, "render": cmd_render, "ao": cmd_ao,
             "ssr": cmd_ssr, "implicit": cmd_implicit, "frames": cmd_frames, "report": cmd_report}


def _cmd_sweep(args) -> int:
    from ._sweep_cmd import cmd_sweep
    return cmd_sweep(args)


def _cmd_tune(args) -> int:
    from ._tune_cmd import cmd_tune
    return cmd_tune(args)


_COMMANDS["sweep"] = _cmd_sweep
_COMMANDS["tune"] = _cmd_tune


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the ``ssbench`` command line; returns the exit status."""
    import warnings
    previous = warnings.formatwarning                        # warnings read as one line, for this call only
    warnings.formatwarning = lambda message, category, *rest, **kw: (
        f"ssbench: {'note' if category.__name__ == 'SceneNote' else 'warning'}: {message}\n")
    try:
        return _dispatch(argv)
    finally:
        warnings.formatwarning = previous


#: commands whose rows carry the pass's own time: they run on ``--threads`` torch threads
_TIMED = ("ao", "ssr", "implicit")


def _timed(args) -> int:
    """Run the command; a timed one on ``--threads`` (:func:`ssbench.runinfo.timing_threads`), restored after."""
    if args.command not in _TIMED:
        return _COMMANDS[args.command](args)
    import torch

    from ..runinfo import timing_threads
    before = torch.get_num_threads()
    torch.set_num_threads(timing_threads(args.threads))
    try:
        return _COMMANDS[args.command](args)
    finally:
        torch.set_num_threads(before)


def _dispatch(argv: Optional[Sequence[str]]) -> int:
    args = None
    try:
        args = _parser().parse_args(argv)
        if not args.compile:
            return _timed(args)
        from ..passes.compiled import ENV
        before = os.environ.get(ENV)
        os.environ[ENV] = "1"                                # inherited by sweep and timing subprocesses
        try:
            return _timed(args)
        finally:
            if before is None:
                os.environ.pop(ENV, None)
            else:
                os.environ[ENV] = before
    except SystemExit as e:                                  # --help / --version
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    except UsageError as e:
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
        resume = " (re-run the same command to resume)" if getattr(args, "command", None) == "sweep" else ""
        print(f"ssbench: interrupted{resume}", file=sys.stderr)
        return 130
    except OSError as e:                                     # a file or folder the run could not read or write
        if os.environ.get("SSBENCH_DEBUG"):
            raise
        where = f"{e.filename}: " if e.filename else ""
        print(f"ssbench: error: {where}{e.strerror or e}", file=sys.stderr)
        return 1
    except Exception as e:                                   # never a traceback: one line, and how to get it
        if os.environ.get("SSBENCH_DEBUG"):
            raise
        msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
        print(f"ssbench: error: {type(e).__name__}: {msg} (set SSBENCH_DEBUG=1 for the traceback)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

