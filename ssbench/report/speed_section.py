"""The report's speed-against-error section: embedded default sweeps, fronts, equal-error cost.

Per effect (``ao``, ``ssr``, ``implicit``) it runs the embedded sweep file ``sweeps/<effect>.yaml`` (one or more
``---``-separated sweep documents, rows pooled; resolution set to min(report size, :data:`SIZE`), seeds to
the report's seed; each document's methods and grids are what the method modules declare as ``SPEED_GRIDS``,
:mod:`ssbench.report.speed_sweeps`) with :func:`ssbench.bench.run_sweep` into ``run_dir/sweeps/<sweep name>/``, writes the pooled
raw rows to ``run_dir/rows/speed_<effect>.jsonl`` and ``.parquet`` (``rows/<effect>.jsonl`` belongs to the
effect's own section), and writes under ``img/speed/``:

* ``<effect>_error_time.png`` — every configuration a point, error (each of the effect's :data:`SPECS` metrics)
  against time (log), per scene; the Pareto front as a step line, listed in the page; on the primary metric
  the ground truth's ladder (:mod:`ssbench.analysis.equal_error`) for scale;
* ``<effect>_<figure>.png`` — the artifact-vs-parameter small multiples (:mod:`ssbench.analysis.multiples`),
  one panel per ``SpeedPanel`` the methods declare (:func:`figures`).

Equal-error cost, per scene and method at its best configuration (least primary error): AO — the cosine
ground-truth rays of equal RMSE and their time; SSR — the exact mirror trace (one ray per pixel, zero hit
error) and the mirror-radiance spp of equal colour RMSE; implicit — the fixed-step march steps of equal
punch-through and the certified reference's time. Nothing here crashes the report: a failing effect is a note.
"""
from __future__ import annotations

import os
import time
import traceback
from typing import Any, Optional

from ..analysis import multiples as MU
from ..analysis.multiples import Panel
from .ao_section import fmt
from .speed_summary import glance_lines, summary_md
from .speed_sweeps import as_sweeps, run_sweeps, write_rows, load_embedded

#: summary_md is the section's (build.py calls ``<section>_section.summary_md``); it lives in speed_summary
__all__ = ["build_speed_section", "summary_md", "figures", "default_sweeps", "SPECS", "SIZE", "EFFECT_TITLES"]

#: the sweeps' largest image size (the report's, when smaller)
SIZE = (160, 120)
SWEEP_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "sweeps")
EFFECT_TITLES = {"ao": "Ambient occlusion", "ssr": "Screen-space reflections", "implicit": "Implicit surfaces"}
_SSR_WRONG = ("frac_missed", "frac_false_hit", "frac_misplaced_hit", "frac_punch_through", "frac_unfixable_hit")
def _ssr_derived(row: dict) -> None:
    """``hit_error_share``: missed + false + misplaced hits + punch-through + hits on unfixable targets (shares of
    the reflective pixels)."""
    vals = [row.get(k) for k in _SSR_WRONG]
    row["hit_error_share"] = sum(vals) if all(isinstance(v, (int, float)) for v in vals) else None


#: per effect: ``metrics`` (row key, label; the first is primary: best configurations, summary, front), ``eq``
#: (the metric of the equal-error ladder), ``derive`` (adds derived keys to a row in memory, not to the raw rows)
#: and ``figures`` (small multiples: key -> (title, metric, y label); their panels are what each method declares
#: as ``SPEED_PANELS``: :func:`figures`)
SPECS: dict[str, dict] = {
    "ao": {"metrics": [("rmse_cos", "RMSE vs cosine AO"), ("flip_cos", "ꟻLIP vs cosine AO"),
                       ("halo_dark_flavour", "dark halo (false occlusion at edges)"),
                       ("banding", "banding")], "eq": "rmse_cos",
           "derive": None, "figures": {"banding": ("Banding vs sample count and noise tile", "banding", ""),
                                       "halos": ("Halos vs range check and blur", "halo_dark_flavour", "")}},
    "ssr": {"metrics": [("hit_error_share", "missed + wrong hits (false, misplaced, punch-through, unfixable)"),
                        ("rmse_faded", "colour RMSE"),
                        ("flip_faded", "colour ꟻLIP")], "eq": "rmse_faded", "derive": _ssr_derived,
            "figures": {"hits": ("Missed / false hits and punch-through vs steps, stride, thickness, jitter",
                                 _SSR_WRONG, "share of reflective pixels")}},
    "implicit": {"metrics": [("punch_through_rate", "punch-through (final frame)"), ("false_hit_rate", "false hits"),
                             ("depth_rel_mae", "relative depth MAE")], "eq": "punch_through_rate", "derive": None,
                 "figures": {"punch": ("Punch-through vs step size and frame", "punch_through_rate", "")}},
}


