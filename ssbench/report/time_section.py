"""The report's "Time" section: every AO method over frames, raw and temporally accumulated
(:mod:`ssbench.passes.temporal`), as a renderer shows it — flicker on a still camera, ghosting and the error over
frames on an orbiting one, ghosting near a moving object with and without its motion vectors, and animated
raw | accumulated comparisons; then every SSR method's flicker and ghosting (:mod:`ssbench.report.time_ssr`) and
every implicit caster's TXAA (:mod:`ssbench.report.time_implicit`).

Per method (:func:`ssbench.evaluate.ao_frames`, :data:`SCENE`, radius 0.5, noise advancing every frame, Halton
sub-pixel jitter): ``flicker`` / ``flicker_accumulated`` on the still camera; on the camera turning
:data:`ORBIT_DEG` per frame, ``ghosting`` (the error the resolve adds over the raw frames where it kept history,
against each frame's ray-traced truth of the method's flavour) over every such pixel and near depth edges, and the
mean |error| of each frame raw and accumulated. On :data:`MOVING_SCENE` with :data:`MOVING` (the ball sliding over
the floor under a still camera), ``ghosting_moving`` within :data:`~ssbench.evaluate.MOVING_BAND` px of the ball
(its contact shadow trails over the static floor) with the ball's motion vectors, and
``ghosting_moving_camera_only`` reprojecting by the camera alone. Files: ``img/time/error.png``,
``img/time/<method>.gif``, ``img/time/moving_<method>.gif``. Rows (``rows/time.jsonl``): one per method.
"""
from __future__ import annotations

import os
import time
from typing import Optional

import numpy as np
import torch

from ..pictures import ao_rgb
from ..scenes.motion import Motion
from .summary import fmt, unavailable_md
from .time_implicit import implicit_rows, summary_lines as implicit_summary_lines
from .time_ssr import ssr_rows, summary_lines as ssr_summary_lines

SCENE = "stairs"
MOVING_SCENE = "sphere_on_plane"
MOVING = Motion("ball", (0.15, 0.0, 0.0))
FRAMES = 8
ORBIT_DEG = 1.5
RADIUS = 0.5
TRUTH_RAYS = 64
#: method of the animated comparisons
ANIMATED = "gtao"
AO_KEYS = ("flicker", "flicker_accumulated", "ghosting", "ghosting_edges", "error_raw", "error_accumulated",
           "ghosting_moving", "ghosting_moving_camera_only")


def _error_curves(run: object, truth: list) -> tuple[list, list]:
    raw = [float((run.ao[t] - truth[t]).abs()[run.mask[t]].mean()) for t in range(len(truth))]
    acc = [float((run.accumulated[t] - truth[t]).abs()[run.mask[t]].mean()) for t in range(len(truth))]
    return raw, acc


def _plot(path: str, curves: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.5, 3.4), layout="constrained")
    for k, (m, (raw, acc)) in enumerate(curves.items()):
        c = f"C{k}"
        ax.plot(range(len(raw)), raw, ls="--", color=c, alpha=0.7)
        ax.plot(range(len(acc)), acc, ls="-", color=c, marker="o", ms=3, label=m)
    ax.set_xlabel("frame"), ax.set_ylabel("mean |AO − truth|")
    ax.set_title(f"{SCENE}, camera turning {ORBIT_DEG}° per frame: raw (dashed) vs accumulated (solid)", fontsize=10)
    ax.legend(fontsize=7, ncol=3)
    ax.grid(alpha=0.3)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _gif(path: str, run: object) -> None:
    from PIL import Image
    frames = []
    for t in range(run.ao.shape[0]):
        pair = np.concatenate([ao_rgb(run.ao[t], run.mask[t]), np.full((run.ao.shape[-2], 4, 3), 255, np.uint8),
                               ao_rgb(run.accumulated[t], run.mask[t])], 1)
        frames.append(Image.fromarray(pair))
    os.makedirs(os.path.dirname(path), exist_ok=True)
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=250, loop=0)


