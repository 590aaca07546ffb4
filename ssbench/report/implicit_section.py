"""The report's implicit-surface section (progressive-tracing article): the progressive method against fixed-step at the same N.

Every number comes from rows of :func:`ssbench.evaluate.run_implicit` (or its λ columns,
:func:`ssbench.evaluate.lipschitz_diagnostic`). At a small size (default 96×72) it writes under
``img/implicit/``:

* per scene of :data:`COMPARE_SCENES`: ``<scene>/punch_through.png`` — punch-through rate vs frame of the
  progressive method and of fixed-step at the same ``N``, with the h/w predictions (the article's comparison,
  結果); ``<method>.png`` / ``<method>_classes.png`` — the final frames side by side (fixed-step still see-through);
* ``evaluations.png`` — f evaluations per pixel of fixed-step, sphere tracing and the progressive method (final
  frame, one colour scale); ``sphere_steps.png`` — sphere-tracing steps on three scenes;
* ``double_root/`` — the pixels where interval arithmetic saw an ambiguous root that no sign change reveals;
* ``animated/invalidations.png`` — the (1+ε)t' probe's invalidations per frame (object, then camera motion);

plus the table of declared λ against the observed max |∇f| of every catalog scene (overshoot flagged). Nothing
here may crash the report: each part that fails becomes a note.
"""
from __future__ import annotations

import os
import time
import traceback
from typing import Optional

import numpy as np
import torch

from ..pictures import implicit_class_rgb as class_rgb, implicit_color_rgb as color_image
from .ao_section import fmt, write_png
from .summary import unavailable_md

#: scenes of the progressive-vs-fixed comparison
COMPARE_SCENES = ("thin_shell", "thin_plate")
#: scenes of the sphere-tracing step maps (valid λ, valid λ with grazing rays, wrong λ)
STEP_SCENES = ("thin_shell", "torus", "displaced_torus")
PCT = "{:.2%}"


def _hw(x: torch.Tensor) -> np.ndarray:
    return x.detach().double().cpu().reshape(x.shape[-2], x.shape[-1]).numpy()


def heat_rgb(x: torch.Tensor, vmax: float, cmap: str = "magma") -> np.ndarray:
    """``(H, W, 3)`` uint8 ``x / vmax`` on ``cmap``."""
    import matplotlib
    v = np.clip(np.nan_to_num(_hw(x)) / max(vmax, 1e-12), 0, 1)
    return (matplotlib.colormaps[cmap](v)[..., :3] * 255 + 0.5).astype(np.uint8)


def save_fig(fig, path: str) -> None:
    from ..io import save_figure
    save_figure(fig, path, dpi=100)


def class_legend() -> list[dict]:
    """``[{label, description, color}]`` of the implicit casters' class map colours (a legend beside the maps)."""
    from ..metrics.implicit import CLASS_COLORS, CLASS_DESCRIPTIONS, CLASS_NAMES
    return [{"label": CLASS_NAMES[c].replace("_", " "), "description": CLASS_DESCRIPTIONS[c],
             "color": "#%02x%02x%02x" % tuple(int(255 * v + 0.5) for v in CLASS_COLORS[c])} for c in CLASS_NAMES]


def _plot_punch(path: str, prog: dict, fixed: dict) -> None:
    from matplotlib.figure import Figure
    fig = Figure(figsize=(5.6, 3.4))
    ax = fig.subplots()
    floor = 0.5 / max(1.0, prog["truth_hit_share"] * prog["width"] * prog["height"])
    x = np.arange(1, prog["frames"] + 1)
    clip = lambda v: np.maximum(np.array([np.nan if r is None else r for r in v], float), floor)   # noqa: E731
    ax.plot(x, clip(prog["punch_through_per_frame"]), "o-", ms=3, color="#1f77b4", label="progressive (measured)")
    if prog["predicted_punch_through"]:
        ax.plot(x, clip(prog["predicted_punch_through"]), "--", color="#1f77b4",
                label="progressive h/w prediction (survivor form)")
    ax.plot(x, clip(fixed["punch_through_per_frame"]), "s-", ms=3, color="#d62728", label="fixed step (measured)")
    if fixed["predicted_punch_through"]:
        ax.plot(x, clip(fixed["predicted_punch_through"]), ":", color="#d62728", label="fixed step h/w prediction")
    ax.axhline(0.01, color="grey", lw=0.8)
    ax.set_yscale("log")
    ax.set_ylim(floor * 0.8, 1.2)
    ax.set(xlabel="frame", ylabel="punch-through (share of truth hits)",
           title=f"{prog['scene']}: N = {prog['params']['steps']}, {prog['width']}×{prog['height']}")
    ax.legend(fontsize=7)
    fig.subplots_adjust(left=0.14, right=0.98, bottom=0.14, top=0.9)          # (tight_layout: a second draw)
    save_fig(fig, path)


