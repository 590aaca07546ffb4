"""The ``ssbench`` command: ``info``, ``scenes``, ``render``, ``ao``, ``ssr``, ``implicit``, ``sweep`` and ``report``.

``main(argv)`` returns the exit status instead of exiting, so it can be called in-process; user errors print
``ssbench: error: ...`` to stderr (exit status 2 for bad arguments, 1 for a failed run) without a traceback
(set ``SSBENCH_DEBUG=1`` to get the traceback of a ``ValueError``/``KeyError`` instead).
"""
from __future__ import annotations

import argparse
import json
import math
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


def _int_at_least(lo: int, what: str, why: str = "", name: str = "int"):
    """argparse type: an integer >= ``lo``; errors read ``expected <what>[<why>], got ...``."""
    def parse(s: str) -> int:
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {s!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"expected {what}{why}, got {v}")
        return v
    parse.__name__ = name
    return parse


def _positive(name: str):
    return _int_at_least(1, "a positive integer", name=name)


_non_negative = _int_at_least(0, "a non-negative integer", name="non_negative")
_rays = _int_at_least(2, "an integer >= 2", " (for a standard error)", name="rays")


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


def _positive_float(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {s!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {s!r}")
    return v


def _non_negative_float(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {s!r}")
    return v


def _size(s: str) -> tuple[int, int]:
    w, sep, h = s.lower().partition("x")
    try:
        size = (int(w), int(h))
    except ValueError:
        size = None
    if not sep or size is None or min(size) < 1:
        raise argparse.ArgumentTypeError(f"expected WxH with two positive integers (e.g. 96x72), got {s!r}")
    return size


_BOOLS = {"true": True, "yes": True, "on": True, "false": False, "no": False, "off": False}


def parse_value(text: str):
    """A ``--param`` value as bool (true/false/yes/no/on/off), int, float or else str; never ``eval``."""
    t = text.strip()
    if t.lower() in _BOOLS:
        return _BOOLS[t.lower()]
    try:
        return int(t, 10)
    except ValueError:
        pass
    try:
        v = float(t)
    except ValueError:
        return t
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"value {text!r} is not a finite number")
    return v


def _param(s: str) -> tuple[str, object]:
    name, sep, value = s.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier() or not value.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE (e.g. radius=0.5), got {s!r}")
    return name, parse_value(value)


def coerce_params(params_cls, pairs, method: str) -> dict:
    """``--param`` pairs checked against the pass's params dataclass: known names, no repeats, and values
    of the default's type (an int is accepted for a float; anything else is an error naming the parameter)."""
    import dataclasses
    defaults = params_cls()
    known = {f.name: getattr(defaults, f.name) for f in dataclasses.fields(params_cls)}
    out: dict = {}
    for name, value in pairs:
        if name not in known:
            raise _UsageError(f"argument --param: unknown parameter {name!r} for {method}; "
                              f"known: {', '.join(known)}")
        if name in out:
            raise _UsageError(f"argument --param: {name} given twice")
        d = known[name]
        if isinstance(d, bool):
            ok = isinstance(value, bool)
        elif isinstance(d, int):
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif isinstance(d, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            value = float(value) if ok else value
        elif isinstance(d, str):
            ok, value = True, str(value)
        else:
            ok = d is None or isinstance(value, type(d))
        if not ok:
            raise _UsageError(f"argument --param: {name} expects {type(d).__name__} (default {d!r}), "
                              f"got {value!r}")
        out[name] = value
    return out


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
    from .passes import AO_METHODS
    q = sub.add_parser("ao", help="run one AO method on a scene and score it against the ray-traced GT")
    q.add_argument("scene", metavar="SCENE", help="catalog name or scene file (.yaml, .toml, .xml)")
    q.add_argument("--method", required=True, choices=list(AO_METHODS), help="AO method")
    q.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="override a pass parameter (repeatable), e.g. --param num_steps=8")
    q.add_argument("--radius", type=_positive_float, help="radius of the pass and the GT (default: the pass's)")
    q.add_argument("--weighting", choices=("uniform", "cosine", "obscurance"),
                   help="GT flavour to score against (default: the one the pass approximates)")
    q.add_argument("--blur", choices=("box", "cross_bilateral", "joint_bilateral"),
                   help="blur the pass output before scoring (noise_raw/banding_raw keep the raw AO)")
    q.add_argument("--width", type=_positive("width"), default=320)
    q.add_argument("--height", type=_positive("height"), default=240)
    q.add_argument("--rays", type=_rays, default=256, help="GT rays per pixel, >= 2 (default 256)")
    q.add_argument("--seed", type=_non_negative, default=0)
    q.add_argument("--repeats", type=_positive("repeats"), default=3, help="timed runs after a warm-up")
    q.add_argument("--out", metavar="DIR", help="write ao.png, gt.png, error maps and row.json here")
    q.add_argument("--json", action="store_true", help="print the row as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the render cache")
    from .passes import SSR_METHODS
    q = sub.add_parser("ssr", help="run one SSR method on a scene and classify it against the exact reflections")
    q.add_argument("scene", metavar="SCENE", help="catalog name or scene file (.yaml, .toml, .xml)")
    q.add_argument("--method", required=True, choices=list(SSR_METHODS), help="SSR method")
    q.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="override a pass parameter (repeatable), e.g. --param pixel_stride=4")
    q.add_argument("--width", type=_positive("width"), default=320)
    q.add_argument("--height", type=_positive("height"), default=240)
    q.add_argument("--spp", type=_positive("spp"), default=16,
                   help="samples per pixel of the colour buffer and the mirror radiance (default 16)")
    q.add_argument("--k-px", type=_positive_float, default=1.5, dest="k_px",
                   help="hit tolerance in pixels for a correct hit (default 1.5)")
    q.add_argument("--seed", type=_non_negative, default=0)
    q.add_argument("--repeats", type=_positive("repeats"), default=3, help="timed runs after a warm-up")
    q.add_argument("--out", metavar="DIR", help="write colour, class, visit and error maps and row.json here")
    q.add_argument("--json", action="store_true", help="print the row as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the render cache")
    from .passes import IMPLICIT_METHODS
    q = sub.add_parser("implicit", help="ray cast an implicit-surface scene over frames, scored against the "
                                        "certified first hit")
    q.add_argument("scene", metavar="SCENE", help="implicit catalog name or scene file (.yaml, .toml)")
    q.add_argument("--method", choices=list(IMPLICIT_METHODS), default="progressive",
                   help="ray caster (default progressive)")
    q.add_argument("--frames", type=_positive("frames"), default=60, help="frames to cast (default 60)")
    q.add_argument("--steps", type=_positive("steps"), help="marching steps N (sphere: max_steps)")
    q.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="override a method parameter (repeatable), e.g. --param epsilon=0.002")
    q.add_argument("--size", type=_size, metavar="WxH", help="image size (default: the scene camera's)")
    q.add_argument("--seed", type=_non_negative, default=0)
    q.add_argument("--truth", choices=("all", "last", "none"), default="all",
                   help="frames scored against the reference (default all; 'last' for long animations)")
    q.add_argument("--out", metavar="DIR", help="write colour, t, evaluations and class-map PNGs and row.json")
    q.add_argument("--gif", action="store_true", help="with --out: also write the frames as frames.gif")
    q.add_argument("--fps", type=_positive("fps"), default=10, help="frames per second of the GIF (10)")
    q.add_argument("--json", action="store_true", help="print the row as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the reference cache")
    from .bench.cli import add_sweep_parser
    add_sweep_parser(sub)
    q = sub.add_parser("report", help="render the built-in scenes into an HTML report")
    q.add_argument("--out", default="reports", metavar="DIR", help="reports root (default: reports)")
    q.add_argument("--width", type=_positive("width"), default=320)
    q.add_argument("--height", type=_positive("height"), default=240)
    q.add_argument("--spp", type=_positive("spp"), default=64)
    q.add_argument("--seed", type=_non_negative, default=0)
    q.add_argument("--scenes", type=_scene_list, default=None, help="comma-separated subset of the catalog")
    q.add_argument("--cache", action="store_true", help="use the render cache (timings then measure the cache)")
    q.add_argument("--no-ao", action="store_true", help="leave out the ambient-occlusion section")
    q.add_argument("--ao-radius", type=_positive_float, default=0.5, help="AO radius of the report (0.5)")
    q.add_argument("--ao-rays", type=_rays, default=128, help="AO GT rays per pixel (128)")
    q.add_argument("--no-ssr", action="store_true", help="leave out the screen-space reflections section")
    q.add_argument("--ssr-spp", type=_positive("ssr-spp"), default=16,
                   help="samples per pixel of the SSR mirror radiance (16)")
    q.add_argument("--no-implicit", action="store_true", help="leave out the implicit-surface section")
    q.add_argument("--no-speed", action="store_true", help="leave out the speed section")
    q.add_argument("--no-tuning", action="store_true", help="leave out the tuning section")
    q.add_argument("--compare", nargs=2, metavar=("RUN_A", "RUN_B"),
                   help="instead of building: compare two runs (folders, names under --out, or 'latest')")
    q.add_argument("--rtol", type=_non_negative_float, default=1e-3,
                   help="with --compare: relative tolerance of result changes (0.001)")
    q.add_argument("--time-rtol", type=_non_negative_float, default=0.25,
                   help="with --compare: relative change of a time worth listing (0.25)")
    q.set_defaults(report_parser=q)
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


