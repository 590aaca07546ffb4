"""The report's "How each metric was calibrated" section: every artifact metric against the knob that causes
its artifact (:mod:`ssbench.analysis.calibration`, :mod:`ssbench.analysis.calibration_hits`), drawn as response
curves, with the direction each must move and whether it did; plus each AO method's flicker at its defaults.

Files: ``img/calibration/<experiment>.png``. Rows (``rows/calibration.jsonl``): one per response curve
(:meth:`~ssbench.analysis.calibration.Response.as_row` plus ``monotone``, ``ratio`` and ``ratio_err``), and one per AO method
with ``flicker`` (noise advancing, no jitter) and ``flicker_jitter`` (sub-pixel jitter alone).
"""
from __future__ import annotations

import os
import time
from typing import Callable, Optional

import torch

from .summary import fmt, unavailable_md

#: AO scene of the per-method flicker table
FLICKER_SCENE = "sphere_on_plane"


def _experiments(use_cache: bool) -> list[tuple[str, str, str, Callable]]:
    """(key, title, what must happen, run) of every experiment, in page order."""
    from ..analysis import calibration as C
    from ..analysis import calibration_hits as H
    return [
        ("banding", "Banding vs kernel size (SSAO article Fig. 5)", "falls as K grows; lower with the rotation on",
         lambda: C.banding_response(use_cache=use_cache)),
        ("halo", "Dark halo vs the range check (SSAO article Figs. 7–9)",
         "the dark halo rises as max_distance grows (missing occlusion falls)",
         lambda: C.halo_response(use_cache=use_cache)),
        ("flat_bias", "Flat bias vs the self-occlusion bias (SSAO article Fig. 10)", "falls as min_distance grows",
         lambda: C.flat_bias_response(use_cache=use_cache)),
        ("noise", "Noise vs kernel size (SSAO article Fig. 5)", "falls as K grows",
         lambda: C.noise_response(use_cache=use_cache)),
        ("flicker", "Flicker vs sample count (noise advancing every frame)", "falls as the samples grow",
         lambda: C.flicker_response(use_cache=use_cache)),
        ("ghosting", "Ghosting vs the temporal resolve's blend weight (camera turning)",
         "falls as α grows (less history kept)", lambda: C.ghosting_response(use_cache=use_cache)),
        ("ssr", "SSR classes vs thickness and stride (SSR article Figs. 4–6)",
         "false hits rise and misses fall with the thickness; misplaced hits rise with the stride",
         lambda: H.ssr_response(use_cache=use_cache)),
        ("punch", "Punch-through vs step count (progressive-tracing article)", "falls as the steps shorten",
         lambda: H.punch_through_response(use_cache=use_cache))]


def _plot(path: str, title: str, responses: list) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    groups: dict = {}
    for r in responses:
        groups.setdefault((r.scene, r.knob), []).append(r)
    fig, axes = plt.subplots(1, len(groups), figsize=(4.2 * len(groups), 3.3), squeeze=False, layout="constrained")
    for ax, ((scene, knob), rs) in zip(axes[0], groups.items()):
        for r in rs:
            numeric = all(isinstance(v, (int, float)) for v in r.x)
            xs = list(r.x) if numeric else list(range(len(r.x)))
            ax.errorbar(xs, r.y, yerr=r.err if any(r.err) else None, marker="o", ms=4, capsize=2,
                        label=f"{r.series} ({r.expect})")
            if numeric and min(xs) > 0 and max(xs) / min(xs) >= 8:
                ax.set_xscale("log")
                ax.minorticks_off()
            ax.set_xticks(xs, [f"{v:g}" if numeric else str(v) for v in r.x])
        metrics = {r.metric for r in rs}
        ylabel = (metrics.pop() if len(metrics) == 1 else
                  "share of reflective pixels" if all(m.startswith("frac_") for m in metrics) else "AO units")
        ax.set_xlabel(knob), ax.set_ylabel(ylabel)
        ax.set_title(scene, fontsize=10)
        ax.legend(fontsize=7, loc="best")
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=11)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _flicker_methods(use_cache: bool) -> list[dict]:
    from ..evaluate import ao_frames
    from ..passes import AO_METHODS
    out = []
    for m in AO_METHODS:
        noise = ao_frames(FLICKER_SCENE, m, frames=8, jitter=False, radius=1.0, use_cache=use_cache)
        jit = ao_frames(FLICKER_SCENE, m, frames=8, advance_noise=False, radius=1.0, use_cache=use_cache)
        out.append({"kind": "flicker", "scene": FLICKER_SCENE, "method": m, "frames": 8, "radius": 1.0,
                    "flicker": noise.flicker, "flicker_jitter": jit.flicker})
    return out