def _plot_maps(path: str, maps: list, label: str, cmap: str = "magma") -> float:
    """Maps side by side on one colour scale (square-root norm, so the few grazing rays do not wash it out)."""
    from matplotlib.colors import PowerNorm
    from matplotlib.figure import Figure
    vmax = max(1.0, max(float(m.max()) for _, m in maps))
    fig = Figure(figsize=(2.6 * len(maps) + 1.0, 2.4), layout="constrained")
    axes = fig.subplots(1, len(maps), squeeze=False)[0]
    for ax, (title, m) in zip(axes, maps):
        im = ax.imshow(_hw(m), cmap=cmap, norm=PowerNorm(0.5, vmin=0, vmax=vmax), interpolation="nearest")
        ax.set_title(title, fontsize=9)
        ax.set_axis_off()
    fig.colorbar(im, ax=list(axes), label=label, shrink=0.9)
    save_fig(fig, path)
    return vmax


def _plot_invalidations(path: str, row: dict, segments) -> None:
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.4, 2.8))
    ax = fig.subplots()
    for s in segments:
        ax.axvspan(s.start + 0.5, s.stop + 0.5, color="#ffbb78" if s.object else "#aec7e8", alpha=0.6,
                   label=f"{s.object or 'camera'} moves")
    ax.bar(np.arange(row["frames"]), row["invalidated_per_frame"], color="#333333", width=0.8,
           label="invalidated pixels")
    ax.set(xlabel="frame", ylabel="pixels", title=f"{row['scene']}: (1+ε)t' probe invalidations per frame")
    ax.legend(fontsize=7)
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.17, top=0.88)
    save_fig(fig, path)


def _compare(d, rel, name, frames, steps, kw, ev_mod):
    prog = ev_mod.run_implicit(name, "progressive", {"steps": steps}, frames=frames, **kw)
    fixed = ev_mod.run_implicit(name, "fixed", {"steps": steps}, frames=frames, **kw)
    images = {"plot": f"{rel}/punch_through.png"}
    _plot_punch(os.path.join(d, "punch_through.png"), prog.row, fixed.row)
    for m, ev in (("fixed", fixed), ("progressive", prog)):
        write_png(os.path.join(d, f"{m}.png"), color_image(ev.result, ev.cameras[ev.last], ev.scene))
        write_png(os.path.join(d, f"{m}_classes.png"), class_rgb(ev.classes[ev.last]))
        images[m], images[f"{m}_classes"] = f"{rel}/{m}.png", f"{rel}/{m}_classes.png"
    cells = {}
    for m, r in (("progressive", prog.row), ("fixed", fixed.row)):
        pred = r["predicted_punch_through"] or [None]
        cells[m] = {"first": fmt(r["punch_through_per_frame"][0], PCT), "first_pred": fmt(pred[0], PCT),
                    "last": fmt(r["punch_through_per_frame"][-1], PCT), "last_pred": fmt(pred[-1], PCT),
                    "to1": fmt(r["frames_to_1pct"], "{}"), "to1_pred": fmt(r["predicted_frames_to_1pct"], "{}"),
                    "evals": fmt(r["evaluations_mean"], "{:.1f}"), "ms": fmt(r["seconds_per_frame"] * 1e3, "{:.1f}")}
    return ({"name": name, "description": prog.scene.description, "images": images, "cells": cells},
            [prog.row, fixed.row], (prog, fixed))