def figures(effect: str) -> dict:
    """``{key: (title, [Panel, ...])}`` of ``effect``'s artifact figures: every panel a method of the effect
    declares (``SPEED_PANELS``, :class:`ssbench.passes.SpeedPanel`), in registry order; a panel naming a
    figure the effect does not have is a ``ValueError`` naming the method."""
    from ..bench import get_effect
    from ..passes import declared
    eff, spec = get_effect(effect), SPECS[effect]["figures"]
    out: dict = {k: (title, []) for k, (title, _, _) in spec.items()}
    for name in eff.method_names():
        for sp in declared(eff.method(name)[0], "SPEED_PANELS", ()) or ():
            if sp.figure not in spec:
                raise ValueError(f"{name}: SPEED_PANELS names figure {sp.figure!r}; {effect} has "
                                 f"{', '.join(spec)}")
            _, metric, ylabel = spec[sp.figure]
            out[sp.figure][1].append(Panel(name, sp.param, sp.metric or metric, tuple(sp.fix),
                                           ylabel=ylabel if sp.metric is None else ""))
    return out


def default_sweeps() -> dict[str, str]:
    """``{effect: path}`` of the embedded sweep files."""
    return {e: os.path.join(SWEEP_DIR, f"{e}.yaml") for e in SPECS}


_LADDER_KEYS = {"ao": ("width", "height", "seed", "radius", "rays"), "ssr": ("width", "height", "seed", "spp"),
                "implicit": ("width", "height", "seed")}


def _ladder_key(effect: str, row: dict) -> tuple:
    return tuple(row.get(k) for k in _LADDER_KEYS[effect])


def _ladders(effect: str, rows: list, use_cache: bool, notes: list) -> dict:
    """``{scene: Ladder}`` at the size, seed (and AO radius and rays, SSR spp) of the scene's first row; rows
    with other values are left out of the equal-error table (a note says so)."""
    from ..analysis import equal_error as EQ
    from ..analysis.pareto import row_value
    out, truth_cache = {}, {}
    ok = [r for r in rows if not r.get("error")]
    for scene in dict.fromkeys(r["scene"] for r in ok):
        mine = [r for r in ok if r["scene"] == scene]
        r = mine[0]
        if any(_ladder_key(effect, x) != _ladder_key(effect, r) for x in mine):
            notes.append(f"{scene}: rows differ in {', '.join(_LADDER_KEYS[effect])}; equal-error cost only for "
                         f"those like its first row")
        try:
            if effect == "ao":
                out[scene] = EQ.ao_ladder(scene, r["width"], r["height"], r["radius"], r["rays"], r["seed"],
                                          use_cache=use_cache)
            elif effect == "ssr":
                out[scene] = EQ.ssr_ladder(scene, r["width"], r["height"], r["spp"], r["seed"], use_cache=use_cache)
            else:
                stop = min(row_value(b, SPECS[effect]["eq"]) for b in EQ.best_rows(mine, SPECS[effect]["eq"]).values())
                out[scene] = EQ.implicit_ladder(scene, r["width"], r["height"], r["seed"], stop_at=stop,
                                                truth_cache=truth_cache, use_cache=use_cache)
            out[scene] = (out[scene], _ladder_key(effect, r))
        except Exception as e:                                # noqa: BLE001 - a note, not a crash
            notes.append(f"{effect} ground-truth ladder of {scene} skipped: {type(e).__name__}: {e}")
    return out


def _config(row: dict) -> str:
    return MU.config_text(row, [k for k in (row.get("config") or {}).get("params", {})
                                if k not in ("kernel_radius", "radius")]
                          + (["blur"] if row.get("blur") else []))


