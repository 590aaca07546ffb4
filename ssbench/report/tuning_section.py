"""The report's tuning section: default vs tuned AO error on held-out scenes.

:func:`ssbench.tune.tune` fits each method of :data:`METHODS` on :data:`TRAIN` against the cosine ray-traced AO
at a fixed radius and scores the defaults and the tuned parameters on :data:`HELD_OUT`. To stay within about a
minute on two cores it runs small: the report's size scaled down to at most ``max_width`` pixels wide, few
ground-truth rays, a 3-node grid. The numbers are therefore indicative; ``ssbench tune`` runs the full-size
search. The section never raises: a method that fails becomes a note. Rows go to ``rows/tuning.jsonl`` and each
method's full result to ``tuning/<method>.json``.
"""
from __future__ import annotations

import json
import math
import os
import time
import traceback
from typing import Optional

import torch

from .summary import unavailable_md

def report_methods() -> tuple[str, ...]:
    """The AO methods whose module declares ``TUNED_IN_REPORT = True`` (and something ``TUNABLE``)."""
    from ..passes import AO_METHODS, ao_method, declared
    return tuple(m for m in AO_METHODS
                 if declared(ao_method(m)[0], "TUNED_IN_REPORT", False) and declared(ao_method(m)[0], "TUNABLE"))


#: methods tuned in the report (each method's own ``TUNED_IN_REPORT``), training scenes and held-out scenes
METHODS = report_methods()
TRAIN = ("crease", "sphere_on_plane")
HELD_OUT = ("cornell_box", "stairs")


def _fmt(v, spec: str = "{:.4f}") -> str:
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else spec.format(v)


def tuning_size(width: int, height: int, max_width: int = 80) -> tuple[int, int]:
    """``(w, h)``: the report size scaled down (aspect kept) to at most ``max_width`` wide.

    Example:
        >>> tuning_size(320, 240), tuning_size(40, 30)
        ((80, 60), (40, 30))
    """
    if width <= max_width:
        return width, height
    return max_width, max(1, round(height * max_width / width))


def _empty(note: str = "") -> dict:
    return {"available": False, "note": note, "notes": [], "methods": [], "rows": [], "size": "", "seconds": 0.0,
            "threads": torch.get_num_threads(), "train": list(TRAIN), "held_out": list(HELD_OUT), "gt_radius": None,
            "rays": None, "weighting": "cosine", "search": ""}


def _method_block(res) -> dict:
    """Template cells of one :class:`~ssbench.tune.TuneResult`."""
    m = res.summary
    params = [{"name": p["name"], "default": _fmt(p["default"], "{:.4g}"),
               "tuned": _fmt(p["tuned"], "{:.4g}") + (f" (at {p['at_bound']} bound)" if p.get("at_bound") else ""),
               "range": f"[{p['lo']:.4g}, {p['hi']:.4g}]",
               "differentiable": "yes" if p["differentiable"] else f"no ({p['why'].split(' (')[0]})"}
              for p in res.params]
    scenes = [{"scene": r["scene"], "split": r["split"].replace("_", "-"), "default": _fmt(r["default"]),
               "tuned": _fmt(r["tuned"]), "change": _fmt(r["change"], "{:+.1%}")} for r in res.rows]
    improved = bool(m["held_improved"])
    verdict = (f"tuning beats the defaults on the held-out scenes: mean RMSE {_fmt(m['held_default'])} → "
               f"{_fmt(m['held_tuned'])}" if improved else
               f"tuning does NOT beat the defaults on the held-out scenes: mean RMSE {_fmt(m['held_default'])} → "
               f"{_fmt(m['held_tuned'])}") + (f" ({m['note']})" if m.get("note") else "")
    return {"method": res.method, "params": params, "scenes": scenes, "improved": improved, "verdict": verdict,
            "train_default": _fmt(m["train_default"]), "train_tuned": _fmt(m["train_tuned"]),
            "held_default": _fmt(m["held_default"]), "held_tuned": _fmt(m["held_tuned"]),
            "time_default": _fmt(m["time_ms_default"], "{:.1f}"), "time_tuned": _fmt(m["time_ms_tuned"], "{:.1f}"),
            "source": m["source"], "evaluations": res.search["evaluations"], "seconds": m["seconds"],
            "held_default_value": m["held_default"], "held_tuned_value": m["held_tuned"],
            "time_ms_tuned": m["time_ms_tuned"]}


def _rows(res) -> list[dict]:
    s = res.settings
    tuned = {p["name"]: p["tuned"] for p in res.params}
    return [{"method": res.method, "scene": r["scene"], "split": r["split"], "rmse_cos_default": r["default"],
             "rmse_cos_tuned": r["tuned"], "tuned_params": tuned, "width": s["width"], "height": s["height"],
             "gt_radius": s["gt_radius"], "rays": s["rays"], "seed": s["seed"], "source": res.summary["source"]}
            for r in res.rows]


