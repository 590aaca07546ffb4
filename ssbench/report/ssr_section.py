"""The report's screen-space reflections section: exact mirror truth, every SSR method at its defaults.

Per scene (default :data:`SSR_SCENES`; a report run with an explicit scene list uses that list) it takes one
G-buffer (the report's own render when it has one, else a fresh one), traces the exact reflections
(``ssbench.reference.reflections``), runs every method of :data:`ssbench.passes.SSR_METHODS` through
:func:`ssbench.evaluate.run_ssr` at its default parameters (one untimed debug run for the visit map), and writes

* ``img/ssr/<scene>/truth.png`` — path-traced radiance along the mirror ray (linear → sRGB);
* ``truth_classes.png`` — what a perfect screen-space pass would get: visible target (green), off-screen /
  occluded / back-face target, sky (the class colours of :mod:`ssbench.metrics.ssr`);
* ``<method>.png`` — the pass's reflection colour with its fades; ``<method>_classes.png`` — its per-pixel
  classes (an unfixable target where the pass still reported a hit is its own error class); ``<method>_<view>.png`` —
  each debug buffer the method declares in ``DEBUG_VIEWS`` (e.g. ``debug["visits"]``, depth fetches per texel,
  log scale, SSR article Fig. 11); ``<method>_error.png`` — mean
  absolute RGB error of the raw (fade-free) colour against the truth radiance (magma, saturating at
  :data:`ERR_RANGE`) where the pass can be blamed, grey where the target is unreachable and the pass returned
  nothing (:func:`scored_error_rgb`);
* ``fig11.png`` (first scene only) — one ray's reads per marcher against the pixels it crosses
  (:mod:`.ssr_fig11`, SSR article Fig. 11), when the linear march and both DDAs ran;

plus the class-fraction table with times, the equal-reads table of the first scene (every marcher with 8, 32 and
128 depth reads per ray, :mod:`.ssr_reads`; ``benchmarks/bench_ssr_reads.py`` runs every scene) and a table mapping one physical thickness onto each anchor's
"thickness" knob (:mod:`ssbench.metrics.thickness`). Nothing here may crash the report: a missing reference
or pass, or a failing run, becomes a visible note.
"""
from __future__ import annotations

import os
import time
import traceback
from typing import TYPE_CHECKING, Iterable, Optional

import torch

from ..passes import declared, ssr_method
from .ao_section import fmt, write_png
from .ssr_images import color_rgb, scored_error_rgb, visits_rgb
from .ssr_reads import reads_rows, reads_tables
from .summary import unavailable_md

if TYPE_CHECKING:
    from ..scenes import Scene

#: scenes of the SSR section when the report names none
SSR_SCENES = ("reflective_floor", "fence")
#: colour-error range of the error maps (linear radiance)
ERR_RANGE = 0.5
#: physical thickness and depths of the thickness-knob table
THICKNESS, THICKNESS_DEPTHS = 0.1, (1.0, 3.0, 10.0, 30.0)
#: (row key, column label, format) of the per-scene table
TABLE = (("seconds", "time s", "{:.3f}"), ("frac_correct", "correct", "{:.1%}"),
         ("frac_missed", "missed", "{:.1%}"), ("frac_false_hit", "false hit (wrong surface)", "{:.1%}"),
         ("frac_misplaced_hit", "misplaced hit (> k px)", "{:.1%}"),
         ("frac_punch_through", "punch-through", "{:.1%}"), ("frac_unfixable_hit", "hit on unfixable", "{:.1%}"),
         ("frac_off_screen_target", "off-screen", "{:.1%}"),
         ("frac_occluded_target", "occluded", "{:.1%}"), ("frac_back_face_target", "back-face", "{:.1%}"),
         ("frac_true_miss", "true miss", "{:.1%}"), ("hit_err_px_median", "hit err px (median)", "{:.2f}"),
         ("hit_err_view_median", "hit err view (median)", "{:.3f}"), ("mae_raw", "MAE raw", "{:.4f}"),
         ("mae_raw_truth_hit", "MAE raw (GT hits)", "{:.4f}"),
         ("mae_faded", "MAE faded", "{:.4f}"), ("psnr_raw", "PSNR raw dB", "{:.2f}"),
         ("flip_raw", "ꟻLIP raw", "{:.3f}"), ("steps_mean", "steps mean", "{:.1f}"),
         ("term_out_of_steps", "out of steps", "{:.1%}"))


# ------------------------------------------------------------------------------------------ section
def _unavailable(note: str, **extra) -> dict:
    from ..metrics.ssr import legend_entries
    d = {"available": False, "note": note, "notes": [], "methods": [], "scenes": [], "rows": [],
         "columns": [(k, label) for k, label, _ in TABLE], "overview": [], "legend": legend_entries(),
         "thickness": None, "seconds": 0.0, "err_range": ERR_RANGE, "spp": None, "k_px": None}
    d.update(extra)
    return d


