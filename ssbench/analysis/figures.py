"""Error against time: every configuration of a sweep a point, the Pareto front drawn as a step line.

:func:`error_time_figure` draws a grid of panels (one row per scene, one column per error metric), time on a
log axis, each method in its own colour, front points ringed in black and joined by the front's staircase
(``where="post"``: the boundary of the region the front dominates). A ground-truth :class:`~.equal_error.Ladder`
can be drawn on the panels of its metric (grey, each point labelled with its n), so the screen-space points
sit beside what the same error costs with the ground truth. It returns the fronts it drew, for tables.
"""
from __future__ import annotations

import math
from typing import Callable, Mapping, Optional, Sequence, Union

import numpy as np

from .pareto import pareto_rows, row_time_ms, row_value, usable

__all__ = ["error_time_figure", "method_colors"]


def method_colors(methods: Sequence[str]) -> dict:
    """A fixed colour per method name (matplotlib's ``tab10`` in the given order)."""
    import matplotlib
    cmap = matplotlib.colormaps["tab10"]
    return {m: cmap(i % 10) for i, m in enumerate(dict.fromkeys(methods))}


def _log_x(ax) -> None:
    """Log time axis with plain major labels (1, 2, 5 × 10^k) and unlabelled minor ticks (cheap to lay out)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def error_time_figure(rows: Sequence[Mapping], metrics: Sequence[tuple], path: Optional[str] = None, *,
                      scenes: Optional[Sequence[str]] = None, time: Union[str, Callable] = row_time_ms,
                      ladders: Optional[Mapping] = None, ladder_metric: Optional[str] = None,
                      time_label: str = "time per call, ms (log)", title: str = "") -> dict:
    """Error-vs-time panels of ``rows``; returns ``{(scene, metric): front rows sorted by time}``.

    Args:
        rows: sweep rows; error rows and rows with a NaN coordinate are left out.
        metrics: ``(row key, label)`` per column.
        path: PNG to write (``None``: compute the fronts only).
        scenes: rows of the figure (default: the rows' scenes in order).
        time: a row key or function (default :func:`~ssbench.analysis.pareto.row_time_ms`).
        ladders: ``{scene: Ladder}`` drawn on the ``ladder_metric`` column (its seconds as ms).
    """
    rows = [r for r in rows if usable(r)]
    scenes = list(scenes) if scenes is not None else list(dict.fromkeys(r.get("scene") for r in rows))
    fronts = {}
    for s in scenes:
        for key, _ in metrics:
            fronts[(s, key)] = pareto_rows(rows, key, time, where=lambda r, s=s: r.get("scene") == s)[0]
    if path is None or not scenes or not metrics:
        return fronts
    from matplotlib.figure import Figure
    colors = method_colors([r.get("method") for r in rows])
    nr, nc = len(scenes), len(metrics)
    h = 2.9 * nr + (0.4 if title else 0)
    fig = Figure(figsize=(3.6 * nc, h))                        # a fixed layout: constrained layout costs seconds
    fig.subplots_adjust(left=0.25 / nc + 0.02, right=0.99, bottom=0.5 / h, top=1 - (0.75 if title else 0.35) / h,
                        wspace=0.3, hspace=0.5)
    axes = fig.subplots(nr, nc, squeeze=False)
    for i, s in enumerate(scenes):
        mine = [r for r in rows if r.get("scene") == s]
        for j, (key, label) in enumerate(metrics):
            ax = axes[i, j]
            ax.set_title(f"{s}: {label}", fontsize=8)
            ax.tick_params(labelsize=7)
            for m, c in colors.items():
                pts = np.array([(row_value(r, time), row_value(r, key)) for r in mine if r.get("method") == m],
                               dtype=float).reshape(-1, 2)
                pts = pts[np.isfinite(pts).all(1)]
                if len(pts):
                    ax.scatter(pts[:, 0], pts[:, 1], s=14, color=c, alpha=0.75, lw=0, label=m)
            front = fronts[(s, key)]
            if front:
                ft = [row_value(r, time) for r in front]
                fe = [row_value(r, key) for r in front]
                ax.step(ft, fe, where="post", color="k", lw=0.9, label="Pareto front")
                ax.scatter(ft, fe, s=30, facecolors="none", edgecolors="k", lw=0.9)
            lad = (ladders or {}).get(s)
            if lad is not None and key == ladder_metric:
                lt, le = np.asarray(lad.seconds, float) * 1e3, np.asarray(lad.errors, float)
                ax.plot(lt, le, "x--", color="grey", ms=4, lw=0.8, label=f"{lad.label} (n {lad.kind})")
                for n, x, y in zip(lad.ns, lt, le):
                    if math.isfinite(x) and math.isfinite(y):
                        ax.annotate(str(n), (x, y), fontsize=6, color="grey", xytext=(2, 2),
                                    textcoords="offset points")
            if ax.has_data():
                _log_x(ax)
            ax.set_xlabel(time_label, fontsize=8)
            ax.set_ylabel(label, fontsize=8)
            if i == 0 and j == 0 or (lad is not None and key == ladder_metric and i == 0):
                ax.legend(fontsize=6, loc="best")
    if title:
        fig.suptitle(title, fontsize=10)
    from ..io import save_figure
    save_figure(fig, path, dpi=90)
    return fronts
