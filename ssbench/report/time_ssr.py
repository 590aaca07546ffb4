"""The time section's reflections: every SSR method (mirror and glossy) over frames, raw and temporally
accumulated (:func:`ssbench.evaluate.ssr_frames`).

On :data:`SCENE` (metal strips and spheres of roughness 0–0.5): ``flicker`` / ``flicker_accumulated`` of the
reflected luminance on a still, jittered camera (a new generator each frame: the stochastic glossy pass draws new
GGX directions); on a camera turning :data:`ORBIT_DEG` per frame, ``ghosting`` (over every trusted reflecting
pixel and near depth edges) against each frame's screen-space oracle (:data:`TRUTH_RAYS` lobe directions): the
reflection is reprojected with the floor's motion while what it shows moves with its own parallax, so history
lags. Rows (``rows/time.jsonl``, ``kind: "time_ssr"``): one per method.
"""
from __future__ import annotations

from typing import Optional

from .summary import fmt

SCENE = "glossy_ramp"
ORBIT_DEG = 1.5
TRUTH_RAYS = 16
KEYS = ("flicker", "flicker_accumulated", "ghosting", "ghosting_edges")


def ssr_rows(width: int, height: int, frames: int, accumulation, *, use_cache: bool = True,
             progress: Optional[bool] = None) -> dict:
    """``{"rows", "table", "notes"}`` of every SSR method; a method that fails is a note."""
    from tqdm import tqdm
    from ..evaluate import ssr_frames
    from ..passes import SSR_METHODS
    rows, notes = [], []
    kw = dict(frames=frames, width=width, height=height, accumulation=accumulation, use_cache=use_cache)
    for m in tqdm(list(SSR_METHODS), desc="time (SSR)", unit="method",
                  disable=None if progress is None else not progress):
        try:
            still = ssr_frames(SCENE, m, **kw)
            turning = ssr_frames(SCENE, m, orbit_deg=ORBIT_DEG, truth_rays=TRUTH_RAYS, **kw)
        except Exception as e:
            notes.append(f"{m} (SSR): {type(e).__name__}: {e}")
            continue
        rows.append({"kind": "time_ssr", "scene": SCENE, "method": m, "frames": frames, "width": width,
                     "height": height, "orbit_deg": ORBIT_DEG, "truth_rays": TRUTH_RAYS,
                     "flicker": still.flicker, "flicker_accumulated": still.flicker_accumulated,
                     "ghosting": turning.ghosting, "ghosting_edges": turning.ghosting_edges})
    table = [{**r, **{k: fmt(r[k], "{:.4f}") for k in KEYS}} for r in rows]
    return {"rows": rows, "table": table, "notes": notes, "scene": SCENE, "orbit_deg": ORBIT_DEG,
            "truth_rays": TRUTH_RAYS}


def summary_lines(ssr: dict) -> list:
    """The reflections table of the time part of ``summary.md``."""
    if not ssr["table"]:
        return []
    lines = ["", f"Reflections on {ssr['scene']}: flicker of the reflected luminance on a still camera; ghosting "
                 f"on a camera turning {ssr['orbit_deg']}° per frame against the {ssr['truth_rays']}-ray "
                 "screen-space oracle.", "",
             "| SSR method | flicker raw | flicker accumulated | ghosting | ghosting near edges |",
             "|---|---:|---:|---:|---:|"]
    return lines + [f"| {r['method']} | " + " | ".join(r[k] for k in KEYS) + " |" for r in ssr["table"]]
