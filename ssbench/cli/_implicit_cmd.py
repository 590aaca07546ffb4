"""``ssbench implicit``: an implicit-surface ray caster over frames, scored against the certified hit."""
from __future__ import annotations

import json
import os

from ._args import UsageError, coerce_params, guard_work, out_dir, write_row_json
from ._effect_cmds import check_params


def _series(values, spec: str = "{:.2%}") -> str:
    """``f1 v · f2 v · …``: every frame when few, else frames 1–3, every tenth and the last."""
    from ..report.ao_section import fmt
    n = len(values)
    ks = range(n) if n <= 12 else sorted({0, 1, 2, n - 1, *range(9, n, 10)})
    return " · ".join(f"f{k + 1} {fmt(values[k], spec)}" for k in ks)


def _implicit_table(row: dict) -> str:
    from ..report.ao_section import fmt
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


def cmd_implicit(args) -> int:
    import numpy as np
    import torch

    from .. import evaluate
    from ..implicit.scene import load
    from ..passes import implicit_method
    try:
        sc = load(args.scene)
    except (KeyError, ValueError, OSError) as e:
        raise UsageError(f"argument SCENE: {e.args[0] if isinstance(e, KeyError) and e.args else e}") from None
    _, params_cls = implicit_method(args.method)
    params = coerce_params(params_cls, args.param, args.method)
    if args.steps is not None:
        name = evaluate.steps_param(args.method)
        if name in params:
            raise UsageError(f"argument --steps: conflicts with --param {name}={params[name]}; give one of them")
        params[name] = args.steps
    check_params(params_cls, params, args.method)
    if args.gif and not args.out:
        raise UsageError("argument --gif: needs --out DIR")
    w0, h0 = args.size or (sc.camera.width, sc.camera.height)
    guard_work(force=args.force, width=w0, height=h0, frames=args.frames, size_args="--size")
    if args.out:
        out_dir(args.out)
    from ..report import implicit_section as S
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
        from ..report.ao_section import write_png
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
        write_row_json(args.out, row)
        if not args.json:
            print(f"wrote {written} files to {args.out}")
    return 0