def _methods() -> tuple[list[str], list[str], tuple[str, ...]]:
    """Importable SSR methods, notes for those that are not, and the channels they read at their defaults."""
    import importlib

    from ..evaluate import pass_channels
    from ..passes import SSR_METHODS, ssr_method
    ok, notes, channels = [], [], []
    for name in SSR_METHODS:
        try:
            fn, params_cls, _ = ssr_method(name)
            channels += list(pass_channels(importlib.import_module(fn.__module__), params_cls()))
            ok.append(name)
        except Exception as e:                                       # a pass being written, or broken
            notes.append(f"method {name} skipped: {type(e).__name__}: {e}")
    return ok, notes, tuple(dict.fromkeys(channels))


def thickness_rows(camera, thickness: float = THICKNESS, depths: Iterable[float] = THICKNESS_DEPTHS) -> dict:
    """The thickness-knob table for ``camera`` (report cells already formatted)."""
    from ..metrics import thickness as T
    rows = T.thickness_table(thickness, depths, camera)
    return {"thickness": thickness, "columns": [(k, *T.KNOBS[k]) for k in T.KNOBS],
            "rows": [{"depth": fmt(r["depth"], "{:g}"), "cells": [fmt(r[k], "{:.4g}") for k in T.KNOBS]}
                     for r in rows],
            "size": f"{camera.width}×{camera.height}", "fovy": camera.fovy_deg}


def build_ssr_section(run_dir: str, scenes: Optional[Iterable["str | Scene"]] = None, width: int = 320, height: int = 240,
                      *, spp: int = 16, seed: int = 0, k_px: float = 1.5, use_cache: bool = False,
                      gbuffers: Optional[dict] = None, progress: Optional[bool] = None) -> dict:
    """Run the SSR section into ``run_dir`` (images under ``img/ssr/``); returns its metadata for the template.

    ``gbuffers`` maps scene names to G-buffers already rendered by the report (reused when they hold every
    channel needed). Each method runs once, timed without warm-up. Never raises: failures become notes.
    """
    t_start = time.perf_counter()
    try:
        from .. import evaluate
        from ..evaluate._ssr import reflections_module
        reflections = reflections_module()
    except Exception as e:
        return _unavailable(f"SSR section skipped: the reference reflections are not importable "
                            f"({type(e).__name__}: {e}).")
    try:
        methods, notes, channels = _methods()
    except Exception as e:
        return _unavailable(f"SSR section skipped: the SSR passes are not importable ({type(e).__name__}: {e}).")
    if not methods:
        return _unavailable("SSR section skipped: no SSR method is importable yet.", notes=notes)
    from tqdm import tqdm
    names = list(SSR_SCENES if scenes is None else dict.fromkeys(scenes))
    out_scenes, rows, cam = [], [], None
    for name in tqdm(names, desc="SSR", unit="scene", disable=None if progress is None else not progress):
        try:
            s, r, g = _scene(run_dir, name, methods, channels, width, height, spp, seed, k_px, use_cache,
                             (gbuffers or {}).get(getattr(name, "name", name)), evaluate, reflections,
                             fig11=name == names[0])
            out_scenes.append(s)
            rows += r
            cam = cam or g.camera
        except Exception as e:
            notes.append(f"scene {getattr(name, 'name', name)} skipped: {type(e).__name__}: {e}")
            if os.environ.get("SSBENCH_DEBUG"):
                traceback.print_exc()

    def pick(s, m, k, setting="defaults"):
        return next((r.get(k) for r in rows if r["scene"] == s["name"] and r["method"] == m
                     and r.get("setting") == setting), None)

    overview = [{"method": m, "cells": [fmt(pick(s, m, "frac_correct"), "{:.1%}") for s in out_scenes],
                 "missed": [fmt(pick(s, m, "frac_missed"), "{:.1%}") for s in out_scenes],
                 "seconds": [fmt(pick(s, m, "seconds"), "{:.3f}") for s in out_scenes]} for m in methods]
    equal = [{"method": m, "cells": [f"{fmt(pick(s, m, 'frac_correct', 'equal'), '{:.1%}')} / "
                                     f"{fmt(pick(s, m, 'frac_wrong_output', 'equal'), '{:.1%}')} / "
                                     f"{fmt(pick(s, m, 'frac_missed', 'equal'), '{:.1%}')}" for s in out_scenes],
              "params": [_equal_text(pick(s, m, "params", "equal"), m) for s in out_scenes]} for m in methods]
    from ..metrics.ssr import legend_entries
    return {"available": bool(out_scenes), "note": "" if out_scenes else "SSR section: every scene failed.",
            "notes": notes, "methods": methods, "scenes": out_scenes, "rows": rows,
            "columns": [(k, label) for k, label, _ in TABLE], "overview": overview, "equal": equal,
            "reads": reads_tables(rows),
            "equal_rule": {"ray_length": evaluate.EQUAL_RAY_LENGTH, "thickness": evaluate.EQUAL_THICKNESS},
            "legend": legend_entries(),
            "thickness": thickness_rows(cam) if cam is not None else None, "spp": spp, "k_px": k_px,
            "seconds": time.perf_counter() - t_start, "err_range": ERR_RANGE, "threads": torch.get_num_threads()}


