"""``ssbench frames``: one method over frames, raw and temporally accumulated — flicker, ghosting, TXAA.

``ssbench frames ao SCENE --method gtao --orbit 1.5 --truth-rays 32`` runs :func:`ssbench.evaluate.ao_frames`;
``ssr`` runs :func:`~ssbench.evaluate.ssr_frames`; ``implicit`` runs :func:`~ssbench.evaluate.implicit_frames`
(TXAA against the supersampled reference). ``--move SHAPE:VX,VY,VZ`` moves one object per frame
(:class:`ssbench.scenes.motion.Motion`), ``--no-motion-vectors`` reprojects it by the camera alone.
"""
from __future__ import annotations

import argparse
import json
import math

from ._args import UsageError, coerce_params, guard_work, param_arg, parse_value

EFFECTS = ("ao", "ssr", "implicit")
#: the numbers each effect prints, in order
_SCREEN = ("flicker", "flicker_accumulated", "ghosting", "ghosting_edges", "ghosting_moving")
KEYS = {"ao": _SCREEN, "ssr": _SCREEN, "implicit": ("error_raw", "error_accumulated", "flicker", "flicker_accumulated")}


def move_arg(s: str):
    """``SHAPE:VX,VY,VZ`` → :class:`~ssbench.scenes.motion.Motion`."""
    from ..scenes.motion import Motion
    shape, sep, rest = s.partition(":")
    parts = rest.split(",")
    try:
        v = tuple(float(parse_value(p)) for p in parts)
        if not sep or len(v) != 3:
            raise ValueError
        return Motion(shape.strip(), v)
    except (ValueError, TypeError):
        raise argparse.ArgumentTypeError(f"expected SHAPE:VX,VY,VZ (e.g. ball:0.15,0,0), got {s!r}") from None


def add_parser(sub) -> None:
    from ..passes.temporal import CLAMPS
    from ._args import non_negative, positive, positive_float
    q = sub.add_parser("frames", help="one method over frames, raw and temporally accumulated: flicker, "
                                      "ghosting, TXAA")
    q.add_argument("effect", choices=EFFECTS, help="ao, ssr or implicit (TXAA against the supersampled truth)")
    q.add_argument("scene", metavar="SCENE", help="catalog name or scene file (implicit: an implicit scene)")
    q.add_argument("--method", required=True, help="a method of the effect")
    q.add_argument("--param", type=param_arg, action="append", default=[], metavar="NAME=VALUE",
                   help="override a pass parameter (repeatable)")
    q.add_argument("--frames", type=positive("frames"), default=8, help="frames (>= 2, default 8)")
    q.add_argument("--width", type=positive("width"), default=128)
    q.add_argument("--height", type=positive("height"), default=96)
    q.add_argument("--seed", type=non_negative, default=0)
    q.add_argument("--orbit", type=float, default=0.0, metavar="DEG", help="camera turn per frame (ao, ssr)")
    q.add_argument("--move", type=move_arg, metavar="SHAPE:VX,VY,VZ", help="move one object per frame (ao, ssr)")
    q.add_argument("--no-motion-vectors", action="store_true", help="reproject the moving object by the camera alone")
    q.add_argument("--no-jitter", action="store_true", help="no sub-pixel jitter (ao, ssr)")
    q.add_argument("--truth-rays", type=non_negative, default=0,
                   help="rays per pixel of each frame's truth, for ghosting (ao, ssr; 0: none)")
    q.add_argument("--alpha", type=positive_float, default=0.1, help="the resolve's blend weight (0.1)")
    q.add_argument("--clamp", choices=CLAMPS, default="minmax", help="neighbourhood clamp (minmax)")
    q.add_argument("--depth-tolerance", type=positive_float, default=None,
                   help="relative depth mismatch that rejects history (0.02; implicit: inf, the TXAA resolve)")
    q.add_argument("--json", action="store_true", help="print the numbers as JSON")
    q.add_argument("--no-cache", action="store_true", help="do not read or write the render cache")
    q.add_argument("--force", action="store_true", help="run work above the size limits (ssbench/RELIABILITY.md)")


def _accumulation(args):
    from ..passes.temporal import AccumulationParams
    tol = args.depth_tolerance
    if args.effect == "implicit":
        return AccumulationParams(args.alpha, args.clamp, math.inf if tol is None else tol, background=True)
    return AccumulationParams(args.alpha, args.clamp, 0.02 if tol is None else tol)


def cmd_frames(args) -> int:
    from .. import evaluate
    from ..passes import ao_method, implicit_method, ssr_method
    resolve = {"ao": ao_method, "ssr": ssr_method, "implicit": implicit_method}[args.effect]
    try:
        params_cls = resolve(args.method)[1]
    except KeyError as e:
        raise UsageError(f"argument --method: {e.args[0] if e.args else e}") from None
    params = coerce_params(params_cls, args.param, args.method)
    from ._effect_cmds import check_params
    check_params(params_cls, params, args.method)
    if args.frames < 2:
        raise UsageError("argument --frames: expected an integer >= 2")
    if args.truth_rays == 1:
        raise UsageError("argument --truth-rays: expected 0 or an integer >= 2")
    if args.effect == "implicit" and (args.move or args.orbit or args.truth_rays):
        raise UsageError("argument --move/--orbit/--truth-rays: the implicit TXAA run is a still camera scored "
                         "against the supersampled reference")
    if args.move is not None:
        from ..scenes import load
        try:
            args.move.index(load(args.scene))
        except ValueError as e:
            raise UsageError(f"argument --move: {e}") from None
    guard_work(force=args.force, width=args.width, height=args.height, rays=max(1, args.truth_rays),
               frames=args.frames)
    acc = _accumulation(args)
    common = dict(frames=args.frames, width=args.width, height=args.height, seed=args.seed,
                  use_cache=not args.no_cache)
    if args.effect == "implicit":
        run = evaluate.implicit_frames(args.scene, args.method, params or None, accumulation=acc, **common)
        row = {"error_raw": run.raw_error(), "error_accumulated": run.late_error(),
               "flicker": run.flicker, "flicker_accumulated": run.flicker_accumulated}
    else:
        fn = evaluate.ao_frames if args.effect == "ao" else evaluate.ssr_frames
        run = fn(args.scene, args.method, params or None, jitter=not args.no_jitter, orbit_deg=args.orbit,
                 accumulation=acc, truth_rays=args.truth_rays, moving=args.move,
                 motion_vectors=not args.no_motion_vectors, **common)
        row = {k: getattr(run, k) for k in KEYS[args.effect]}
    row = {"effect": args.effect, "scene": str(args.scene), "method": args.method, "frames": args.frames,
           "width": args.width, "height": args.height, "alpha": acc.alpha, "clamp": acc.clamp,
           "depth_tolerance": acc.depth_tolerance, "orbit_deg": args.orbit,
           "moving": None if args.move is None else {"shape": args.move.shape, "velocity": list(args.move.velocity)},
           "motion_vectors": not args.no_motion_vectors, **{k: float(v) for k, v in row.items()}}
    if args.json:
        print(json.dumps({k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}))
    else:
        print(f"{row['scene']} · {row['effect']} {row['method']} · {row['width']}x{row['height']} · "
              f"{row['frames']} frames · resolve alpha {acc.alpha}, clamp {acc.clamp}, depth tolerance "
              f"{acc.depth_tolerance:g}")
        for k in KEYS[args.effect]:
            print(f"{k:<22}{row[k]:>10.4f}")
    return 0