def _ao_table(row: dict) -> str:
    from .evaluate import TARGET_METRICS
    from .report.ao_section import fmt
    blur = f" · blur {row['blur']} ({fmt(row['blur_seconds'], '{:.4f}')} s)" if row["blur"] else ""
    head = (f"{row['scene']} · {row['method']} · {row['width']}x{row['height']} · radius {row['radius']} "
            f"({row['radius_param']}) · flavour {row['weighting']} · {row['rays']} GT rays · seed {row['seed']}\n"
            f"params: {', '.join(f'{k}={v}' for k, v in row['params'].items())}{blur}\n"
            f"time {fmt(row['seconds'], '{:.4f}')} s (median of {row['repeats']}, {row['threads']} threads)\n")
    cols = ("cos", "flavour", "oracle")
    lines = [f"{'metric':<16}" + "".join(f"{c:>12}" for c in cols)]
    for m in TARGET_METRICS:
        lines.append(f"{m:<16}" + "".join(f"{fmt(row[f'{m}_{c}']):>12}" for c in cols))
    extra = [("banding", "{:.4f}"), ("noise", "{:.3e}"), ("info_loss_rmse", "{:.4f}"), ("estimator_rmse", "{:.4f}"),
             ("gt_stderr_cos", "{:.4f}")]
    if row["blur"]:
        extra += [("banding_raw", "{:.4f}"), ("noise_raw", "{:.3e}")]
    lines += [f"{k:<16}{fmt(row[k], spec):>12}" for k, spec in extra]
    if not row["oracle"] and row.get("oracle_error"):
        lines.append(f"oracle unavailable: {row['oracle_error']}")
    return head + "\n".join(lines)