def _scene(run_dir, name, methods, channels, width, height, spp, seed, k_px, use_cache, g, evaluate, reflections,
           fig11: bool = True):
    from .. import reference
    from ..metrics import ssr as M
    from ..scenes import load
    sc = load(name)                                             # a catalog name or a user's loaded scene
    name = sc.name
    d = os.path.join(run_dir, "img", "ssr", name)
    rel = f"img/ssr/{name}"
    need = tuple(dict.fromkeys(channels + evaluate.SSR_GT_CHANNELS + ("metallic", "roughness")))
    if g is None or (g.width, g.height) != (width, height) or any(getattr(g, c) is None for c in need):
        g = reference.gbuffer(sc, width, height, channels=need, spp=spp, seed=seed, use_cache=use_cache)
    t0 = time.perf_counter()
    truth = reflections(sc, g, spp=spp, seed=seed, use_cache=use_cache)
    gt_s = time.perf_counter() - t0
    valid = truth.valid.bool()
    tclasses = M.truth_classes(truth, g)
    images = {"truth": f"{rel}/truth.png", "truth_classes": f"{rel}/truth_classes.png"}
    write_png(os.path.join(d, "truth.png"), color_rgb(truth.radiance, valid))
    write_png(os.path.join(d, "truth_classes.png"), M.class_rgb(tclasses))
    tf = M.class_fractions(tclasses)
    method_rows, rows, notes, results = [], [], [], {}
    for m in methods:
        try:
            ev = evaluate.run_ssr(sc, m, seed=seed, spp=spp, k_px=k_px, repeats=1, warmup=False, gbuffer=g,
                                  truth=truth, debug=True, use_cache=use_cache,
                                  reflective="specular")
        except Exception as e:
            notes.append(f"{m}: {type(e).__name__}: {e}")
            continue
        row, res = ev.row, ev.result
        results[m] = res
        files = {"color": color_rgb(res.color, valid), "classes": M.class_rgb(ev.classes),
                 "error": scored_error_rgb(M.color_error_map(res.raw_color, truth.radiance), ev.classes, valid,
                                           ERR_RANGE)}
        views = []
        for key, caption in (declared(ssr_method(m)[0], "DEBUG_VIEWS", None) or {}).items():
            buf = ev.debug.get(key)                              # what the method says it returns
            if isinstance(buf, torch.Tensor) and buf.dim() == 4 and tuple(buf.shape[-2:]) == (g.height, g.width):
                files[key], top = visits_rgb(buf[:1, :1])
                views.append({"key": key, "caption": caption, "max": top})
            else:
                notes.append(f"{m}: declares debug view {key!r} but debug[{key!r}] is missing")
        imgs = {}
        for k, rgb in files.items():
            fn = f"{m}.png" if k == "color" else f"{m}_{k}.png"
            write_png(os.path.join(d, fn), rgb)
            imgs[k] = f"{rel}/{fn}"
        rows.append({**row, "setting": "defaults"})
        method_rows.append({"method": m, "images": imgs, "views": views,
                            "params": ", ".join(f"{k}={v}" for k, v in row["params"].items()),
                            "source": declared(ssr_method(m)[0], "DEFAULTS_SOURCE", ""),
                            "cells": [fmt(row.get(k), spec) for k, _, spec in TABLE]})
    for m in results:                                    # the same methods at equal settings (no pictures)
        try:
            eq = evaluate.equal_settings(m, g)
            ev = evaluate.run_ssr(sc, m, eq, seed=seed, spp=spp, k_px=k_px, repeats=1, warmup=False, gbuffer=g,
                                  truth=truth, use_cache=use_cache, reflective="specular")
            rows.append({**ev.row, "setting": "equal"})
        except Exception as e:
            notes.append(f"{m} at equal settings: {type(e).__name__}: {e}")
    if fig11:                                            # the first scene (benchmarks/bench_ssr_reads.py: all)
        rows += reads_rows(sc, g, truth, notes, seed=seed, spp=spp, k_px=k_px, use_cache=use_cache)
    fig11 = _fig11(d, rel, g, results, notes) if fig11 else None
    if fig11:
        images["fig11"] = fig11.pop("image")
    return ({"name": name, "description": sc.description, "images": images, "methods": method_rows,
             "width": g.width, "height": g.height,
             "notes": notes, "gt_seconds": gt_s, "fig11": fig11,
             "truth_cells": {k: fmt(tf.get(k), "{:.1%}") for k in ("correct", "off_screen_target",
                                                                   "occluded_target", "back_face_target",
                                                                   "true_miss")}}, rows, g)


