"""SSR article Fig. 11 in the report: which depth texels *one* ray reads, per marcher, against the pixels it crosses.

For one reflective pixel the linear view-space march (``ssr_linear(..., trace_pixel=)``), the DDA at stride 1
and the supercover DDA (:func:`ssbench.passes.ssr.visits.visit_map`) march the same mirror ray over the real
depth buffer. :func:`one_ray` counts, per marcher, the reads, the distinct pixels read, the pixels read more than
once (oversampling) and the pixels the segment crosses before the march stopped that it never read (skipped),
with :func:`~ssbench.passes.ssr.visits.crossed_pixels` as the independent yardstick; :func:`plot` draws them.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np
import torch

#: marchers of the figure: (label, SSR method)
MARCHERS = (("linear march, the DDA's reads", "linear"), ("DDA (stride 1)", "dda"),
            ("supercover DDA", "dda_supercover"))


def pick_pixel(g, result) -> Optional[tuple[int, int]]:
    """A reflective pixel in the lower third whose ray (``result``: the DDA at defaults) hits after the longest
    diagonal run (largest ``min(|Δx|, |Δy|)`` in pixels, so it crosses both rows and columns), ``(x, y)``;
    ``None`` if no ray hits."""
    from ..passes.ssr.common import HIT
    H = g.height
    hit = (result.termination[0, 0] == HIT) & g.mask[0, 0]
    if g.metallic is not None:
        hit &= g.metallic[0, 0] >= 0.5
    rows = torch.arange(H)[:, None].expand_as(hit)
    hit &= rows >= (2 * H) // 3
    if not bool(hit.any()):
        return None
    cols = torch.arange(g.width)[None, :].expand_as(hit)
    run = torch.minimum((rows + 0.5 - result.hit_pixel[0, 1]).abs(), (cols + 0.5 - result.hit_pixel[0, 0]).abs())
    y, x = divmod(int(torch.where(hit, run, -math.inf).flatten().argmax()), g.width)
    return x, y


def _stats(visits: torch.Tensor, crossed: torch.Tensor, origin) -> dict:
    crossed = crossed.clone()
    crossed[origin[1], origin[0]] = False
    return {"reads": int(visits.sum()), "pixels": int((visits > 0).sum()), "twice": int((visits > 1).sum()),
            "skipped": int((crossed & (visits == 0)).sum()), "outside": int(((visits > 0) & ~crossed).sum())}


def one_ray(g, pixel: tuple[int, int], results: Optional[dict] = None) -> list[dict]:
    """Per marcher (:data:`MARCHERS`): ``label, visits (H, W), crossed (H, W)`` (the pixels the ray's screen
    segment crosses from its origin to where this march stopped: its hit or ``P1``) and the counts of
    :func:`_stats` (``reads, pixels, twice, skipped, outside``). The DDAs run at their defaults; the linear march
    gets the DDA's number of reads as equal view-space steps up to the DDA's hit (``iterations`` scaled to match),
    so the picture compares where equal budgets land. ``results``: method → the pass's :class:`SSRResult` over the
    whole image at those parameters, when already computed (the hit ends the segment)."""
    import dataclasses

    from ..passes import ssr_method
    from ..passes.ssr.linear import LinearSSRParams, ssr_linear
    from ..passes.ssr.visits import crossed_pixels, visit_map
    x, y = pixel
    H, W = g.height, g.width
    out = {}
    for label, method in MARCHERS[1:]:
        fn, params_cls, _ = ssr_method(method)
        params = params_cls()                                            # the method's declared defaults
        m = visit_map(g, params, (x, y))
        res = (results or {}).get(method) or fn(g, params)
        hit = bool(res.hit[0, 0, y, x])
        end = res.hit_pixel[0, :, y, x].tolist() if hit else m["p1"]
        out[method] = {"label": label, "method": method, "visits": m["visits"], "p0": m["p0"], "end": end,
                       "reach": float((res.hit_view[0, :, y, x] - g.position[0, :, y, x]).norm()) if hit else None}
    dda, lin = out["dda"], LinearSSRParams()
    reads = max(1, int(dda["visits"].sum()))
    if dda["reach"]:                                      # equal steps of reach / reads view units
        n = max(1, math.ceil(lin.max_ray_distance * reads / dda["reach"]))
        lin = LinearSSRParams(iterations=n, max_iterations=max(n, lin.max_iterations))
    one = torch.zeros_like(g.mask)
    one[0, 0, y, x] = True                  # the linear march reads mask only to pick its rays: march just this one
    tr = ssr_linear(dataclasses.replace(g, mask=one), lin, trace_pixel=(x, y)).debug["trace"][0]
    pts = tr["pixel"][~tr["refine"]]                                              # the march, not the refinement
    visits = torch.zeros(H, W, dtype=torch.int32)
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < W) & (pts[:, 1] >= 0) & (pts[:, 1] < H)
    c, r = pts[inside, 0].floor().long(), pts[inside, 1].floor().long()
    visits.index_put_((r, c), torch.ones_like(c, dtype=torch.int32), accumulate=True)
    out["linear"] = {"label": MARCHERS[0][0], "method": "linear", "visits": visits, "p0": [x + 0.5, y + 0.5],
                     "end": pts[-1].tolist() if len(pts) else [x + 0.5, y + 0.5], "iterations": lin.iterations}
    rays = [out[m] for _, m in MARCHERS]
    for ray in rays:
        ray["crossed"] = crossed_pixels(ray["p0"], ray["end"], H, W)
        ray.update(_stats(ray["visits"], ray["crossed"], (x, y)))
    return rays


def _window(centre, H: int, W: int, size: int) -> tuple[int, int, int, int]:
    """``(r0, r1, c0, c1)``: a ``size``-pixel square around ``centre = (x, y)``, shifted to lie in the image."""
    c0 = min(max(0, int(centre[0]) - size // 2), max(0, W - size))
    r0 = min(max(0, int(centre[1]) - size // 2), max(0, H - size))
    return r0, min(H, r0 + size), c0, min(W, c0 + size)


def plot(path: str, rays: list[dict], pixel: tuple[int, int], size: int = 24) -> None:
    """Two crops per marcher, ``size`` pixels square: where the ray starts (top row) and where it ends (bottom
    row). Green read once, red read more than once, grey crossed but never read, the segment in blue. Saved
    atomically as PNG."""
    from matplotlib.figure import Figure

    from .implicit_section import save_fig
    H, W = rays[0]["visits"].shape
    p0, p1 = rays[1]["p0"], rays[1]["end"]                                        # the DDA's segment
    length = max(1e-9, math.hypot(p1[0] - p0[0], p1[1] - p0[1]))
    u = ((p1[0] - p0[0]) / length, (p1[1] - p0[1]) / length)
    half = min(size / 2 - 2, length / 2)
    spots = [("start", (p0[0] + u[0] * half, p0[1] + u[1] * half)), ("end", (p1[0] - u[0] * half, p1[1] - u[1] * half))]
    fig = Figure(figsize=(3.0 * len(rays), 6.8))                                 # (constrained layout: 2x slower)
    axes = fig.subplots(2, len(rays), squeeze=False)
    fig.subplots_adjust(left=0.06, right=0.99, bottom=0.04, top=0.84, wspace=0.25, hspace=0.12)
    for j, r in enumerate(rays):
        img = np.ones((H, W, 3))
        img[r["crossed"].numpy()] = (0.75, 0.75, 0.75)                            # crossed, not read
        img[(r["visits"] == 1).numpy()] = (0.2, 0.65, 0.2)                        # read once
        img[(r["visits"] > 1).numpy()] = (0.85, 0.1, 0.1)                         # read several times
        for i, (where, centre) in enumerate(spots):
            ax = axes[i, j]
            r0, r1, c0, c1 = _window(centre, H, W, size)
            ax.imshow(img[r0:r1, c0:c1], interpolation="nearest", extent=(c0, c1, r1, r0))
            ax.plot([r["p0"][0], r["end"][0]], [r["p0"][1], r["end"][1]], "-", color="#1f4fbf", lw=0.8)
            ax.set_xlim(c0, c1), ax.set_ylim(r1, r0)
            ax.tick_params(labelsize=6)
            if i == 0:
                ax.set_title(f"{r['label']}\n{r['reads']} reads, {r['pixels']} pixels, {r['twice']} read twice+,\n"
                             f"{r['skipped']} crossed but skipped", fontsize=8)
            if j == 0:
                ax.set_ylabel(f"near the {where}", fontsize=8)
    fig.suptitle(f"One ray from pixel {pixel} (SSR article Fig. 11): green once, red twice or more, grey skipped",
                 fontsize=9)
    save_fig(fig, path)