def _tables(rows: list, eq_rows: list, spec: dict, fronts: dict, ladders: dict) -> dict:
    from ..analysis import equal_error as EQ
    from ..analysis.pareto import row_time_ms, row_value
    primary = spec["metrics"][0][0]
    labels = dict(spec["metrics"])
    on_front = {(s, r["config_id"]) for (s, m), pts in fronts.items() if m == primary for r in pts}
    by_id = {r["config_id"]: r for r in rows}
    scenes, methods = (list(dict.fromkeys(r[k] for r in rows)) for k in ("scene", "method"))
    order = lambda d: (scenes.index(d["scene"]), methods.index(d["method"]))                    # noqa: E731
    out = {
        "fronts": [{"scene": s, "metric": labels[m], "points": [
            {"method": r["method"], "config": _config(r), "error": fmt(row_value(r, m), "{:.4g}"),
             "time": fmt(row_time_ms(r), "{:.2f}")} for r in pts]} for (s, m), pts in fronts.items()],
        "summary": [{"scene": s, "method": m, "config": _config(r), "error": fmt(row_value(r, primary), "{:.4g}"),
                     "time": fmt(row_time_ms(r), "{:.2f}"), "time_s": row_time_ms(r) / 1e3,
                     "floor_ratio": fmt(r.get("floor_ratio"), "{:.1f}"),
                     "fused_floor_ratio": fmt(r.get("fused_floor_ratio"), "{:.1f}"),
                     "front": "yes" if (s, r["config_id"]) in on_front else "no"}
                    for (s, m), r in EQ.best_rows(rows, primary).items()],
        "equal_error": [dict(e, config=_config(by_id[e["config_id"]]), error=fmt(e["error"], "{:.4g}"),
                             time_ms=fmt(e["time_ms"], "{:.2f}"), gt_ms=fmt(e["gt_ms"], "{:.1f}"),
                             ratio=fmt(e["ratio"], "{:.3g}"), n=fmt(e["n"], "{:.3g}"))
                        for e in EQ.equal_error_table(eq_rows, ladders, spec["eq"])],
        "ladders": [{"scene": s, "kind": L.kind, "label": L.label, "ns": list(L.ns),
                     "errors": [fmt(x, "{:.4g}") for x in L.errors], "ms": [fmt(1e3 * x, "{:.1f}") for x in L.seconds],
                     "predicted": [fmt(x, "{:.4g}") for x in L.predicted] if L.predicted else None,
                     "reference": fmt(1e3 * L.reference_seconds, "{:.1f}"), "reference_n": L.reference_n}
                    for s, L in ladders.items()]}
    out["summary"].sort(key=order)
    out["equal_error"].sort(key=order)
    return out


def _effect(effect: str, sweeps: list, run_dir: str, progress, use_cache: bool) -> dict:
    from ..analysis.figures import error_time_figure
    spec, notes, t = SPECS[effect], [], [time.perf_counter()]
    rows, runs = run_sweeps(sweeps, run_dir, progress, notes)
    files = write_rows(rows, os.path.join(run_dir, "rows", f"speed_{effect}"))
    for r in rows:
        if spec["derive"]:
            spec["derive"](r)
        if r.get("error"):
            notes.append(f"{r['scene']} {r['method']} {_config(r)}: {r['error']}")
    t.append(time.perf_counter())
    keyed = _ladders(effect, rows, use_cache, notes)
    ladders = {sc: lad for sc, (lad, _) in keyed.items()}
    eq_rows = [r for r in rows if r["scene"] in keyed and keyed[r["scene"]][1] == _ladder_key(effect, r)]
    t.append(time.perf_counter())
    img = os.path.join(run_dir, "img", "speed")
    rel = lambda p: os.path.relpath(p, run_dir).replace(os.sep, "/")          # noqa: E731
    fig = os.path.join(img, f"{effect}_error_time.png")
    eq_metric = spec["eq"]
    fronts = error_time_figure(rows, spec["metrics"], fig, scenes=list(dict.fromkeys(r["scene"] for r in rows)),
                               ladders=ladders, ladder_metric=eq_metric,
                               title=f"{EFFECT_TITLES[effect]}: error against time")
    explorer = _explorer(effect, rows, spec, fronts, img, rel)
    multiples = []
    for key, (title, panels) in figures(effect).items():
        if not panels:
            continue
        p = os.path.join(img, f"{effect}_{key}.png")
        data = MU.small_multiples(rows, panels, p, ncols=min(len(panels), 4 if effect == "ssr" else 3), title=title)
        multiples.append({"title": title, "image": rel(p), "points": sum(d["points"] for d in data)})
    t.append(time.perf_counter())
    return {"name": effect, "title": EFFECT_TITLES[effect], "available": True, "note": "", "notes": notes,
            "rows": len(rows), "errors": sum(bool(r.get("error")) for r in rows), "sweeps": runs,
            "files": {k: rel(v) for k, v in files.items()}, "metric": spec["metrics"][0][1], "eq_metric": eq_metric,
            "figure": rel(fig), "multiples": multiples, "explorer": explorer, **_tables(rows, eq_rows, spec, fronts, ladders),
            "seconds": t[-1] - t[0], "stages": {"sweeps": t[1] - t[0], "ladders": t[2] - t[1], "figures": t[3] - t[2]}}


