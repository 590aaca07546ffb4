"""The report's "Glossy reflections" section: every SSR method on rough surfaces against the path-traced lobe.

On :data:`SCENE` (a metal floor in strips of rising roughness and metal spheres likewise), every method of
:data:`ssbench.passes.SSR_METHODS` runs at its defaults through :func:`ssbench.evaluate.run_glossy` against one
glossy truth (:func:`ssbench.reference.glossy.glossy_reflections`, :data:`TRUTH_RAYS` directions per pixel): the
mirror marchers are the baseline the glossy methods (``GLOSSY = True`` beside their code) must beat. Files:
``img/glossy/error.png`` (mean |error| per roughness bin, against the oracle — the marcher and its filter — and
against the lobe — everything — with the information loss and the truth's standard error drawn),
``img/glossy/speed.png`` (time against error), and ``img/glossy/<name>.png`` (the truth's lobe and oracle, each
glossy method's reflection). Rows (``rows/glossy.jsonl``): one per method.
"""
from __future__ import annotations

import os
import time
from typing import Optional

import torch

from ..pictures import color_rgb
from .summary import fmt, unavailable_md

SCENE = "glossy_ramp"
TRUTH_RAYS = 64
SPP = 16


def _curves(path: str, rows: list[dict], glossy: set) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained", sharey=True)
    mids = [0.5 * (b["lo"] + b["hi"]) for b in rows[0]["bins"]]
    for ax, key, title in ((axes[0], "mae_vs_oracle", "against the oracle: marcher and filter"),
                           (axes[1], "mae_lobe", "against the lobe: everything")):
        for k, r in enumerate(rows):
            ys = [b[key] for b in r["bins"]]
            ax.plot(mids, ys, marker="o", ms=3, lw=2.0 if r["method"] in glossy else 1.0,
                    ls="-" if r["method"] in glossy else "--", color=f"C{k}", label=r["method"])
        se = [b["truth_se_mean"] for b in rows[0]["bins"]]
        ax.fill_between(mids, 0, se, color="0.8", label="truth's standard error")
        if key == "mae_lobe":
            ax.plot(mids, [b["mae_oracle"] for b in rows[0]["bins"]], color="k", lw=1, ls=":",
                    label="information loss (oracle vs lobe)")
        ax.set_xlabel("roughness"), ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("mean |reflection − truth|")
    axes[1].legend(fontsize=7)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _speed(path: str, rows: list[dict], glossy: set) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.5, 3.6), layout="constrained")
    for k, r in enumerate(rows):
        ax.scatter([r["seconds"] * 1e3], [r["mae_lobe"]], color=f"C{k}", marker="o" if r["method"] in glossy else "s")
        ax.annotate(r["method"], (r["seconds"] * 1e3, r["mae_lobe"]), fontsize=7, xytext=(3, 3),
                    textcoords="offset points")
    ax.set_xscale("log"), ax.set_xlabel("time per frame, ms (one call)"), ax.set_ylabel("mean |reflection − lobe|")
    ax.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def build_glossy_section(run_dir: str, width: int = 160, height: int = 120, *, seed: int = 0, use_cache: bool = True,
                         progress: Optional[bool] = None) -> dict:
    """Run the glossy section into ``run_dir``; returns its metadata. Never raises for one method: a note."""
    from PIL import Image
    from tqdm import tqdm

    from ..evaluate import run_glossy
    from ..passes import SSR_METHODS, declared, ssr_method
    t0 = time.perf_counter()
    rows, notes, images = [], [], {}
    g = truth = None
    glossy = {m for m in SSR_METHODS if declared(ssr_method(m)[0], "GLOSSY", False)}
    d = os.path.join(run_dir, "img", "glossy")
    os.makedirs(d, exist_ok=True)
    for m in tqdm(list(SSR_METHODS), desc="glossy", unit="method", disable=None if progress is None else not progress):
        try:
            ev = run_glossy(SCENE, m, width=width, height=height, seed=seed, spp=SPP, rays=TRUTH_RAYS, warmup=False,
                            gbuffer=g, truth=truth, use_cache=use_cache)
        except Exception as e:
            notes.append(f"{m}: {type(e).__name__}: {e}")
            continue
        if truth is None:
            for name, rgb in (("lobe", ev.truth.lobe), ("oracle", ev.truth.oracle)):
                Image.fromarray(color_rgb(rgb)).save(os.path.join(d, f"{name}.png"))
                images[name] = f"img/glossy/{name}.png"
        g, truth = ev.gbuffer, ev.truth
        rows.append({"kind": "glossy", **ev.row, "glossy": m in glossy})
        if m in glossy:
            Image.fromarray(color_rgb(ev.result.raw_color)).save(os.path.join(d, f"{m}.png"))
            images[m] = f"img/glossy/{m}.png"
    if rows:
        _curves(os.path.join(d, "error.png"), rows, glossy)
        _speed(os.path.join(d, "speed.png"), rows, glossy)
        images["error"], images["speed"] = "img/glossy/error.png", "img/glossy/speed.png"
    keys = ("mae_lobe", "mae_vs_oracle", "mae_oracle", "mae_specular", "mae_resolve_only", "rmse_lobe_net",
            "truth_se_mean")
    table = [{"method": r["method"], "glossy": r["glossy"], "ms": fmt(r["seconds"] * 1e3, "{:.1f}"),
              **{k: fmt(r[k], "{:.4f}") for k in keys}} for r in rows]
    glance = [{"method": t["method"], "headline": f"glossy_ramp: |error| {t['mae_lobe']} vs the lobe, "
                                                  f"{t['mae_vs_oracle']} vs the oracle", "seconds": "–", "scenes": 1}
              for t in table]
    return {"available": bool(rows), "note": "" if rows else "no SSR method ran on the glossy scene",
            "notes": notes, "rows": rows, "table": table, "images": images, "glance": glance, "scene": SCENE,
            "glossy_methods": sorted(glossy), "truth_rays": TRUTH_RAYS, "spp": SPP, "size": f"{width}×{height}",
            "gt_seconds": float(truth.seconds) if truth is not None else None,
            "seconds": time.perf_counter() - t0, "threads": torch.get_num_threads()}


def summary_md(sec: dict) -> str:
    """The glossy part of ``summary.md``."""
    lines = ["", "## Glossy reflections", ""]
    if not sec.get("available"):
        return unavailable_md(lines, sec, "Glossy reflections")
    lines += [f"{sec['scene']}, {sec['size']}, truth {sec['truth_rays']} lobe directions per pixel; mean |error| over "
              "the specular pixels.", "",
              "| method | ms | vs lobe | vs oracle | information loss | resolved vs specular | resolve only | truth SE |",
              "|---|---:|---:|---:|---:|---:|---:|---:|"]
    lines += [f"| {t['method']} | {t['ms']} | {t['mae_lobe']} | {t['mae_vs_oracle']} | {t['mae_oracle']} | "
              f"{t['mae_specular']} | {t['mae_resolve_only']} | {t['truth_se_mean']} |" for t in sec["table"]]
    return "\n".join(lines + [f"- {n}" for n in sec["notes"]]) + "\n"
