"""Artifact-vs-parameter small multiples from sweep rows: one panel per (method, parameter), one line per value
of the other parameters that vary (and per scene).

A :class:`Panel` names the method, the parameter on the x axis and the metric on the y axis. The parameter is
looked up in the row's resolved ``params`` first, then in the row itself (a setting such as ``blur``, or
``floor_samples``: the texel reads per pixel the timing recorded, a sample count common to every AO method);
``"frame"`` plots a per-frame list metric (e.g. ``punch_through_per_frame``) against the frame number. Lines
are keyed by the scene and the *other* varying keys (the config's parameter overrides and settings that take
more than one value among the method's rows, minus the panel's ``over`` keys, which determine x). With more
than ``max_lines`` lines a panel shows, per scene, the median over the other configurations at each x with a
min–max band (said in the legend). Non-numeric x values (names, ``None``, booleans) are categories, in order
of first appearance.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from .pareto import row_value, usable

__all__ = ["Panel", "x_value", "varying_keys", "config_text", "panel_lines", "small_multiples"]


@dataclasses.dataclass(frozen=True)
class Panel:
    """One small multiple: ``metric`` (a row key, or a tuple of them) of ``method``'s rows against ``param``.

    ``fix``: ``(key, value)`` pairs a row must match (resolved parameters or row fields, e.g.
    ``(("blur", None),)``); ``over``: keys that x depends on. Both are left out of the line keys. Labels default
    to the keys.
    """

    method: str
    param: str
    metric: Union[str, tuple]
    fix: tuple = ()
    over: tuple = ()
    xlabel: str = ""
    ylabel: str = ""

    @property
    def title(self) -> str:
        metric = self.metric if isinstance(self.metric, str) else " / ".join(self.metric)
        return f"{self.method}: {self.ylabel or metric} vs {self.xlabel or self.param}"


def x_value(row: Mapping, key: str) -> Any:
    """``row["params"][key]`` when the method has that parameter, else ``row[key]`` (settings, row fields)."""
    params = row.get("params") or {}
    return params[key] if key in params else row.get(key)


def _config_keys(row: Mapping) -> dict:
    cfg = row.get("config") or {}
    out = {k: x_value(row, k) for k in (cfg.get("params") or {})}
    out.update({k: row.get(k, v) for k, v in (cfg.get("settings") or {}).items()})
    return out


def _hashable(v: Any) -> Any:
    return repr(v) if isinstance(v, (list, dict)) else v


def varying_keys(rows: Iterable[Mapping]) -> list[str]:
    """Parameter overrides and settings (from each row's ``config``) with more than one value among ``rows``,
    in first-seen order.

    Example:
        >>> rows = [{"params": {"k": 8, "r": 1.0}, "config": {"params": {"k": 8}, "settings": {"blur": None}}},
        ...         {"params": {"k": 16, "r": 1.0}, "config": {"params": {"k": 16}, "settings": {"blur": "box"}}}]
        >>> varying_keys(rows)
        ['k', 'blur']
    """
    seen: dict[str, set] = {}
    for r in rows:
        for k, v in _config_keys(r).items():
            seen.setdefault(k, set()).add(_hashable(v))
    return [k for k, vals in seen.items() if len(vals) > 1]


def _fmt(v: Any) -> str:
    if v is None:
        return "none"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def config_text(row: Mapping, keys: Optional[Sequence[str]] = None) -> str:
    """``"k=8, blur=box"``: the row's values of ``keys`` (default: its config's parameter overrides).

    Example:
        >>> config_text({"params": {"k": 8}, "blur": None, "config": {"params": {"k": 8}}}, ["k", "blur"])
        'k=8, blur=none'
    """
    if keys is None:
        keys = list(((row.get("config") or {}).get("params") or {}))
    return ", ".join(f"{k}={_fmt(x_value(row, k))}" for k in keys) or "defaults"


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def _metrics(panel: Panel) -> tuple:
    return (panel.metric,) if isinstance(panel.metric, str) else tuple(panel.metric)


def panel_lines(rows: Iterable[Mapping], panel: Panel, *, max_lines: int = 8) -> dict:
    """The data of one panel: ``{"panel", "categories" (None for numeric x), "lines": [{"label", "x", "y",
    "lo", "hi"}], "points"}``; ``x`` are numbers (category indices for categorical x), sorted; ``lo``/``hi`` are
    the band of an aggregated line (else ``None``); ``points`` counts the (x, y) pairs behind the lines.
    ``panel.metric`` may be a tuple of metrics: one set of lines per metric, labelled with it."""
    mine = [r for r in rows if usable(r) and r.get("method") == panel.method
            and all(x_value(r, k) == v for k, v in panel.fix)]
    skip = {panel.param, *panel.over, *(k for k, _ in panel.fix)}
    others = [k for k in varying_keys(mine) if k not in skip]
    metrics = _metrics(panel)
    raw: dict[tuple, list] = {}
    for metric in metrics:
        for r in mine:
            key = (metric, r.get("scene")) + tuple(_hashable(x_value(r, k)) for k in others)
            if panel.param == "frame":
                pts = [(i + 1, float(y)) for i, y in enumerate(r.get(metric) or []) if y is not None]
            else:
                pts = [(x_value(r, panel.param), row_value(r, metric))]
            raw.setdefault(key, []).extend((x, y) for x, y in pts if not (isinstance(y, float) and math.isnan(y)))
    xs_all = [x for pts in raw.values() for x, _ in pts]
    categories = None if all(_is_num(x) for x in xs_all) else list(dict.fromkeys(_fmt(x) for x in xs_all))
    conv = (lambda x: float(x)) if categories is None else (lambda x: float(categories.index(_fmt(x))))
    name = (lambda m: f"{m.removeprefix('frac_')} · ") if len(metrics) > 1 else (lambda m: "")   # noqa: E731
    lines = []
    if len(raw) <= max_lines * len(metrics):
        for key, pts in raw.items():
            if pts:
                pts = sorted((conv(x), y) for x, y in pts)
                label = name(key[0]) + ", ".join([str(key[1])] + [f"{k}={_fmt(v)}" for k, v in zip(others, key[2:])])
                lines.append({"label": label, "x": [p[0] for p in pts], "y": [p[1] for p in pts], "lo": None,
                              "hi": None})
    else:
        for group in dict.fromkeys(k[:2] for k in raw):
            by_x: dict[float, list] = {}
            mates = [k for k in raw if k[:2] == group]
            for key in mates:
                for x, y in raw[key]:
                    by_x.setdefault(conv(x), []).append(y)
            xs = sorted(by_x)
            if xs:
                lines.append({"label": f"{name(group[0])}{group[1]} (median of {len(mates)} configs, band min–max)",
                              "x": xs, "y": [float(np.median(by_x[x])) for x in xs],
                              "lo": [min(by_x[x]) for x in xs], "hi": [max(by_x[x]) for x in xs]})
    return {"panel": panel, "categories": categories, "lines": lines, "points": sum(map(len, raw.values()))}


def small_multiples(rows: Sequence[Mapping], panels: Sequence[Panel], path: Optional[str] = None, *,
                    ncols: int = 3, max_lines: int = 8, title: str = "") -> list[dict]:
    """Draw ``panels`` (:func:`panel_lines` of each) as a grid of small multiples into the PNG ``path``
    (``None``: compute only); returns the panels' data. A panel with no rows says so."""
    if isinstance(ncols, bool) or not isinstance(ncols, int) or ncols < 1:
        raise ValueError(f"ncols: must be an integer >= 1, got {ncols!r}")
    data = [panel_lines(rows, p, max_lines=max_lines) for p in panels]
    if path is None or not data:
        return data
    import textwrap

    from matplotlib import colormaps
    from matplotlib.figure import Figure
    nc = min(ncols, len(data))
    nr = math.ceil(len(data) / nc)
    labels = list(dict.fromkeys(ln["label"] for d in data for ln in d["lines"]))
    palette = colormaps["tab10" if len(labels) <= 10 else "tab20"].colors
    colour = {lab: palette[i % len(palette)] for i, lab in enumerate(labels)}   # one colour per line, everywhere
    shared = len(data) > 1 and len(labels) <= 20      # one legend under the grid instead of one over each panel
    leg_rows = math.ceil(len(labels) / 4) if shared else 0
    h = 2.9 * nr + (0.4 if title else 0) + 0.22 * leg_rows
    fig = Figure(figsize=(3.6 * nc, h))                        # a fixed layout: constrained layout costs seconds
    fig.subplots_adjust(left=0.22 / nc + 0.03, right=0.985, bottom=(0.55 + 0.22 * leg_rows) / h,
                        top=1 - (0.8 if title else 0.45) / h, wspace=0.38, hspace=0.7)
    axes = np.atleast_1d(fig.subplots(nr, nc, squeeze=False)).reshape(-1)
    for ax, d in zip(axes, data):
        p = d["panel"]
        ax.set_title("\n".join(textwrap.wrap(p.title, 44)), fontsize=9)
        ax.set_xlabel(p.xlabel or p.param, fontsize=9)
        ax.set_ylabel(p.ylabel or " / ".join(_metrics(p)), fontsize=9)
        ax.tick_params(labelsize=8)
        if not d["lines"]:
            ax.text(0.5, 0.5, "no rows", ha="center", va="center", transform=ax.transAxes, color="grey")
            continue
        for ln in d["lines"]:
            style = "o-" if len(ln["x"]) > 1 else "o"
            ax.plot(ln["x"], ln["y"], style, ms=3, lw=1.2, label=ln["label"], color=colour[ln["label"]])
            if ln["lo"] is not None:
                ax.fill_between(ln["x"], ln["lo"], ln["hi"], color=colour[ln["label"]], alpha=0.15, lw=0)
        if d["categories"] is not None:
            ax.set_xticks(range(len(d["categories"])), d["categories"], fontsize=7)
        else:
            xs = [x for ln in d["lines"] for x in ln["x"]]
            if p.param != "frame" and min(xs) > 0 and max(xs) / min(xs) >= 8:
                ax.set_xscale("log", base=2)
        if not shared:
            ax.legend(fontsize=7, loc="best", framealpha=0.7)
    for ax in axes[len(data):]:
        ax.set_axis_off()
    if shared and labels:
        from matplotlib.lines import Line2D
        handles = [Line2D([], [], color=colour[lab], marker="o", ms=3, lw=1.2) for lab in labels]
        fig.legend(handles, labels, loc="lower center", ncol=min(4, len(labels)), fontsize=8, frameon=False,
                   bbox_to_anchor=(0.5, 0.005))
    if title:
        fig.suptitle(title, fontsize=11)
    from ..io import save_figure
    save_figure(fig, path, dpi=90)
    return data