def _explorer(effect: str, rows: list, spec: dict, fronts: dict, img: str, rel) -> dict:
    """The sweep explorer's data (:mod:`ssbench.report.explorer`), with the error map's colour bar written."""
    from ..bench import get_effect
    from .colorbars import colorbar_png
    from .explorer import explorer_data
    pics = get_effect(effect).picture_spec()
    bar = None
    if pics is not None and pics.scale is not None:
        sc = pics.scale
        bar = rel(colorbar_png(os.path.join(img, f"{effect}_explorer_colorbar.png"), sc.cmap, sc.vmin, sc.vmax,
                               sc.label, low=sc.low, high=sc.high))
    return explorer_data(effect, EFFECT_TITLES[effect], rows, spec["metrics"], fronts, bar, pics)


def build_speed_section(run_dir: str, *, width: int, height: int, seed: int = 0, use_cache: bool = True,
                        progress: Optional[bool] = None, sweeps: Optional[dict] = None,
                        threads: Optional[int] = 1) -> dict:
    """Run the speed section into ``run_dir``; returns its template metadata (never raises).

    Args:
        width, height: the report's size; the embedded sweeps run at min(it, :data:`SIZE`).
        seed: the sweeps' seed (embedded sweeps) and the ground truths'.
        use_cache: the reference disk cache for the equal-error ladders' references (the sweeps' evaluations
            always read it; the ladders' own times are measured afresh).
        sweeps: ``{effect: Sweep | dict | path | list of them}`` replacing the embedded sweeps of those effects
            (used as given); effects missing from it are skipped when it is given.
        threads: torch threads while the section runs (restored after).
    """
    import torch
    t0, before = time.perf_counter(), torch.get_num_threads()
    size = (min(width, SIZE[0]), min(height, SIZE[1]))
    out: dict[str, Any] = {"available": False, "note": "", "notes": [], "effects": [], "seconds": 0.0,
                           "size": f"{size[0]}×{size[1]}", "threads": threads or before, "gt_threads": None}
    try:
        from ..reference import backend
        out["gt_threads"] = backend.info().get("drjit_threads")
    except Exception:                                          # noqa: BLE001 - metadata only
        pass
    try:
        if threads:
            torch.set_num_threads(threads)
        todo = {e: ("embedded", p) for e, p in default_sweeps().items()} if sweeps is None else \
            {e: ("given", v) for e, v in sweeps.items()}
        for effect, (kind, value) in todo.items():
            try:
                if effect not in SPECS:
                    raise ValueError(f"sweeps: unknown effect {effect!r}; known: {', '.join(SPECS)}")
                sw = load_embedded(value, size, seed) if kind == "embedded" else as_sweeps(value)
                bad = [s.name for s in sw if s.effect != effect]
                if bad:
                    raise ValueError(f"sweeps[{effect!r}]: sweep(s) {bad} are of another effect")
                out["effects"].append(_effect(effect, sw, run_dir, progress, use_cache))
            except Exception as e:                            # noqa: BLE001 - the report must not crash
                if os.environ.get("SSBENCH_DEBUG"):
                    traceback.print_exc()
                out["effects"].append({"name": effect, "title": EFFECT_TITLES.get(effect, effect),
                                       "available": False, "note": f"{effect} skipped: {type(e).__name__}: {e}",
                                       "notes": []})
    finally:
        torch.set_num_threads(before)
    out["available"] = any(e["available"] for e in out["effects"])
    out["glance"] = glance_lines(out)
    if not out["available"]:
        out["note"] = "Speed section: no effect could run." + "".join(
            f" {e['note']}" for e in out["effects"] if e.get("note"))
    out["seconds"] = time.perf_counter() - t0
    return out