def build_calibration_section(run_dir: str, *, use_cache: bool = True, progress: Optional[bool] = None) -> dict:
    """Run every calibration experiment into ``run_dir``; returns the section's metadata. Never raises: a failed
    experiment becomes a note."""
    from tqdm import tqdm
    from ..analysis.calibration import verdict
    t0 = time.perf_counter()
    experiments, rows, notes = [], [], []
    todo = _experiments(use_cache)
    for key, title, expect, run in tqdm(todo, desc="calibration", unit="experiment",
                                        disable=None if progress is None else not progress):
        try:
            responses = run()
            rel = f"img/calibration/{key}.png"
            _plot(os.path.join(run_dir, *rel.split("/")), title, responses)
        except Exception as e:
            notes.append(f"{title}: {type(e).__name__}: {e}")
            continue
        curves = []
        for r in responses:
            v = verdict(r, max(r.err) if any(r.err) else 1e-9)
            rows.append({"kind": "response", "experiment": key, **r.as_row(), **v})
            curves.append({"scene": r.scene, "series": r.series, "metric": r.metric, "knob": r.knob,
                           "expect": r.expect, "x": ", ".join(str(x) for x in r.x),
                           "y": ", ".join(fmt(y, "{:.4g}") for y in r.y), "ok": v["monotone"],
                           "ratio": fmt(v["ratio"], "{:.2f}") + (f" ± {v['ratio_err']:.2f}"
                                                                  if v["ratio_err"] > 0 else ""),
                           "note": r.note})
        experiments.append({"key": key, "title": title, "expect": expect, "image": rel, "curves": curves})
    methods = []
    try:
        methods = _flicker_methods(use_cache)
        rows += methods
    except Exception as e:
        notes.append(f"flicker per method: {type(e).__name__}: {e}")
    ok = sum(c["ok"] for e in experiments for c in e["curves"])
    total = sum(len(e["curves"]) for e in experiments)
    glance = [{"method": e["key"], "headline": "; ".join(f"{c['series']}: {c['expect']} "
                                                          f"{'✓' if c['ok'] else '✗'} ({c['ratio']}×)"
                                                          for c in e["curves"][:2]),
               "seconds": "–", "scenes": len({c["scene"] for c in e["curves"]})} for e in experiments]
    return {"available": bool(experiments), "note": "" if experiments else "every calibration experiment failed",
            "notes": notes, "experiments": experiments, "rows": rows, "glance": glance,
            "flicker": [{**m, "flicker": fmt(m["flicker"], "{:.4f}"), "flicker_jitter": fmt(m["flicker_jitter"],
                                                                                             "{:.4f}")}
                        for m in methods],
            "passed": ok, "total": total, "seconds": time.perf_counter() - t0,
            "threads": torch.get_num_threads()}


def summary_md(sec: dict) -> str:
    """The calibration part of ``summary.md``."""
    lines = ["", "## How each metric was calibrated", ""]
    if not sec.get("available"):
        return unavailable_md(lines, sec, "Calibration")
    lines += [f"{sec['passed']} of {sec['total']} response curves move the way their metric must.", "",
              "| experiment | scene | curve | knob values | metric values | must | monotone | ratio |",
              "|---|---|---|---|---|---|---|---:|"]
    for e in sec["experiments"]:
        for c in e["curves"]:
            lines.append(f"| {e['key']} | {c['scene']} | {c['series']} ({c['metric']} vs {c['knob']}) | {c['x']} | "
                         f"{c['y']} | {c['expect']} | {'yes' if c['ok'] else 'no'} | {c['ratio']} |")
    if sec.get("flicker"):
        lines += ["", f"Flicker of each AO method at its defaults ({FLICKER_SCENE}, 8 frames): noise advancing / "
                  "sub-pixel jitter alone.", "", "| method | flicker | flicker (jitter) |", "|---|---:|---:|"]
        lines += [f"| {m['method']} | {m['flicker']} | {m['flicker_jitter']} |" for m in sec["flicker"]]
    return "\n".join(lines + [f"- {n}" for n in sec["notes"]]) + "\n"
