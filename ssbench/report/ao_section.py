"""The report's ambient-occlusion section: ground truths, every AO method at its defaults, error maps, artifacts.

Per scene (default :data:`AO_SCENES`; a report run with an explicit scene list uses that list) it renders one
G-buffer, traces the ray-traced ground truth in all three flavours and the screen-space oracle, runs every
method of :data:`ssbench.passes.AO_METHODS` through :func:`ssbench.evaluate.run_ao` at its default parameters
with the radius set to the report's ``radius`` (so all methods and ground truths share one radius), and writes

* ``img/ao/<scene>/gt_<flavour>.png``, ``oracle_cosine.png`` — AO in grey (background black);
* ``<method>.png``, ``<method>_err_cos.png``, ``<method>_err_flavour.png`` — the method's AO and its signed
  error ``method − GT`` against the cosine GT and (when it differs) the GT of the method's own flavour
  (``RdBu``: red = too dark, blue = too bright, saturating at ±:data:`ERR_RANGE`);
* ``<method>_highpass.png`` (the :func:`~ssbench.metrics.highpass` residual behind *noise*) and
  ``<method>_spectrum.png`` (log power spectrum behind *tile energy*, tile harmonics ringed);
* ``halo_band.png`` and ``flat_region.png`` — the pixel sets behind *halo* and *flat bias*.

Nothing here may crash the report: a missing reference AO or pass, or a failing run, becomes a visible note.
"""
from __future__ import annotations

import math
import os
import time
import traceback
from typing import TYPE_CHECKING, Iterable, Optional

import numpy as np
import torch

from ..passes import ao_method, declared
from ..pictures import ao_rgb, error_rgb
from .summary import unavailable_md
from .flip_maps import flip_rgb

if TYPE_CHECKING:
    from ..scenes import Scene

#: scenes of the AO section when the report names none (small, so ``make report`` stays fast)
AO_SCENES = ("crease", "cornell_box", "sphere_on_plane", "stairs", "furnished_room")
FLAVOURS = ("cosine", "uniform", "obscurance", "volume_hemisphere", "volume_sphere")
#: signed-error colour range
ERR_RANGE = 0.5
#: (row key, column label, format) of the per-scene artifact table
TABLE = (("seconds", "time s", "{:.3f}"), ("rmse_cos", "RMSE cos", "{:.4f}"),
         ("rmse_flavour", "RMSE flav", "{:.4f}"), ("estimator_rmse", "RMSE oracle (estimator)", "{:.4f}"),
         ("info_loss_rmse", "info loss RMSE", "{:.4f}"), ("bias_flavour", "bias", "{:+.4f}"),
         ("psnr_cos", "PSNR cos dB", "{:.2f}"), ("ssim_cos", "SSIM cos", "{:.3f}"),
         ("flip_cos", "ꟻLIP cos", "{:.3f}"),
         ("halo_dark_flavour", "dark halo", "{:.4f}"), ("halo_missing_flavour", "missing occl. (band)", "{:.4f}"),
         ("halo_band_flavour", "halo band MAE", "{:.4f}"), ("halo_ratio_flavour", "halo ratio", "{:.2f}"),
         ("flat_bias_flavour", "flat bias", "{:.4f}"), ("over_darkening_flavour", "over-dark.", "{:.2f}"),
         ("banding", "banding", "{:.4f}"), ("tile_energy", "tile energy", "{:.4f}"),
         ("noise", "noise var", "{:.2e}"))