def _parts(run_dir, size, frames, steps, seed, use_cache, samples, out):
    from .. import evaluate as E
    from ..implicit import catalog
    from ..implicit.scene import load
    kw = dict(width=size[0], height=size[1], seed=seed, use_cache=use_cache, lipschitz_samples=samples,
              truth_cache={})                                    # one trace per scene, shared by the methods
    root = os.path.join(run_dir, "img", "implicit")
    notes, rows = out["notes"], out["rows"]

    def part(label, f):
        try:
            return f()
        except Exception as e:                                   # the report must not crash on one part
            notes.append(f"{label} skipped: {type(e).__name__}: {e}")
            if os.environ.get("SSBENCH_DEBUG"):
                traceback.print_exc()

    runs = {}
    for name in COMPARE_SCENES:
        got = part(f"scene {name}", lambda: _compare(os.path.join(root, name), f"img/implicit/{name}", name,
                                                     frames, steps, kw, E))
        if got:
            out["comparisons"].append(got[0])
            rows += got[1]
            runs[name] = got[2]

    def heat():
        prog, fixed = runs["thin_shell"]
        sph = E.run_implicit("thin_shell", "sphere", None, frames=1, **kw)
        rows.append(sph.row)
        maps = [(f"{r.row['method']} ({fmt(r.row['evaluations_mean'], '{:.1f}')}/px)", r.result.evaluations)
                for r in (fixed, sph, prog)]
        vmax = _plot_maps(os.path.join(root, "evaluations.png"), maps, "f evaluations per pixel")
        return {"image": "img/implicit/evaluations.png", "vmax": fmt(vmax, "{:.0f}"),
                "cells": [{"method": r.row["method"], "mean": fmt(r.row["evaluations_mean"], "{:.1f}"),
                           "p95": fmt(r.row["evaluations_p95"], "{:.0f}"),
                           "max": fmt(r.row["evaluations_max"], "{:.0f}"),
                           "punch": fmt(r.row["punch_through_rate"], PCT)} for r in (fixed, sph, prog)]}
    out["heatmaps"] = part("evaluation heatmaps", heat)

    def sphere_steps():
        evs = [E.run_implicit(n, "sphere", None, frames=1, truth_frames="none", **kw) for n in STEP_SCENES]
        rows.extend(ev.row for ev in evs)
        _plot_maps(os.path.join(root, "sphere_steps.png"), [(ev.row["scene"], ev.result.steps) for ev in evs],
                   "sphere-tracing steps", "viridis")
        return {"image": "img/implicit/sphere_steps.png",
                "cells": [{"scene": ev.row["scene"], "mean": fmt(ev.row["steps_mean"], "{:.1f}"),
                           "max": fmt(ev.row["steps_max"], "{:.0f}"), "oos": fmt(ev.row["term_out_of_steps"], PCT),
                           "overshoot": ev.row["overshoot_pixels"], "fallbacks": ev.row["fallbacks"]} for ev in evs]}
    out["sphere_steps"] = part("sphere-tracing steps", sphere_steps)

    for name in catalog.names():
        lam = part(f"λ check of {name}", lambda: E.lipschitz_diagnostic(load(name).surface(0), samples, seed))
        if lam:
            out["lipschitz"].append({"scene": name, "declared": fmt(lam["lambda_declared"], "{:g}"),
                                     "observed": fmt(lam["lambda_observed"], "{:.4g}"),
                                     "ratio": fmt(lam["lambda_ratio"], "{:.3f}"), "overshoot": lam["lambda_overshoot"]})

    def double_root():
        ev = E.run_implicit("double_root", "fixed", {"steps": steps}, frames=1, **kw)
        rows.append(ev.row)
        d, amb = os.path.join(root, "double_root"), ev.truth.ambiguous_t
        write_png(os.path.join(d, "ambiguous.png"), heat_rgb(torch.isfinite(amb).double(), 1.0, "viridis"))
        write_png(os.path.join(d, "fixed.png"), color_image(ev.result, ev.cameras[0], ev.scene))
        r = ev.row
        return {"images": {"ambiguous": "img/implicit/double_root/ambiguous.png",
                           "fixed": "img/implicit/double_root/fixed.png"},
                "ambiguous": r["truth_ambiguous_pixels"], "truth_hit": fmt(r["truth_hit_share"], PCT),
                "fixed_hit": fmt(r["hit_share_per_frame"][0], PCT), "certified": fmt(r["truth_certified"], PCT),
                "description": ev.scene.description}
    out["double_root"] = part("double_root", double_root)

    def animated():
        sc = load("animated")
        ev = E.run_implicit(sc, "progressive", {"steps": steps}, frames=sc.frames, truth_frames="none", **kw)
        rows.append(ev.row)
        segs = sc.animation.segments
        _plot_invalidations(os.path.join(root, "animated", "invalidations.png"), ev.row, segs)
        inv, spans, moved = ev.row["invalidated_per_frame"], [], set()
        for s in segs:
            fr = range(s.start + 1, min(s.stop, ev.row["frames"] - 1) + 1)
            moved |= set(fr)
            first = next((k for k in fr if inv[k] > 0), None)
            spans.append({"what": f"{s.object or 'camera'} moves", "frames": f"{fr.start}–{fr.stop - 1}",
                          "total": sum(inv[k] for k in fr), "first": fmt(first, "{}")})
        still = sum(v for k, v in enumerate(inv) if k not in moved)
        return {"image": "img/implicit/animated/invalidations.png", "spans": spans, "still": still,
                "frames": ev.row["frames"], "description": sc.description}
    out["animated"] = part("animated", animated)


