"""``ssbench ao`` and ``ssbench ssr``: one pass on one scene, scored against the ground truth."""
from __future__ import annotations

import json
import os
import sys

from ._args import UsageError, coerce_params, guard_work, out_dir, write_row_json
from ._scene_cmds import load_scene


def _ao_table(row: dict) -> str:
    from ..evaluate import TARGET_METRICS
    from ..report.ao_section import fmt
    blur = f" · blur {row['blur']} ({fmt(row['blur_seconds'], '{:.4f}')} s)" if row["blur"] else ""
    head = (f"{row['scene']} · {row['method']} · {row['width']}x{row['height']} · radius {row['radius']} "
            f"({row['radius_param']}) · flavour {row['weighting']} · {row['rays']} GT rays · seed {row['seed']}\n"
            f"params: {', '.join(f'{k}={v}' for k, v in row['params'].items())}{blur}\n"
            f"time {fmt(row['seconds'], '{:.4f}')} s (median of {row['repeats']}, {row['threads']} threads)\n")
    cols = ("cos", "flavour", "oracle")
    lines = [f"{'metric':<16}" + "".join(f"{c:>12}" for c in cols)]
    for m in TARGET_METRICS:
        lines.append(f"{m:<16}" + "".join(f"{fmt(row[f'{m}_{c}']):>12}" for c in cols))
    extra = [("banding", "{:.4f}"), ("tile_energy", "{:.4f}"), ("noise", "{:.3e}"), ("info_loss_rmse", "{:.4f}"), ("estimator_rmse", "{:.4f}"),
             ("gt_stderr_cos", "{:.4f}")]
    if row["blur"]:
        extra += [("banding_raw", "{:.4f}"), ("tile_energy_raw", "{:.4f}"), ("noise_raw", "{:.3e}")]
    lines += [f"{k:<16}{fmt(row[k], spec):>12}" for k, spec in extra]
    if not row["oracle"] and row.get("oracle_error"):
        lines.append(f"oracle unavailable: {row['oracle_error']}")
    return head + "\n".join(lines)


def _scene_and_params(args, resolve):
    """Scene, parameter class and ``--param`` overrides of an ``ao``/``ssr`` command."""
    sc = load_scene(args.scene, args.defines)
    try:
        _, params_cls, _ = resolve(args.method)
    except (ImportError, AttributeError) as e:
        raise UsageError(f"argument --method: {args.method} is not importable ({type(e).__name__}: {e})", 1)
    return sc, params_cls, coerce_params(params_cls, args.param, args.method)


def check_params(params_cls, params, method) -> None:
    """The parameter dataclass's own checks, up front, as a usage error."""
    from .. import evaluate
    try:
        evaluate.resolve_params(params_cls, params, method)
    except (ValueError, TypeError) as e:
        raise UsageError(f"argument --param: {e}") from None


def cmd_ao(args) -> int:
    from .. import evaluate
    from ..passes import ao_method
    sc, params_cls, params = _scene_and_params(args, ao_method)
    rname = evaluate.radius_param(params_cls, sys.modules.get(params_cls.__module__))
    if args.radius is not None and rname in params:
        raise UsageError(f"argument --radius: conflicts with --param {rname}={params[rname]}; give one of them")
    check_params(params_cls, params, args.method)
    guard_work(force=args.force, width=args.width, height=args.height, rays=args.rays)
    if args.out:
        out_dir(args.out)
    try:
        ev = evaluate.run_ao(sc, args.method, params, width=args.width, height=args.height, radius=args.radius,
                             rays=args.rays, weighting=args.weighting, seed=args.seed, repeats=args.repeats,
                             blur=args.blur, use_cache=not args.no_cache)
    except RuntimeError as e:                                # e.g. no vectorised Mitsuba variant for the GT
        if os.environ.get("SSBENCH_DEBUG"):
            raise
        raise UsageError(str(e), 1) from None
    row = ev.row
    print(json.dumps(row, indent=2, default=str) if args.json else _ao_table(row))
    if args.out:
        from ..report.ao_section import ao_rgb, error_rgb, write_png
        mask = ev.gbuffer.mask
        write_png(os.path.join(args.out, "ao.png"), ao_rgb(ev.ao, mask))
        for t, r in ev.references.items():
            write_png(os.path.join(args.out, f"gt_{t}.png"), ao_rgb(r.ao, mask))
            write_png(os.path.join(args.out, f"error_{t}.png"), error_rgb(ev.ao - r.ao, mask))
        write_row_json(args.out, row)
        if not args.json:
            print(f"wrote {2 * len(ev.references) + 2} files to {args.out}")
    return 0


def _ssr_table(row: dict) -> str:
    from ..metrics.ssr import CLASS_NAMES
    from ..report.ao_section import fmt
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


def cmd_ssr(args) -> int:
    from .. import evaluate
    from ..passes import ssr_method
    sc, params_cls, params = _scene_and_params(args, ssr_method)
    check_params(params_cls, params, args.method)
    guard_work(force=args.force, width=args.width, height=args.height, rays=args.spp, rays_arg="--spp")
    if args.out:
        out_dir(args.out)
    try:
        ev = evaluate.run_ssr(sc, args.method, params, width=args.width, height=args.height, seed=args.seed,
                              repeats=args.repeats, spp=args.spp, k_px=args.k_px, debug=bool(args.out),
                              use_cache=not args.no_cache)
    except (RuntimeError, ImportError) as e:                 # e.g. no vectorised Mitsuba variant for the truth
        if os.environ.get("SSBENCH_DEBUG"):
            raise
        raise UsageError(str(e), 1) from None
    row = ev.row
    print(json.dumps(row, indent=2, default=str) if args.json else _ssr_table(row))
    if args.out:
        from ..metrics import ssr as M
        from ..report.ao_section import write_png
        from ..report.ssr_images import color_rgb, magma_rgb, visits_rgb
        from ..report.ssr_section import ERR_RANGE
        res, truth = ev.result, ev.truth
        valid = truth.valid.bool()
        images = {"color.png": color_rgb(res.color, valid), "raw_color.png": color_rgb(res.raw_color, valid),
                  "truth.png": color_rgb(truth.radiance, valid),
                  "truth_classes.png": M.class_rgb(M.truth_classes(truth, ev.gbuffer)),
                  "classes.png": M.class_rgb(ev.classes),
                  "error.png": magma_rgb(M.color_error_map(res.raw_color, truth.radiance), valid, ERR_RANGE)}
        visits = ev.debug.get("visits")
        if hasattr(visits, "dim") and visits.dim() == 4:
            images["visits.png"] = visits_rgb(visits[:1, :1])[0]
        for name, rgb in images.items():
            write_png(os.path.join(args.out, name), rgb)
        write_row_json(args.out, row)
        if not args.json:
            print(f"wrote {len(images) + 1} files to {args.out}")
    return 0
