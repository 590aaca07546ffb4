"""The AO section's "beyond AO" table: every AO method's bent normal and multi-bounce AO against their own truths
(:func:`ssbench.evaluate.ao_beyond`), on :data:`SCENES` at radius :data:`RADIUS` with :data:`RAYS` rays per
pixel, beside the baselines (shading normal; exact single-bounce AO; the fit on the exact AO) and the truths'
error bars. Rows (``rows/ao_beyond.jsonl``): one per scene and method.
"""
from __future__ import annotations

from typing import Optional

from .summary import fmt

SCENES = ("crease", "stairs", "cornell_box")
RADIUS = 0.5
RAYS = 256
KEYS = ("bent_mean_deg", "bent_p95_deg", "multibounce_rmse", "multibounce_bias")
BASE_KEYS = ("shading_normal_mean_deg", "bent_truth_stderr_deg", "single_bounce_rmse", "fit_exact_rmse",
             "multibounce_truth_stderr")


def build_ao_beyond(width: int = 160, height: int = 120, *, seed: int = 0, use_cache: bool = True,
                    progress: Optional[bool] = None) -> dict:
    """``{"available", "rows", "scenes", "notes", ...}``; a scene or method that fails is a note."""
    from tqdm import tqdm
    from ..evaluate import ao_beyond
    from ..passes import AO_METHODS
    rows, notes, scenes = [], [], []
    jobs = [(s, m) for s in SCENES for m in AO_METHODS]
    for scene, m in tqdm(jobs, desc="AO beyond", unit="run", disable=None if progress is None else not progress):
        try:
            rows.append(ao_beyond(scene, m, width=width, height=height, radius=RADIUS, rays=RAYS, seed=seed,
                                  use_cache=use_cache))
        except Exception as e:
            notes.append(f"{m} on {scene} (bent normal / multi-bounce): {type(e).__name__}: {e}")
    for scene in SCENES:
        mine = [r for r in rows if r["scene"] == scene]
        if not mine:
            continue
        base = {k: fmt(mine[0][k], "{:.2f}" if k.endswith("_deg") else "{:.4f}") for k in BASE_KEYS}
        cells = [{"method": r["method"], **{k: fmt(r[k], "{:.2f}" if k.endswith("_deg") else "{:.4f}") for k in KEYS}}
                 for r in mine]
        scenes.append({"scene": scene, "base": base, "methods": cells})
    return {"available": bool(rows), "rows": rows, "scenes": scenes, "notes": notes, "radius": RADIUS,
            "rays": RAYS, "size": f"{width}×{height}"}


def summary_lines(beyond: dict) -> list:
    """The bent-normal and multi-bounce tables of the AO part of ``summary.md``."""
    if not beyond.get("available"):
        return []
    lines = ["", f"### Beyond AO: bent normals and multi-bounce ({beyond['size']}, radius {beyond['radius']}, "
                 f"{beyond['rays']} rays)", ""]
    for s in beyond["scenes"]:
        b = s["base"]
        lines += [f"{s['scene']}: shading normal {b['shading_normal_mean_deg']}° from the bent normal (truth ± "
                  f"{b['bent_truth_stderr_deg']}°); multi-bounce truth ± {b['multibounce_truth_stderr']}, "
                  f"single bounce RMSE {b['single_bounce_rmse']}, fit on exact AO {b['fit_exact_rmse']}.", "",
                  "| method | bent mean ° | bent p95 ° | multi-bounce RMSE | bias |", "|---|---:|---:|---:|---:|"]
        lines += [f"| {c['method']} | " + " | ".join(c[k] for k in KEYS) + " |" for c in s["methods"]] + [""]
    return lines + [f"- {n}" for n in beyond["notes"]]