def build_time_section(run_dir: str, width: int = 128, height: int = 96, *, use_cache: bool = True,
                       progress: Optional[bool] = None) -> dict:
    """Run the time section into ``run_dir``; returns its metadata. Never raises: a failed method is a note."""
    from tqdm import tqdm
    from ..evaluate import ao_frames
    from ..passes import AO_METHODS
    from ..passes.temporal import AccumulationParams
    from ..scenes import load
    t0 = time.perf_counter()
    acc = AccumulationParams()
    rows, notes, curves, animated = [], [], {}, {}
    sc, sc_moving = load(SCENE), load(MOVING_SCENE)
    kw = dict(frames=FRAMES, width=width, height=height, radius=RADIUS, accumulation=acc, use_cache=use_cache)
    for m in tqdm(list(AO_METHODS), desc="time", unit="method", disable=None if progress is None else not progress):
        try:
            still = ao_frames(sc, m, **kw)
            turning = ao_frames(sc, m, orbit_deg=ORBIT_DEG, truth_rays=TRUTH_RAYS, **kw)
            curves[m] = _error_curves(turning, turning.truth)
            ball = {mv: ao_frames(sc_moving, m, truth_rays=TRUTH_RAYS, moving=MOVING, motion_vectors=mv, **kw)
                    for mv in (True, False)}
        except Exception as e:
            notes.append(f"{m}: {type(e).__name__}: {e}")
            continue
        rows.append({"kind": "time", "scene": SCENE, "method": m, "frames": FRAMES, "radius": RADIUS,
                     "width": width, "height": height, "orbit_deg": ORBIT_DEG, "alpha": acc.alpha, "clamp": acc.clamp,
                     "flicker": still.flicker, "flicker_accumulated": still.flicker_accumulated,
                     "ghosting": turning.ghosting, "ghosting_edges": turning.ghosting_edges,
                     "error_raw": float(np.mean(curves[m][0][1:])), "error_accumulated": float(np.mean(curves[m][1][1:])),
                     "moving_scene": MOVING_SCENE, "moving_shape": MOVING.shape, "moving_velocity": list(MOVING.velocity),
                     "ghosting_moving": ball[True].ghosting_moving,
                     "ghosting_moving_camera_only": ball[False].ghosting_moving})
        if m == ANIMATED:
            animated = {"": turning, "moving_": ball[True]}
    images = {}
    if curves:
        _plot(os.path.join(run_dir, "img", "time", "error.png"), curves)
        images["error"] = "img/time/error.png"
    for prefix, run in animated.items():
        _gif(os.path.join(run_dir, "img", "time", f"{prefix}{ANIMATED}.gif"), run)
        images[f"{prefix}animation"] = f"img/time/{prefix}{ANIMATED}.gif"
    table = [{**r, **{k: fmt(r[k], "{:.4f}") for k in AO_KEYS}} for r in rows]
    ssr = ssr_rows(width, height, FRAMES, acc, use_cache=use_cache, progress=progress)
    imp = implicit_rows(run_dir, max(8, width // 2), max(6, height // 2), use_cache=use_cache, progress=progress)
    if imp["image"]:
        images["txaa"] = imp["image"]
    glance = [{"method": r["method"], "headline": f"flicker {r['flicker']} → {r['flicker_accumulated']} "
                                                  f"accumulated; ghosting {r['ghosting']}",
               "seconds": "–", "scenes": 1} for r in table]
    return {"available": bool(rows), "note": "" if rows else "no AO method ran over frames",
            "notes": notes + ssr["notes"] + imp["notes"], "rows": rows + ssr["rows"] + imp["rows"], "table": table,
            "ssr": ssr, "implicit": imp,
            "moving": {"scene": MOVING_SCENE, "shape": MOVING.shape, "velocity": list(MOVING.velocity)},
            "images": images, "glance": glance, "scene": SCENE, "frames": FRAMES,
            "orbit_deg": ORBIT_DEG, "radius": RADIUS, "truth_rays": TRUTH_RAYS, "animated": ANIMATED,
            "resolve": {"alpha": acc.alpha, "clamp": acc.clamp, "depth_tolerance": acc.depth_tolerance},
            "size": f"{width}×{height}", "seconds": time.perf_counter() - t0, "threads": torch.get_num_threads()}


def summary_md(sec: dict) -> str:
    """The time part of ``summary.md``."""
    lines = ["", "## Time", ""]
    if not sec.get("available"):
        return unavailable_md(lines, sec, "Time")
    lines += [f"{sec['scene']}, {sec['size']}, {sec['frames']} frames, radius {sec['radius']}; accumulation "
              f"alpha {sec['resolve']['alpha']}, clamp {sec['resolve']['clamp']}; ghosting and error on a camera "
              f"turning {sec['orbit_deg']}° per frame against {sec['truth_rays']}-ray truth per frame.", "",
              f"Moving object: {sec['moving']['shape']} of {sec['moving']['scene']} moving "
              f"{sec['moving']['velocity']} per frame, ghosting within the band around it, with its motion vectors "
              "and by the camera alone.", "",
              "| method | flicker raw | flicker accumulated | ghosting | ghosting near edges | error raw | error accumulated "
              "| ghosting, moving object | camera only |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['method']} | " + " | ".join(r[k] for k in AO_KEYS) + " |" for r in sec["table"]]
    lines += ssr_summary_lines(sec["ssr"]) + implicit_summary_lines(sec["implicit"])
    return "\n".join(lines + [f"- {n}" for n in sec["notes"]]) + "\n"