def _equal_text(params: Optional[dict], method: str) -> str:
    """The two shared settings of an equal-settings row, by the method's own parameter names."""
    if not params:
        return "–"
    from ..evaluate import equal_roles
    return ", ".join(f"{name}={params[name]:.3g}" for name in equal_roles(method).values() if name in params)


def _fig11(d: str, rel: str, g, results: dict, notes: list) -> Optional[dict]:
    """One ray's reads per marcher (:mod:`.ssr_fig11`) when the linear march and both DDAs ran; else ``None``."""
    from . import ssr_fig11
    if not all(m in results for _, m in ssr_fig11.MARCHERS):
        return None
    try:
        pixel = ssr_fig11.pick_pixel(g, results["dda"])
        if pixel is None:
            return None
        rays = ssr_fig11.one_ray(g, pixel, results)
        ssr_fig11.plot(os.path.join(d, "fig11.png"), rays, pixel)
    except Exception as e:
        notes.append(f"one-ray visit figure: {type(e).__name__}: {e}")
        return None
    keys = ("label", "reads", "pixels", "twice", "skipped", "outside")
    return {"image": f"{rel}/fig11.png", "pixel": list(pixel), "rays": [{k: r[k] for k in keys} for r in rays]}


def summary_md(ssr: dict) -> str:
    """The SSR section of ``summary.md``: correct / missed share and time per method and scene."""
    lines = ["", "## Screen-space reflections", ""]
    if not ssr.get("available"):
        return unavailable_md(lines, ssr, "SSR")
    lines += [f"Each method at its authors' defaults; {ssr['spp']} spp truth radiance, hit tolerance {ssr['k_px']} px. "
              "Correct / missed share of reflective pixels (time s).", "",
              "| method | " + " | ".join(s["name"] for s in ssr["scenes"]) + " |",
              "|---|" + "---:|" * len(ssr["scenes"])]
    for o in ssr["overview"]:
        lines.append(f"| {o['method']} | " + " | ".join(f"{c} / {mi} ({t})" for c, mi, t in
                                                       zip(o["cells"], o["missed"], o["seconds"])) + " |")
    if ssr.get("equal"):
        rule = ssr["equal_rule"]
        lines += ["", f"At equal settings (ray length {rule['ray_length']} × S, thickness {rule['thickness']} × S, "
                  "S = median eye distance of the visible geometry): correct / wrong output / missed.", "",
                  "| method | " + " | ".join(s["name"] for s in ssr["scenes"]) + " |",
                  "|---|" + "---:|" * len(ssr["scenes"])]
        lines += [f"| {o['method']} | " + " | ".join(f"{c} ({p})" for c, p in zip(o["cells"], o["params"])) + " |"
                  for o in ssr["equal"]]
    lines += ["", "Defaults from:"] + [f"- {m}: {declared(ssr_method(m)[0], 'DEFAULTS_SOURCE') or 'not declared'}"
                                      for m in ssr["methods"]]
    return "\n".join(lines + _class_md(ssr.get("rows") or []) + [f"- {n}" for n in ssr["notes"]]) + "\n"


def _class_md(rows: list[dict]) -> list[str]:
    """Every pixel class per scene and method (share of reflective pixels), with the definitions."""
    from ..metrics import ssr as M
    codes = [c for c in M.CLASS_NAMES if c != M.NOT_REFLECTIVE]
    out = ["", "Pixel classes, share of reflective pixels (wrong output: false + misplaced + punch-through + "
           "hit on unfixable target):", "",
           "| scene | method | setting | " + " | ".join(M.CLASS_LABELS[c] for c in codes) + " | wrong output |",
           "|---|---|---|" + "---:|" * (len(codes) + 1)]
    for r in rows:
        cells = [fmt(r.get(f"frac_{M.CLASS_NAMES[c]}"), "{:.1%}") for c in codes]
        out.append(f"| {r.get('scene')} | {r.get('method')} | {r.get('setting', 'defaults')} | " + " | ".join(cells)
                   + f" | {fmt(r.get('frac_wrong_output'), '{:.1%}')} |")
    out += [""] + [f"- *{M.CLASS_LABELS[c]}*: {M.CLASS_DESCRIPTIONS[c]}" for c in codes] + [""]
    return out
