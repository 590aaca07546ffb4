"""The time section's implicit surfaces: TXAA (the progressive-tracing article's jitter, 補足: アンチエイリアシング)
resolved over frames for every implicit caster (:func:`ssbench.evaluate.implicit_frames`).

On each of :data:`SCENES`, still camera, :data:`FRAMES` frames: the mean |luminance error| at the silhouettes
against the :data:`TRUTH_FACTOR`²-sample supersampled certified reference, raw (the aliasing) and accumulated
over the last four frames, with the TXAA resolve (no depth test) and with the AO resolve's depth test (which the
jitter trips at every silhouette); flicker raw and accumulated. File: ``img/time/txaa.png`` (the error over
frames). Rows (``rows/time.jsonl``, ``kind: "time_implicit"``).
"""
from __future__ import annotations

import os
from typing import Optional

from .summary import fmt

SCENES = ("torus", "thin_shell")
FRAMES = 16
TRUTH_FACTOR = 4
KEYS = ("error_raw", "error_txaa", "error_depth_test", "flicker", "flicker_accumulated")


def _plot(path: str, curves: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(SCENES), figsize=(7.5, 3.0), layout="constrained", squeeze=False)
    for ax, scene in zip(axes[0], SCENES):
        for k, (m, (raw, acc)) in enumerate((m, c) for (s, m), c in curves.items() if s == scene):
            ax.plot(range(len(raw)), raw, ls="--", color=f"C{k}", alpha=0.7)
            ax.plot(range(len(acc)), acc, ls="-", color=f"C{k}", marker="o", ms=2, label=m)
        ax.set_title(scene, fontsize=9), ax.set_xlabel("frame"), ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("silhouette |error|")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("TXAA: raw jittered frames (dashed) vs accumulated (solid)", fontsize=10)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def implicit_rows(run_dir: str, width: int, height: int, *, use_cache: bool = True,
                  progress: Optional[bool] = None) -> dict:
    """``{"rows", "table", "notes", "image"}`` of every implicit caster on :data:`SCENES`; failures are notes."""
    from tqdm import tqdm
    from ..evaluate import LATE_FRAMES, implicit_frames
    from ..passes import IMPLICIT_METHODS
    from ..passes.temporal import AccumulationParams
    rows, notes, curves = [], [], {}
    kw = dict(frames=FRAMES, width=width, height=height, truth_factor=TRUTH_FACTOR, use_cache=use_cache)
    jobs = [(s, m) for s in SCENES for m in IMPLICIT_METHODS]
    for scene, m in tqdm(jobs, desc="time (TXAA)", unit="run", disable=None if progress is None else not progress):
        try:
            txaa = implicit_frames(scene, m, **kw)
            depth = implicit_frames(scene, m, accumulation=AccumulationParams(background=True), **kw)
        except Exception as e:
            notes.append(f"{m} on {scene} (TXAA): {type(e).__name__}: {e}")
            continue
        curves[(scene, m)] = (txaa.error_raw, txaa.error_accumulated)
        rows.append({"kind": "time_implicit", "scene": scene, "method": m, "frames": FRAMES, "width": width,
                     "height": height, "truth_factor": TRUTH_FACTOR,
                     "error_raw": txaa.raw_error(), "error_txaa": txaa.late_error(),
                     "error_depth_test": depth.late_error(),
                     "flicker": txaa.flicker, "flicker_accumulated": txaa.flicker_accumulated})
    image = None
    if curves:
        _plot(os.path.join(run_dir, "img", "time", "txaa.png"), curves)
        image = "img/time/txaa.png"
    table = [{**r, **{k: fmt(r[k], "{:.4f}") for k in KEYS}} for r in rows]
    return {"rows": rows, "table": table, "notes": notes, "image": image, "scenes": list(SCENES),
            "frames": FRAMES, "truth_factor": TRUTH_FACTOR, "late": LATE_FRAMES}


def summary_lines(imp: dict) -> list:
    """The TXAA table of the time part of ``summary.md``."""
    if not imp["table"]:
        return []
    lines = ["", f"Implicit TXAA, {imp['frames']} jittered frames on a still camera: silhouette |error| against the "
                 f"{imp['truth_factor']}²-sample supersampled reference, raw and accumulated (mean of the last "
                 f"{imp['late']} frames), with the TXAA resolve and with a depth test.", "",
             "| scene | method | error raw | error TXAA | error with depth test | flicker raw | flicker accumulated |",
             "|---|---|---:|---:|---:|---:|---:|"]
    return lines + [f"| {r['scene']} | {r['method']} | " + " | ".join(r[k] for k in KEYS) + " |"
                    for r in imp["table"]]
