"""Colour bars for the report's false-colour maps: a small labelled PNG per scale, written once per section,
so an error map can be read without opening the legend text."""
from __future__ import annotations


def colorbar_png(path: str, cmap: str, vmin: float, vmax: float, label: str, *, low: str = "", high: str = "",
                 dpi: int = 100) -> str:
    """Write a horizontal colour bar of ``cmap`` over ``[vmin, vmax]`` (ticks at both ends and the middle), with
    ``label`` below and optional words at the ``low`` / ``high`` ends; returns ``path``.

    Example:
        >>> import os, tempfile, matplotlib.image as mimage
        >>> p = colorbar_png(os.path.join(tempfile.mkdtemp(), "bar.png"), "RdBu", -0.5, 0.5, "AO − GT")
        >>> mimage.imread(p).shape[1] > 3 * mimage.imread(p).shape[0]       # wide and flat
        True
    """
    import matplotlib
    import matplotlib.pyplot as plt
    from ..io import save_figure
    fig, ax = plt.subplots(figsize=(3.4, 0.85))                  # room below the bar for ticks and the label
    fig.subplots_adjust(left=0.06, right=0.94, bottom=0.62, top=0.94)
    norm = matplotlib.colors.Normalize(vmin=vmin, vmax=vmax)
    bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), cax=ax, orientation="horizontal")
    bar.set_ticks([vmin, 0.5 * (vmin + vmax), vmax])
    bar.ax.tick_params(labelsize=8)
    text = f"{low} ← {label} → {high}" if (low or high) else label
    bar.set_label(text, fontsize=8)
    try:
        return save_figure(fig, path, dpi=dpi)
    finally:
        plt.close(fig)
