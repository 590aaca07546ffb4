"""``ssbench tune METHOD``: the command-line face of :func:`ssbench.tune.tune`.

The main ``ssbench`` parser adds it with :func:`add_tune_parser` and dispatches to :func:`cmd_tune` (its
``handler`` default); ``python -m ssbench.cli._tune_cmd tune METHOD ...`` runs it alone (:func:`main`). Prints a
table of default vs tuned RMSE per training and held-out scene, the tuned parameters and the time per frame;
``--out DIR`` also writes ``DIR/tune.json`` (strict JSON: NaN and infinities become null).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from typing import Optional, Sequence

from ..tune.space import BLUR_SPACES, SPACES
from ..tune.tuner import WEIGHTINGS

__all__ = ["add_tune_parser", "cmd_tune", "format_result", "main"]


def _number(kind, lo: float, what: str):
    def parse(s: str):
        try:
            v = kind(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {s!r}") from None
        if not (math.isfinite(v) and v >= lo) or (lo == 0 and kind is float and v == 0):
            raise argparse.ArgumentTypeError(f"expected {what}, got {s!r}")
        return v
    parse.__name__ = what
    return parse


def _scenes(s: str) -> list[str]:
    """Comma-separated catalog names or scene files; ``""`` or ``none``: no scenes."""
    from ..scenes import catalog
    if s.strip().lower() in ("", "none"):
        return []
    names = list(dict.fromkeys(n.strip() for n in s.split(",") if n.strip()))
    bad = [n for n in names if n not in catalog.CATALOG and not os.path.isfile(n)]
    if bad:
        raise argparse.ArgumentTypeError(f"unknown scene(s) {', '.join(bad)}; built-in scenes: "
                                         f"{', '.join(catalog.names())} (or a scene file)")
    return names


def _tune_list(s: str) -> list[tuple[str, Optional[tuple[float, float]]]]:
    """``NAME[=LO:HI],...``: parameters to tune, optionally with their range."""
    out = []
    for item in (x.strip() for x in s.split(",") if x.strip()):
        name, sep, rng = item.partition("=")
        bounds = None
        if sep:
            lo, colon, hi = rng.partition(":")
            try:
                bounds = (float(lo), float(hi))
            except ValueError:
                bounds = None
            if not colon or bounds is None or not all(map(math.isfinite, bounds)) or not bounds[0] < bounds[1]:
                raise argparse.ArgumentTypeError(f"expected NAME or NAME=LO:HI with LO < HI, got {item!r}")
        out.append((name.strip(), bounds))
    if not out:
        raise argparse.ArgumentTypeError("expected at least one parameter name")
    return out


def _param(s: str) -> tuple[str, object]:
    from . import parse_value
    name, sep, value = s.partition("=")
    if not sep or not name.strip().isidentifier() or not value.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE (e.g. quality=high), got {s!r}")
    return name.strip(), parse_value(value)


def add_tune_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``tune`` sub-command to ``subparsers``; returns it (``handler`` default: :func:`cmd_tune`)."""
    q = subparsers.add_parser(
        "tune", help="tune an AO method's continuous parameters against ray-traced AO; report held-out scenes",
        description="Grid narrowing, then Adam steps on the parameters the torch pass is differentiable in, "
                    "minimising the mean RMSE against a fixed ray-traced AO on the training scenes; default vs "
                    "tuned RMSE on training and held-out scenes.")
    q.add_argument("method", metavar="METHOD", choices=list(SPACES), help=f"AO method: {', '.join(SPACES)}")
    q.add_argument("--scenes", type=_scenes, default=["crease", "sphere_on_plane"],
                   help="training scenes, comma-separated (default crease,sphere_on_plane)")
    q.add_argument("--held-out", type=_scenes, default=["cornell_box", "stairs"], dest="held_out",
                   help="held-out scenes (default cornell_box,stairs; 'none' for none)")
    q.add_argument("--budget-ms", type=_number(float, 0, "a number > 0"), dest="budget_ms",
                   help="reject configurations slower than this per frame (timed at --width x --height)")
    q.add_argument("--tune", type=_tune_list, dest="tune",
                   help="parameters to tune, NAME[=LO:HI],... (default: all continuous ones not in --param)")
    q.add_argument("--blur", choices=list(BLUR_SPACES), default=None,
                   help="score the AO after this blur (as 'ssbench ao --blur') and tune its continuous parameters "
                        "too (blur_*: cross_bilateral blur_falloff, blur_threshold; joint_bilateral "
                        "blur_sigma_color, blur_sigma_space; box none)")
    q.add_argument("--param", type=_param, action="append", default=[], metavar="NAME=VALUE",
                   help="hold a pass parameter fixed (repeatable), e.g. --param quality=high")
    q.add_argument("--width", type=_number(int, 1, "a positive integer"), default=160)
    q.add_argument("--height", type=_number(int, 1, "a positive integer"), default=120)
    q.add_argument("--gt-radius", type=_number(float, 0, "a number > 0"), default=0.5, dest="gt_radius",
                   help="ground-truth AO radius, fixed (default 0.5); the default config uses it as its radius")
    q.add_argument("--rays", type=_number(int, 2, "an integer >= 2"), default=256, help="GT rays per pixel")
    q.add_argument("--weighting", choices=WEIGHTINGS, default="cosine",
                   help="GT flavour (default cosine; 'flavour': the one the pass approximates)")
    q.add_argument("--points", type=_number(int, 2, "an integer >= 2"), default=5, help="grid nodes per axis")
    q.add_argument("--rounds", type=_number(int, 1, "a positive integer"), default=3, help="grid rounds")
    q.add_argument("--steps", type=_number(int, 0, "an integer >= 0"), default=10,
                   help="Adam steps on the differentiable parameters (0: none)")
    q.add_argument("--lr", type=_number(float, 0, "a number > 0"), default=0.05,
                   help="Adam learning rate, as a fraction of each parameter's range")
    q.add_argument("--seed", type=_number(int, 0, "a non-negative integer"), default=0)
    q.add_argument("--threads", type=_number(int, 1, "a positive integer"), default=1, help="torch threads")
    q.add_argument("--out", metavar="DIR", help="also write DIR/tune.json")
    q.add_argument("--json", action="store_true", help="print the result as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the reference cache")
    q.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    q.set_defaults(handler=cmd_tune)
    return q