def _empty(note: str = "") -> dict:
    return {"available": False, "note": note, "notes": [], "rows": [], "comparisons": [], "heatmaps": None,
            "sphere_steps": None, "lipschitz": [], "double_root": None, "animated": None, "legend": [],
            "size": "", "frames": None, "steps": None, "seconds": 0.0, "threads": torch.get_num_threads()}


def build_implicit_section(run_dir: str, width: int = 96, height: int = 72, *, frames: int = 40, steps: int = 32,
                           seed: int = 0, use_cache: bool = False, lipschitz_samples: int = 20_000,
                           threads: Optional[int] = 1) -> dict:
    """Run the implicit section into ``run_dir`` (images under ``img/implicit/``); returns its template metadata.

    ``frames`` frames of the comparison at ``steps`` marching steps (the catalog's thin cases are designed
    against ``N = 32``). ``threads``: torch threads while the section runs (restored after; None: unchanged).
    One by default: tensors of 96×72 rays gain nothing from more, and on shared cores OpenMP barriers stall
    (measured on 2 busy cores: 26 s with 1 thread, 340 s with 2). Never raises: failures become notes.
    """
    before = torch.get_num_threads()
    if threads:
        torch.set_num_threads(threads)
    try:
        return _build(run_dir, width, height, frames, steps, seed, use_cache, lipschitz_samples)
    finally:
        torch.set_num_threads(before)


def _build(run_dir, width, height, frames, steps, seed, use_cache, lipschitz_samples) -> dict:
    t0 = time.perf_counter()
    try:
        import importlib
        for mod in ("ssbench.evaluate", "ssbench.metrics.implicit", "ssbench.reference.implicit"):
            importlib.import_module(mod)
        out = _empty()
        out.update(legend=class_legend(), size=f"{width}×{height}", frames=frames, steps=steps)
    except Exception as e:
        return _empty(f"Implicit section skipped: the implicit slice is not importable ({type(e).__name__}: {e}).")
    _parts(run_dir, (width, height), frames, steps, seed, use_cache, lipschitz_samples, out)
    out["available"] = bool(out["comparisons"] or out["lipschitz"] or out["animated"])
    out["note"] = "" if out["available"] else "Implicit section: every part failed."
    out["seconds"] = time.perf_counter() - t0
    return out


def summary_md(imp: dict) -> str:
    """The implicit section of ``summary.md``: the comparison, λ overshoots, the double root, invalidations."""
    lines = ["", "## Implicit surfaces", ""]
    if not imp.get("available"):
        return unavailable_md(lines, imp, "Implicit")
    lines.append(f"{imp['size']}, N = {imp['steps']}, {imp['frames']} frames; punch-through progressive vs fixed "
                 "step (h/w prediction in brackets).")
    lines.append("")
    for c in imp["comparisons"]:
        p, f = c["cells"]["progressive"], c["cells"]["fixed"]
        lines.append(f"- {c['name']}: frame 1 {p['first']} vs {f['first']} ({p['first_pred']}); frame "
                     f"{imp['frames']} {p['last']} ({p['last_pred']}) vs {f['last']}; < 1% at frame {p['to1']} "
                     f"({p['to1_pred']}); evaluations/px {p['evals']} vs {f['evals']}.")
    over = [f"{r['scene']} (declared {r['declared']}, observed {r['observed']})" for r in imp["lipschitz"]
            if r["overshoot"]]
    lines.append(f"- λ overshoot: {', '.join(over) or 'none'}.")
    if imp["double_root"]:
        dr = imp["double_root"]
        lines.append(f"- double_root: fixed step hits {dr['fixed_hit']}, truth hits {dr['truth_hit']}; interval "
                     f"arithmetic flags {dr['ambiguous']} ambiguous pixels (no sign change to find).")
    if imp["animated"]:
        a = imp["animated"]
        lines.append("- animated invalidations: " + "; ".join(f"{s['what']} (frames {s['frames']}) {s['total']}, "
                                                             f"first at frame {s['first']}" for s in a["spans"])
                     + f"; other frames {a['still']}.")
    return "\n".join(lines + [f"- {n}" for n in imp["notes"]]) + "\n"
