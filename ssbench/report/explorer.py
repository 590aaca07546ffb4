"""The sweep explorer: one static page per effect of the speed section (``explore_<effect>.html`` beside
``index.html``) where a person picks a scene and a method, moves one slider per parameter the sweeps varied, and
sees that configuration's image and error map (the PNGs the sweeps wrote with ``images: true``,
:mod:`ssbench.bench.pictures`), its row's numbers, and its point ringed on the error–time plot of every
configuration of the scene.

:func:`explorer_data` turns the pooled rows into the page's data (stored in the section's metadata, so
``ssbench report --from`` re-renders the pages without computing); :func:`write_pages` renders them. The page is
plain HTML with its data inline and a small script (``templates/explore.js.j2``); nothing runs server-side and
nothing is fetched from the network. A slider position with no configuration of its own shows the nearest one
(most knobs equal, the moved one first) and says so.
"""
from __future__ import annotations

import json
import math
import os
from typing import Optional

__all__ = ["knobs", "explorer_data", "write_pages", "DEFAULT"]

#: a parameter a configuration does not set (its method's default)
DEFAULT = "default"
#: settings that never make a knob (bookkeeping, not a choice that changes the image)
_NOT_KNOBS = ("threads", "repeats")


def _text(v) -> str:
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v, sort_keys=True)
    return str(v)


def _choices(row: dict) -> dict:
    """What a configuration chose: its parameters as given, its settings, size and seed."""
    c = row.get("config") or {}
    out = dict(c.get("params") or {})
    out.update({k: v for k, v in (c.get("settings") or {}).items() if k not in _NOT_KNOBS})
    out["size"] = f"{row.get('width')}×{row.get('height')}"
    out["seed"] = row.get("seed")
    return out


def knobs(rows: list) -> list[dict]:
    """``[{"name", "values"}]``: the choices that differ among ``rows`` (one scene and method), each with its
    values as text — numbers ascending, :data:`DEFAULT` first for a parameter some rows leave unset, other
    values in order of appearance.

    Example:
        >>> rows = [{"config": {"params": {"k": 8}}}, {"config": {"params": {"k": 32}}},
        ...         {"config": {"params": {"k": 16, "blur": "box"}}}]
        >>> knobs(rows)
        [{'name': 'k', 'values': ['8', '16', '32']}, {'name': 'blur', 'values': ['default', 'box']}]
    """
    chosen = [_choices(r) for r in rows]
    out = []
    for name in dict.fromkeys(k for c in chosen for k in c):
        raw = [c.get(name, DEFAULT) for c in chosen]
        texts = list(dict.fromkeys(_text(v) for v in raw))
        if len(texts) < 2:
            continue
        nums = {_text(v): v for v in raw if isinstance(v, (int, float)) and not isinstance(v, bool)}
        if len(nums) == len(texts) - (DEFAULT in texts):            # numbers (and perhaps unset): ascending
            texts = [DEFAULT] * (DEFAULT in texts) + sorted(nums, key=nums.get)
        elif DEFAULT in texts:
            texts = [DEFAULT] + [t for t in texts if t != DEFAULT]
        out.append({"name": name, "values": texts})
    return out


def _finite(x) -> Optional[float]:
    return float(x) if isinstance(x, (int, float)) and math.isfinite(x) else None


def explorer_data(effect: str, title: str, rows: list, metrics: list, fronts: dict, colorbar: Optional[str],
                  pictures) -> dict:
    """The explorer page's data for one effect.

    Args:
        rows: the pooled sweep rows; ``images`` paths relative to the report folder.
        metrics: ``[(row key, label), ...]``, the first one plotted against time.
        fronts: ``{(scene, metric key): [rows on the Pareto front]}`` (:func:`ssbench.analysis.figures.error_time_figure`).
        colorbar: the error map's colour bar PNG (relative to the report folder), or ``None``.
        pictures: the effect's :class:`ssbench.bench.pictures.Pictures` (captions, class-map legend), or ``None``.
    """
    from ..analysis.pareto import row_time_ms, row_value
    from ..passes import title as method_title
    from .ao_section import fmt
    primary = metrics[0][0]
    on_front = {(s, r["config_id"]) for (s, m), pts in fronts.items() if m == primary for r in pts}
    ok = [r for r in rows if not r.get("error")]
    groups: dict = {}
    for r in ok:
        groups.setdefault(f"{r['scene']}|{r['method']}", []).append(r)
    group_knobs = {g: knobs(rs) for g, rs in groups.items()}                      # once per scene and method
    points = []
    for r in ok:
        pics = r.get("images") or {}
        t = row_time_ms(r)
        numbers = [["time per call", fmt(t, "{:.3g}") + " ms"], ["× torch floor", fmt(r.get("floor_ratio"), "{:.1f}")],
                   ["× fused floor", fmt(r.get("fused_floor_ratio"), "{:.1f}")]]
        numbers += [[label, fmt(row_value(r, key), "{:.4g}")] for key, label in metrics]
        ch = _choices(r)
        points.append({"id": r["config_id"], "scene": r["scene"], "method": r["method"],
                       "knobs": {k["name"]: _text(ch.get(k["name"], DEFAULT))
                                 for k in group_knobs[f"{r['scene']}|{r['method']}"]},
                       "x": _finite(t), "y": _finite(row_value(r, primary)),
                       "front": (r["scene"], r["config_id"]) in on_front,
                       "image": pics.get("image"), "error_image": pics.get("error"), "numbers": numbers})
    classes = None
    if pictures is not None and pictures.classes == "implicit":
        from .implicit_section import class_legend
        classes = class_legend()
    return {"effect": effect, "title": title, "page": f"explore_{effect}.html", "metric": metrics[0][1],
            "scenes": list(dict.fromkeys(r["scene"] for r in ok)),
            "methods": [{"name": m, "title": method_title(m)} for m in dict.fromkeys(r["method"] for r in ok)],
            "groups": {g: {"knobs": ks} for g, ks in group_knobs.items()}, "points": points,
            "image_caption": getattr(pictures, "image", ""), "error_caption": getattr(pictures, "error", ""),
            "colorbar": colorbar, "classes": classes, "failed": len(rows) - len(ok),
            "without_images": sum(not p["image"] for p in points)}


def write_pages(run_dir: str, speed: dict, tpl_env, meta: dict) -> list[str]:
    """Render ``explore_<effect>.html`` for every speed effect that carries explorer data; returns their names.
    A page that fails to render is left out and the failure noted in the effect's ``notes``."""
    from .render import write_text
    out = []
    for e in speed.get("effects", []) if speed.get("available") else []:
        data = e.get("explorer")
        if not e.get("available") or not data:
            continue
        try:
            html = tpl_env.get_template("explore.html.j2").render(data=data, meta=meta)
            write_text(os.path.join(run_dir, data["page"]), html)
            out.append(data["page"])
        except Exception as err:                              # noqa: BLE001 - the report must not crash
            e.setdefault("notes", []).append(f"sweep explorer not written: {type(err).__name__}: {err}")
            data["page"] = None
    return out