def _clean(x):
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


def _f(v, spec="{:.4f}") -> str:
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else spec.format(v)


def format_result(res) -> str:
    """The text table :func:`cmd_tune` prints for a :class:`~ssbench.tune.TuneResult`."""
    s, m, sr = res.settings, res.summary, res.search
    blur = f" + {s['blur']} blur" if s.get("blur") else ""
    lines = [f"{res.method}{blur}: tuned on {', '.join(s['train'])} at {s['width']}x{s['height']} against {s['weighting']} "
             f"GT (radius {s['gt_radius']:g}, {s['rays']} rays); held out: {', '.join(s['held_out']) or 'none'}",
             "", f"{'parameter':<20}{'default':>10}{'tuned':>10}   {'range':<18}differentiable"]
    for p in res.params:
        d = f"yes (dRMSE/dx {p['grad']:+.3g})" if p["differentiable"] else f"no: {p['why']}"
        tuned = f"{p['tuned']:.4g}" + ("*" if p["at_bound"] else "")
        lines.append(f"{p['name']:<20}{p['default']:>10.4g}{tuned:>10}   "
                     f"{'[' + format(p['lo'], '.4g') + ', ' + format(p['hi'], '.4g') + ']':<18}{d}")
    if any(p["at_bound"] for p in res.params):
        lines.append("* on the edge of its range: a wider range (--tune NAME=LO:HI) might do better")
    lines += ["", f"{'scene':<24}{'split':<10}{'default RMSE':>13}{'tuned RMSE':>12}{'change':>9}"]
    for r in res.rows:
        lines.append(f"{r['scene']:<24}{r['split']:<10}{_f(r['default']):>13}{_f(r['tuned']):>12}"
                     f"{_f(r['change'], '{:+.1%}'):>9}")
    lines.append(f"{'mean':<24}{'train':<10}{_f(m['train_default']):>13}{_f(m['train_tuned']):>12}")
    if s["held_out"]:
        lines.append(f"{'mean':<24}{'held_out':<10}{_f(m['held_default']):>13}{_f(m['held_tuned']):>12}")
        lines.append(f"held-out: tuning {'beats' if m['held_improved'] else 'does NOT beat'} the defaults")
    if m["note"]:
        lines.append(f"note: {m['note']}")
    budget = f"budget {s['budget_ms']:g} ms, {sr['rejected_over_budget']} rejected" if s["budget_ms"] else "no budget"
    lines.append(f"time per frame ({s['threads']} thread(s)): default {_f(m['time_ms_default'], '{:.1f}')} ms, "
                 f"tuned {_f(m['time_ms_tuned'], '{:.1f}')} ms ({budget}); {sr['evaluations']} evaluations, "
                 f"tuned point from the {m['source']} stage, {m['seconds']:.1f} s")
    return "\n".join(lines)


def cmd_tune(args) -> int:
    """Handle ``ssbench tune``: 0 on success (errors raise ``ValueError`` naming the argument)."""
    import torch
    from ..tune.space import coerce_fixed, tunable_names
    from ..tune.tuner import tune
    blur = getattr(args, "blur", None)
    valid = tunable_names(args.method, blur)
    names, bounds = None, None
    if args.tune:
        bad = [n for n, _ in args.tune if n not in valid]
        if bad:
            raise ValueError(f"argument --tune: {', '.join(map(repr, bad))} not tunable for {args.method}"
                             f"{' with --blur ' + blur if blur else ''}; "
                             f"tunable: {', '.join(valid)}")
        names = [n for n, _ in args.tune]
        bounds = {n: b for n, b in args.tune if b is not None}
    fixed = dict(args.param)
    if len(fixed) != len(args.param):
        raise ValueError("argument --param: a parameter is given twice")
    try:
        fixed = coerce_fixed(args.method, fixed)
    except ValueError as e:
        raise ValueError(f"argument --param: {e}") from None
    if not args.scenes:
        raise ValueError("argument --scenes: need at least one training scene")
    before = torch.get_num_threads()
    torch.set_num_threads(args.threads)
    say = None if args.quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    try:
        res = tune(args.method, args.scenes, args.held_out, width=args.width, height=args.height,
                   gt_radius=args.gt_radius, rays=args.rays, weighting=args.weighting, seed=args.seed, fixed=fixed,
                   names=names, bounds=bounds, points=args.points, rounds=args.rounds, steps=args.steps, lr=args.lr,
                   budget_ms=args.budget_ms, use_cache=not args.no_cache, blur=blur, progress=say)
    finally:
        torch.set_num_threads(before)
    data = _clean(res.as_dict())
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        tmp = os.path.join(args.out, ".tune.json.tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=2, allow_nan=False)
            f.write("\n")
        os.replace(tmp, os.path.join(args.out, "tune.json"))
    print(json.dumps(data, indent=2, allow_nan=False) if args.json else format_result(res))
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``python -m ssbench.cli._tune_cmd tune METHOD ...``: the ``ssbench`` command line (:func:`ssbench.cli.main`);
    returns the exit status (1 for a bad argument value)."""
    from . import main as ssbench_main
    return ssbench_main(argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