def _scene_and_params(args, resolve):
    """Scene, parameter class and ``--param`` overrides of an ``ao``/``ssr`` command."""
    sc = _load_scene(args.scene)
    try:
        _, params_cls, _ = resolve(args.method)
    except (ImportError, AttributeError) as e:
        raise _UsageError(f"argument --method: {args.method} is not importable ({type(e).__name__}: {e})", 1)
    return sc, params_cls, coerce_params(params_cls, args.param, args.method)


def _check_params(params_cls, params, method) -> None:
    """The parameter dataclass's own checks, up front, as a usage error."""
    from . import evaluate
    try:
        evaluate.resolve_params(params_cls, params, method)
    except (ValueError, TypeError) as e:
        raise _UsageError(f"argument --param: {e}") from None


def _cmd_ao(args) -> int:
    from . import evaluate
    from .passes import ao_method
    sc, params_cls, params = _scene_and_params(args, ao_method)
    rname = evaluate.radius_param(params_cls, sys.modules.get(params_cls.__module__))
    if args.radius is not None and rname in params:
        raise _UsageError(f"argument --radius: conflicts with --param {rname}={params[rname]}; give one of them")
    _check_params(params_cls, params, args.method)
    try:
        ev = evaluate.run_ao(sc, args.method, params, width=args.width, height=args.height, radius=args.radius,
                             rays=args.rays, weighting=args.weighting, seed=args.seed, repeats=args.repeats,
                             blur=args.blur, use_cache=not args.no_cache)
    except RuntimeError as e:                                # e.g. no vectorised Mitsuba variant for the GT
        if os.environ.get("SSBENCH_DEBUG"):
            raise
        raise _UsageError(str(e), 1) from None
    row = ev.row
    print(json.dumps(row, indent=2, default=str) if args.json else _ao_table(row))
    if args.out:
        from .report.ao_section import ao_rgb, error_rgb, write_png
        mask = ev.gbuffer.mask
        write_png(os.path.join(args.out, "ao.png"), ao_rgb(ev.ao, mask))
        for t, r in ev.references.items():
            write_png(os.path.join(args.out, f"gt_{t}.png"), ao_rgb(r.ao, mask))
            write_png(os.path.join(args.out, f"error_{t}.png"), error_rgb(ev.ao - r.ao, mask))
        tmp = os.path.join(args.out, ".row.json.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(row, f, indent=2, default=str)
            f.write("\n")
        os.replace(tmp, os.path.join(args.out, "row.json"))
        if not args.json:
            print(f"wrote {2 * len(ev.references) + 2} files to {args.out}")
    return 0


def _ssr_table(row: dict) -> str:
    from .metrics.ssr import CLASS_NAMES
    from .report.ao_section import fmt
    head = (f"{row['scene']} · {row['method']} · {row['width']}x{row['height']} · {row['spp']} spp · "
            f"k {row['k_px']} px · seed {row['seed']}\n"
            f"params: {', '.join(f'{k}={v}' for k, v in row['params'].items())}\n"
            f"time {fmt(row['seconds'], '{:.4f}')} s (median of {row['repeats']}, {row['threads']} threads); "
            f"exact reflections {fmt(row['gt_seconds'], '{:.3f}')} s\n"
            f"reflective pixels {row['reflective_pixels']} ({fmt(row['coverage'], '{:.1%}')} of the image); "
            f"pass hits {fmt(row['hit_rate'], '{:.1%}')}, truth hits {fmt(row['truth_hit_rate'], '{:.1%}')}\n")
    lines = [f"{'class':<20}{'share':>10}{'pass hit':>10}"]
    for key in CLASS_NAMES.values():
        if key == "not_reflective":
            continue
        extra = row.get(f"frac_{key}_pass_hit")
        lines.append(f"{key:<20}{fmt(row[f'frac_{key}'], '{:.2%}'):>10}"
                     + (f"{fmt(extra, '{:.2%}'):>10}" if extra is not None else ""))
    lines.append(f"{'hit error':<20}{'px':>10}{'view':>10}   (over {int(row['hit_err_n'])} hit pairs)")
    for s in ("mean", "median", "p95", "max"):
        lines.append(f"  {s:<18}{fmt(row[f'hit_err_px_{s}'], '{:.3f}'):>10}"
                     f"{fmt(row[f'hit_err_view_{s}'], '{:.4f}'):>10}")
    lines.append(f"{'colour':<20}{'raw':>10}{'faded':>10}")
    for m, spec in (("mae", "{:.4f}"), ("rmse", "{:.4f}"), ("psnr", "{:.2f}"), ("flip", "{:.4f}")):
        lines.append(f"  {m:<18}{fmt(row[f'{m}_raw'], spec):>10}{fmt(row[f'{m}_faded'], spec):>10}")
    lines.append(f"  {'mae (truth hits)':<18}{fmt(row['mae_raw_truth_hit'], '{:.4f}'):>10}"
                 f"{fmt(row['mae_faded_truth_hit'], '{:.4f}'):>10}")
    terms = ", ".join(f"{k[5:]} {fmt(v, '{:.1%}')}" for k, v in row.items() if k.startswith("term_"))
    lines.append(f"terminations: {terms}; steps mean {fmt(row['steps_mean'], '{:.1f}')}, max {row['steps_max']}")
    return head + "\n".join(lines)


def _cmd_ssr(args) -> int:
    from . import evaluate
    from .passes import ssr_method
    sc, params_cls, params = _scene_and_params(args, ssr_method)
    _check_params(params_cls, params, args.method)
    try:
        ev = evaluate.run_ssr(sc, args.method, params, width=args.width, height=args.height, seed=args.seed,
                              repeats=args.repeats, spp=args.spp, k_px=args.k_px, debug=bool(args.out),
                              use_cache=not args.no_cache)
    except (RuntimeError, ImportError) as e:                 # e.g. no vectorised Mitsuba variant for the truth
        if os.environ.get("SSBENCH_DEBUG"):
            raise
        raise _UsageError(str(e), 1) from None
    row = ev.row
    print(json.dumps(row, indent=2, default=str) if args.json else _ssr_table(row))
    if args.out:
        from .metrics import ssr as M
        from .report.ao_section import write_png
        from .report.ssr_section import ERR_RANGE, color_rgb, magma_rgb, visits_rgb
        res, truth = ev.result, ev.truth
        valid = truth.valid.bool()
        images = {"color.png": color_rgb(res.color, valid), "raw_color.png": color_rgb(res.raw_color, valid),
                  "truth.png": color_rgb(truth.radiance, valid),
                  "truth_classes.png": M.class_rgb(M.truth_classes(truth, ev.gbuffer)),
                  "classes.png": M.class_rgb(ev.classes, res.hit.bool()),
                  "error.png": magma_rgb(M.color_error_map(res.raw_color, truth.radiance), valid, ERR_RANGE)}
        visits = ev.debug.get("visits")
        if hasattr(visits, "dim") and visits.dim() == 4:
            images["visits.png"] = visits_rgb(visits[:1, :1])[0]
        for name, rgb in images.items():
            write_png(os.path.join(args.out, name), rgb)
        tmp = os.path.join(args.out, ".row.json.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(row, f, indent=2, default=str)
            f.write("\n")
        os.replace(tmp, os.path.join(args.out, "row.json"))
        if not args.json:
            print(f"wrote {len(images) + 1} files to {args.out}")
    return 0


def _series(values, spec: str = "{:.2%}") -> str:
    """``f1 v · f2 v · …``: every frame when few, else frames 1–3, every tenth and the last."""
    from .report.ao_section import fmt
    n = len(values)
    ks = range(n) if n <= 12 else sorted({0, 1, 2, n - 1, *range(9, n, 10)})
    return " · ".join(f"f{k + 1} {fmt(values[k], spec)}" for k in ks)


def _implicit_table(row: dict) -> str:
    from .report.ao_section import fmt
    pct = "{:.2%}"
    lines = [f"{row['scene']} · {row['method']} · {row['width']}x{row['height']} · {row['frames']} frames · "
             f"seed {row['seed']}", f"params: {', '.join(f'{k}={v}' for k, v in row['params'].items())}",
             f"time/frame {fmt(row['seconds_per_frame'], '{:.4f}')} s (median, {row['threads']} threads); truth "
             f"{row['truth_traced']} trace(s) {fmt(row['truth_seconds'], '{:.2f}')} s",
             f"punch-through: {_series(row['punch_through_per_frame'])}"]
    if row["predicted_punch_through"]:
        lines += [f"predicted (h = {row['prediction_h']}): {_series(row['predicted_punch_through'])}",
                  f"< 1% at frame {fmt(row['frames_to_1pct'], '{}')} (predicted "
                  f"{fmt(row['predicted_frames_to_1pct'], '{}')})"]
    if row["invalidated_per_frame"] is not None:
        inv = row["invalidated_per_frame"]
        lines.append(f"invalidated: {sum(inv)} pixels in {sum(v > 0 for v in inv)} frames; {_series(inv, '{}')}")
    classes = ("correct", "punch_through", "early_hit", "false_hit", "true_miss", "unknown")
    lines += ["final frame, share of pixels: " + ", ".join(f"{c} {fmt(row[f'frac_{c}'], pct)}" for c in classes),
              f"punch-through {fmt(row['punch_through_rate'], pct)} / early hit {fmt(row['early_hit_rate'], pct)} "
              f"of truth hits; false hit {fmt(row['false_hit_rate'], pct)} of truth misses",
              f"depth error (correct px): mean {fmt(row['depth_mae'], '{:.2e}')}, "
              f"max {fmt(row['depth_max'], '{:.2e}')}",
              f"evaluations/px: mean {fmt(row['evaluations_mean'], '{:.1f}')}, "
              f"p95 {fmt(row['evaluations_p95'], '{:.0f}')}, max {fmt(row['evaluations_max'], '{:.0f}')}; "
              f"steps mean {fmt(row['steps_mean'], '{:.1f}')}",
              f"λ: declared {fmt(row['lambda_declared'], '{:g}')}, observed max |∇f| "
              f"{fmt(row['lambda_observed'], '{:.4g}')}" + (" — OVERSHOOT" if row["lambda_overshoot"] else ""),
              f"truth: hits {fmt(row['truth_hit_share'], pct)}, certified {fmt(row['truth_certified'], pct)}, "
              f"ambiguous px {row['truth_ambiguous_pixels']}, unfinished px {row['truth_unfinished_pixels']}"]
    return "\n".join(lines)


def _cmd_implicit(args) -> int:
    import numpy as np
    import torch

    from . import evaluate
    from .implicit.scene import load
    from .passes import implicit_method
    try:
        sc = load(args.scene)
    except (KeyError, ValueError, OSError) as e:
        raise _UsageError(f"argument SCENE: {e.args[0] if isinstance(e, KeyError) and e.args else e}") from None
    _, params_cls = implicit_method(args.method)
    params = coerce_params(params_cls, args.param, args.method)
    if args.steps is not None:
        name = evaluate.steps_param(args.method)
        if name in params:
            raise _UsageError(f"argument --steps: conflicts with --param {name}={params[name]}; give one of them")
        params[name] = args.steps
    _check_params(params_cls, params, args.method)
    if args.gif and not args.out:
        raise _UsageError("argument --gif: needs --out DIR")
    from .report import implicit_section as S
    frames = []

    def on_frame(k, res, cam, cls):
        rgb = S.color_image(res, cam, sc)
        bar = np.zeros((2,) + rgb.shape[1:], np.uint8)        # frame counter strip: every GIF frame differs
        bar[:, : max(1, round((k + 1) * rgb.shape[1] / args.frames))] = 255
        frames.append(np.concatenate([rgb, bar]))

    w, h = args.size or (None, None)
    ev = evaluate.run_implicit(sc, args.method, params, frames=args.frames, width=w, height=h, seed=args.seed,
                               truth_frames=args.truth, use_cache=not args.no_cache,
                               on_frame=on_frame if args.gif else None)
    row = ev.row
    print(json.dumps(row, indent=2, default=str) if args.json else _implicit_table(row))
    if args.out:
        from .report.ao_section import write_png
        res, hit = ev.result, ev.result.hit
        t = torch.where(hit, res.t, torch.nan)
        finite = t[torch.isfinite(t)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.numel() else (0.0, 1.0)
        images = {"color.png": S.color_image(res, ev.cameras[ev.last], sc),
                  "t.png": np.where(hit[0, 0, ..., None].numpy(), S.heat_rgb((t - lo).nan_to_num(0), max(hi - lo,
                                                                             1e-9), "viridis_r"), 0).astype(np.uint8),
                  "evaluations.png": S.heat_rgb(res.evaluations, float(res.evaluations.max()))}
        if ev.last in ev.classes:
            images["classes.png"] = S.class_rgb(ev.classes[ev.last])
        for name, rgb in images.items():
            write_png(os.path.join(args.out, name), rgb)
        written = len(images) + 1
        if args.gif:
            from PIL import Image                                # Pillow (a matplotlib dependency)
            imgs = [Image.fromarray(f) for f in frames]
            imgs[0].save(os.path.join(args.out, "frames.gif"), save_all=True, append_images=imgs[1:],
                         duration=round(1000 / args.fps), loop=0)
            written += 1
        tmp = os.path.join(args.out, ".row.json.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(row, f, indent=2, default=str)
            f.write("\n")
        os.replace(tmp, os.path.join(args.out, "row.json"))
        if not args.json:
            print(f"wrote {written} files to {args.out}")
    return 0


def _cmd_report(args) -> int:
    if args.compare:
        from .report.compare import cmd_compare
        return cmd_compare(args, args.report_parser)
    from .report.build import build_report
    off = lambda flag: False if flag else None                # noqa: E731  (None: the section's default)
    index = build_report(args.out, scenes=args.scenes, width=args.width, height=args.height, spp=args.spp,
                         seed=args.seed, use_cache=args.cache, ao=not args.no_ao, ao_radius=args.ao_radius,
                         ao_rays=args.ao_rays, ssr=not args.no_ssr, ssr_spp=args.ssr_spp,
                         implicit=off(args.no_implicit), speed=off(args.no_speed), tuning=off(args.no_tuning))
    print(f"report: {index}")
    print(f"latest: {os.path.join(os.path.abspath(args.out), 'latest', 'index.html')}")
    return 0


_COMMANDS = {"info": _cmd_info, "scenes": _cmd_scenes, "render": _cmd_render, "ao": _cmd_ao,
             "ssr": _cmd_ssr, "implicit": _cmd_implicit, "report": _cmd_report}


def _cmd_sweep(args) -> int:
    from .bench.cli import cmd_sweep
    return cmd_sweep(args)


_COMMANDS["sweep"] = _cmd_sweep


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