def build_tuning_section(run_dir: str, *, width: int, height: int, seed: int = 0, use_cache: bool = True,
                         progress=None, methods=METHODS, train=TRAIN, held_out=HELD_OUT, gt_radius: float = 0.5,
                         rays: int = 128, points: int = 3, rounds: int = 4, steps: int = 5, max_width: int = 80,
                         threads: Optional[int] = 1) -> dict:
    """Tune ``methods`` on ``train``, score ``held_out``; returns the template metadata (never raises).

    ``width × height`` is the report's size (tuning runs at :func:`tuning_size` of it); ``progress``: ``None``
    (a bar when on a terminal), ``True`` or ``False``. ``threads``: torch threads while it runs (restored).
    """
    t0 = time.perf_counter()
    before = torch.get_num_threads()
    try:
        if threads:
            torch.set_num_threads(threads)
        return _build(run_dir, width, height, seed, use_cache, progress, methods, train, held_out, gt_radius,
                      rays, points, rounds, steps, max_width, t0)
    except Exception as e:                                       # the report must never crash here
        out = _empty(f"Tuning section failed: {type(e).__name__}: {e}")
        out["seconds"] = time.perf_counter() - t0
        return out
    finally:
        torch.set_num_threads(before)


def _build(run_dir, width, height, seed, use_cache, progress, methods, train, held_out, gt_radius, rays, points,
           rounds, steps, max_width, t0) -> dict:
    from tqdm import tqdm
    try:
        from ..tune import prepare_cases, tune
    except Exception as e:
        return _empty(f"Tuning section skipped: ssbench.tune is not importable ({type(e).__name__}: {e}).")
    w, h = tuning_size(int(width), int(height), max_width)
    out = _empty()
    out.update(size=f"{w}×{h}", gt_radius=gt_radius, rays=rays, train=list(train), held_out=list(held_out),
               search=f"grid {points} nodes per axis × {rounds} rounds, then {steps} Adam steps",
               threads=torch.get_num_threads())
    kw = dict(width=w, height=h, gt_radius=gt_radius, rays=rays, weighting="cosine", seed=seed, use_cache=use_cache)
    try:
        cases = (prepare_cases(list(train), **kw), prepare_cases(list(held_out), **kw))
    except Exception as e:
        out.update(note=f"Tuning section: ground truth failed ({type(e).__name__}: {e})",
                   seconds=time.perf_counter() - t0)
        return out
    for m in tqdm(list(methods), desc="tuning", unit="method", disable=None if progress is None else not progress):
        try:
            res = tune(m, list(train), list(held_out), cases=cases, points=points, rounds=rounds, steps=steps, **kw)
        except Exception as e:
            out["notes"].append(f"{m} skipped: {type(e).__name__}: {e} "
                                f"({traceback.extract_tb(e.__traceback__)[-1].name})")
            continue
        out["methods"].append(_method_block(res))
        out["rows"] += _rows(res)
        try:
            path = os.path.join(run_dir, "tuning", f"{m}.json")
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8") as f:
                json.dump(res.as_dict(), f, indent=1, default=str)
        except OSError as e:
            out["notes"].append(f"{m}: could not write tuning/{m}.json ({e})")
    out["available"] = bool(out["methods"])
    out["note"] = "" if out["available"] else "Tuning section: every method failed."
    out["glance"] = [{"method": b["method"], "headline": f"held-out RMSE {b['held_default']} → {b['held_tuned']} "
                      f"({'better' if b['improved'] else 'NOT better'})",
                      "seconds": _fmt(b["time_ms_tuned"] / 1e3, "{:.3f}"), "scenes": len(b["scenes"])}
                     for b in out["methods"]]
    out["seconds"] = time.perf_counter() - t0
    return out


def summary_md(out: dict) -> str:
    """The tuning section of ``summary.md``: per method default vs tuned held-out RMSE and the verdict."""
    lines = ["", "## Tuning", ""]
    if not out.get("available"):
        return unavailable_md(lines, out, "Tuning")
    lines.append(f"Tuned on {', '.join(out['train'])}, held out {', '.join(out['held_out'])}; cosine GT radius "
                 f"{out['gt_radius']}, {out['rays']} rays, {out['size']}; {out['search']}.")
    lines.append("")
    for b in out["methods"]:
        tuned = ", ".join(f"{p['name']} {p['default']}→{p['tuned']}" for p in b["params"])
        lines.append(f"- {b['method']}: {b['verdict']} (training {b['train_default']} → {b['train_tuned']}); "
                     f"{tuned}; {b['time_default']} → {b['time_tuned']} ms/frame.")
    return "\n".join(lines + [f"- {n}" for n in out["notes"]]) + "\n"