def fmt(value, spec: str = "{:.4f}") -> str:
    """A table cell: ``–`` for None/NaN, ``∞`` for infinities."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if isinstance(value, float) and math.isinf(value):
        return "∞" if value > 0 else "−∞"
    return spec.format(value)


# ------------------------------------------------------------------------------------------ pictures
def _hw(x: torch.Tensor) -> np.ndarray:
    return x.detach().float().cpu().reshape(x.shape[-2], x.shape[-1]).numpy()


def region_rgb(base: torch.Tensor, region: torch.Tensor, mask: torch.Tensor, color=(1.0, 0.55, 0.0)) -> np.ndarray:
    """Grey ``base`` with ``region`` tinted (the pixel sets behind halo and flat bias)."""
    rgb = ao_rgb(base, mask).astype(np.float64) / 255
    r = _hw(region) > 0.5
    rgb[r] = 0.35 * rgb[r] + 0.65 * np.asarray(color)
    return (rgb * 255 + 0.5).astype(np.uint8)


def highpass_rgb(ao: torch.Tensor, mask: torch.Tensor, vmax: float = 0.1) -> np.ndarray:
    """The *noise* residual (AO minus its masked 5×5 box blur) on ``RdBu`` at ±``vmax``."""
    from ..metrics import highpass
    return error_rgb(highpass(ao.float(), mask), mask, vmax)


def spectrum_rgb(ao: torch.Tensor, mask: torch.Tensor, tile: int = 4) -> np.ndarray:
    """Centred log power spectrum (magma over the top 8 decades, in ¼-decade bands: a diagnostic, and the bands
    halve its PNG) behind *tile energy*; tile harmonics ringed in cyan."""
    import matplotlib
    from ..metrics import power_spectrum
    power, harm = power_spectrum(ao.float(), mask, tile)
    lp = np.log10(np.fft.fftshift(power.numpy()) + 1e-12)
    top = lp.max()
    rgb = matplotlib.colormaps["magma"](np.floor(np.clip((lp - (top - 8)) / 8, 0, 1) * 32) / 32)[..., :3]
    h = np.fft.fftshift(harm.numpy())
    ring = np.zeros_like(h)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                ring |= np.roll(h, (dy, dx), (0, 1))
    rgb[ring & ~h] = (0.0, 0.9, 1.0)
    return (rgb * 255 + 0.5).astype(np.uint8)


def write_png(path: str, rgb: np.ndarray) -> str:
    """Write an ``(H, W, 3)`` uint8 image atomically (:func:`ssbench.io.write_rgb_png`)."""
    from ..io import write_rgb_png
    return write_rgb_png(path, rgb)


# ------------------------------------------------------------------------------------------ section
def _unavailable(note: str, **extra) -> dict:
    d = {"available": False, "note": note, "notes": [], "methods": [], "scenes": [], "rows": [], "blurs": [],
         "columns": [(k, label) for k, label, _ in TABLE], "overview": [], "radius": None, "rays": None,
         "seconds": 0.0, "err_range": ERR_RANGE}
    d.update(extra)
    return d


def _methods() -> tuple[list[str], list[str], tuple[str, ...]]:
    """Importable AO methods, notes for those that are not, and the channels they read."""
    from ..passes import AO_METHODS, ao_method
    ok, notes, channels = [], [], []
    for name in AO_METHODS:
        try:
            channels += list(ao_method(name)[2])
            ok.append(name)
        except Exception as e:                                       # a pass being written, or broken
            notes.append(f"method {name} skipped: {type(e).__name__}: {e}")
    return ok, notes, tuple(channels)


def build_ao_section(run_dir: str, scenes: Optional[Iterable["str | Scene"]] = None, width: int = 320, height: int = 240,
                     *, radius: float = 0.5, rays: int = 128, seed: int = 0, use_cache: bool = False,
                     progress: Optional[bool] = None) -> dict:
    """Run the AO section into ``run_dir`` (images under ``img/ao/``); returns its metadata for the template.

    Each method runs once, timed without warm-up (``seconds``; ``benchmarks/`` times carefully). Never
    raises: failures are collected into ``note``/``notes``.
    """
    t_start = time.perf_counter()
    try:
        from .. import evaluate, reference
        reference.ambient_occlusion, reference.screen_space_oracle                  # noqa: B018
    except Exception as e:
        return _unavailable(f"AO section skipped: the reference AO is not importable ({type(e).__name__}: {e}).")
    try:
        methods, notes, channels = _methods()
    except Exception as e:
        return _unavailable(f"AO section skipped: the AO passes are not importable ({type(e).__name__}: {e}).")
    if not methods:
        return _unavailable("AO section skipped: no AO method is importable yet.", notes=notes)
    from tqdm import tqdm
    names = list(AO_SCENES if scenes is None else dict.fromkeys(scenes))
    out_scenes, rows = [], []
    for name in tqdm(names, desc="AO", unit="scene", disable=None if progress is None else not progress):
        try:
            s, r = _scene(run_dir, name, methods, channels, width, height, radius, rays, seed, use_cache,
                          evaluate, reference)
            out_scenes.append(s)
            rows += r
        except Exception as e:
            notes.append(f"scene {getattr(name, 'name', name)} skipped: {type(e).__name__}: {e}")
            if os.environ.get("SSBENCH_DEBUG"):
                traceback.print_exc()
    overview = [{"method": m, "cells": [fmt(next((r["rmse_cos"] for r in rows if r["scene"] == s["name"]
                                                  and r["method"] == m), None)) for s in out_scenes],
                 "seconds": [fmt(next((r["seconds"] for r in rows if r["scene"] == s["name"]
                                       and r["method"] == m), None), "{:.3f}") for s in out_scenes]}
                for m in methods]
    from ..evaluate import BLUR_NAMES
    from .colorbars import colorbar_png
    bars = {"error": colorbar_png(os.path.join(run_dir, "img", "ao", "colorbar_error.png"), "RdBu", -ERR_RANGE,
                                  ERR_RANGE, "AO − GT", low="too dark", high="too bright"),
            "noise": colorbar_png(os.path.join(run_dir, "img", "ao", "colorbar_noise.png"), "RdBu", -0.1, 0.1,
                                  "AO − blurred AO"),
            "flip": colorbar_png(os.path.join(run_dir, "img", "ao", "colorbar_flip.png"), "magma", 0.0, 1.0,
                                 "ꟻLIP vs GT cosine", low="same", high="very different")}
    return {"available": bool(out_scenes), "note": "" if out_scenes else "AO section: every scene failed.",
            "colorbars": {k: os.path.relpath(v, run_dir).replace(os.sep, "/") for k, v in bars.items()},
            "blurs": ["raw", *BLUR_NAMES],
            "notes": notes, "methods": methods, "scenes": out_scenes, "rows": rows,
            "columns": [(k, label) for k, label, _ in TABLE], "overview": overview, "radius": radius,
            "rays": rays, "seconds": time.perf_counter() - t_start, "err_range": ERR_RANGE,
            "threads": torch.get_num_threads()}


def _scene(run_dir, name, methods, channels, width, height, radius, rays, seed, use_cache, evaluate, reference):
    from ..metrics import halo
    from ..scenes import load
    sc = load(name)                                             # a catalog name or a user's loaded scene
    name = sc.name
    d = os.path.join(run_dir, "img", "ao", name)
    rel = f"img/ao/{name}"
    t0 = time.perf_counter()
    g = reference.gbuffer(sc, width, height, channels=tuple(dict.fromkeys(evaluate.GT_CHANNELS + channels)),
                          use_cache=use_cache)
    refs: dict = {}
    gts = {}
    for w in FLAVOURS:
        gts[w] = refs[("full", w, float(radius), rays, seed)] = reference.ambient_occlusion(
            sc, g, float(radius), rays, w, seed, use_cache=use_cache)
    oracle = None
    try:
        oracle = refs[("oracle", "cosine", float(radius), rays, seed)] = reference.screen_space_oracle(
            g, float(radius), rays, "cosine", seed, use_cache=use_cache)
    except Exception:                                                     # shown as missing; rows say why
        pass
    gt_s = time.perf_counter() - t0
    mask = g.mask
    images = {}
    for w, r in gts.items():
        images[f"gt_{w}"] = f"{rel}/gt_{w}.png"
        write_png(os.path.join(d, f"gt_{w}.png"), ao_rgb(r.ao, mask))
    if oracle is not None:
        images["oracle"] = f"{rel}/oracle_cosine.png"
        write_png(os.path.join(d, "oracle_cosine.png"), ao_rgb(oracle.ao, mask))
    band = halo(gts["cosine"].ao, gts["cosine"].ao, g.view_z, mask).band_mask     # the metric's own band
    write_png(os.path.join(d, "halo_band.png"), region_rgb(gts["cosine"].ao, band, mask))
    write_png(os.path.join(d, "flat_region.png"),
              region_rgb(gts["cosine"].ao, mask & (gts["cosine"].ao >= 1 - 1e-3), mask, (0.1, 0.6, 1.0)))
    images["halo_band"], images["flat_region"] = f"{rel}/halo_band.png", f"{rel}/flat_region.png"
    method_rows, rows, notes = [], [], []
    for m in methods:
        try:
            ev = evaluate.run_ao(sc, m, radius=float(radius), rays=rays, seed=seed, repeats=1, warmup=False,
                                 gbuffer=g, references=refs, use_cache=use_cache)
        except Exception as e:
            notes.append(f"{m}: {type(e).__name__}: {e}")
            continue
        row = ev.row
        files = {"ao": ao_rgb(ev.ao, mask), "err_cos": error_rgb(ev.ao - ev.references["cos"].ao, mask),
                 "highpass": highpass_rgb(ev.ao, mask), "spectrum": spectrum_rgb(ev.ao, mask),
                 "flip": flip_rgb(ev.ao, ev.references["cos"].ao, mask)}
        if row["weighting"] != "cosine":                                 # else the same as err_cos
            files["err_flavour"] = error_rgb(ev.ao - ev.references["flavour"].ao, mask)
        imgs = {}
        for k, rgb in files.items():
            fn = f"{m}.png" if k == "ao" else f"{m}_{k}.png"
            write_png(os.path.join(d, fn), rgb)
            imgs[k] = f"{rel}/{fn}"
        try:
            blurs = _blur_cells(ev, g, evaluate)
        except Exception as e:
            blurs = []
            notes.append(f"{m} blurs: {type(e).__name__}: {e}")
        rows.append(row)
        method_rows.append({"method": m, "images": imgs, "weighting": row["weighting"], "blurs": blurs,
                            "params": ", ".join(f"{k}={v}" for k, v in row["params"].items()),
                            "source": declared(ao_method(m)[0], "DEFAULTS_SOURCE", ""),
                            "cells": [fmt(row.get(k), spec) for k, _, spec in TABLE]})
    return ({"name": name, "description": sc.description, "images": images, "methods": method_rows,
             "notes": notes, "gt_seconds": gt_s, "flavours": list(FLAVOURS), "width": g.width, "height": g.height,
             "gt_stderr": {w: float(r.stderr[mask].mean()) for w, r in gts.items()}}, rows)


def _blur_cells(ev, g, evaluate) -> list[str]:
    """Noise variance and RMSE vs cosine GT of the raw AO and after each blur of :data:`evaluate.BLUR_NAMES`."""
    from ..metrics import noise, rmse
    mask, gt = g.mask, ev.references["cos"].ao.float()
    maps = [ev.ao_raw] + [evaluate.blur_fn(b)(ev.ao_raw, g).float() for b in evaluate.BLUR_NAMES]
    return ([fmt(float(noise(a, mask)), "{:.2e}") for a in maps]
            + [fmt(float(rmse(a, gt, mask))) for a in maps])


def summary_md(ao: dict) -> str:
    """The AO section of ``summary.md``: RMSE vs cosine GT and time per method and scene."""
    lines = ["", "## Ambient occlusion", ""]
    if not ao.get("available"):
        return unavailable_md(lines, ao, "AO")
    lines += [f"Every method at its authors' defaults, all at the same radius {ao['radius']} (the equal setting); "
              f"{ao['rays']} GT rays per pixel; RMSE vs cosine GT (time s).", "",
              "| method | " + " | ".join(s["name"] for s in ao["scenes"]) + " |",
              "|---|" + "---:|" * len(ao["scenes"])]
    for o in ao["overview"]:
        lines.append(f"| {o['method']} | " + " | ".join(f"{c} ({t})" for c, t in zip(o["cells"], o["seconds"])) + " |")
    rows = ao.get("rows") or []
    if rows:
        lines += ["", "RMSE against the method's own flavour (what it estimates) and against cosine AO (what shading "
                  "needs), mean over the scenes:", "", "| method | flavour | RMSE own flavour | RMSE cosine | "
                  "banding | dark halo |", "|---|---|---:|---:|---:|---:|"]
        for m in dict.fromkeys(r["method"] for r in rows):
            rs = [r for r in rows if r["method"] == m]

            def mean(k):
                v = [r.get(k) for r in rs if isinstance(r.get(k), float) and r.get(k) == r.get(k)]
                return sum(v) / len(v) if v else None
            lines.append(f"| {m} | {rs[0].get('weighting')} | {fmt(mean('rmse_flavour'))} | {fmt(mean('rmse_cos'))} | "
                         f"{fmt(mean('banding'))} | {fmt(mean('halo_dark_flavour'))} |")
        lines += ["", "Defaults from:"] + [f"- {m}: {declared(ao_method(m)[0], 'DEFAULTS_SOURCE') or 'not declared'}"
                                          for m in dict.fromkeys(r["method"] for r in rows)]
    from .ao_beyond import summary_lines
    return "\n".join(lines + [f"- {n}" for n in ao["notes"]] + summary_lines(ao.get("beyond") or {})) + "\n"
