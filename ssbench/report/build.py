"""Build the HTML report: reference renders of the built-in scenes with timings and environment metadata.

A run goes to ``<out_root>/<YYYYmmdd-HHMMSS>/`` (``index.html``, ``summary.md``, ``meta.json``,
``rows/<section>.jsonl``, ``img/...``) and is then copied to ``<out_root>/latest/``: the copy is written to a
temporary directory beside it and renamed into place, so ``latest`` is never half-written. Image links are
relative, so both copies show their images.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import shutil
import tempfile
import time
from typing import Iterable, Optional, Sequence

from ..gbuffer import CHANNELS, GBuffer
from ..io import replace_dir
from ..runinfo import environment, git_state  # noqa: F401  (re-exported: the report's metadata)
from . import summary
from .render import write_pages, write_text

__all__ = ["build_report", "render_scene", "refresh_latest", "environment", "git_state", "PREVIEW_ROW",
           "ALL_CHANNELS"]

#: scenes of the SSR section when the report names none (mirrors ``ssr_section.SSR_SCENES``)
_SSR_SCENES = ("reflective_floor", "fence")
#: G-buffer previews shown under each scene's colour image, in this order
PREVIEW_ROW = ("view_z", "normal", "position", "albedo", "roughness", "metallic", "shape_id", "mask", "back_z")
ALL_CHANNELS = tuple(CHANNELS)
#: widest preview kept, by where the page shows it (colour: the scene's 400-px hero; the row: ~130-px thumbnails);
#: wider renders are shrunk by a whole factor (block mean; ids and mask nearest). Page weight, not information:
#: every section renders at the full size.
PREVIEW_WIDTH = {"color": 400, "row": 240}


# ------------------------------------------------------------------------------------------ rendering
def render_scene(scene, width: Optional[int] = None, height: Optional[int] = None,
                 channels: Sequence[str] = ALL_CHANNELS, *, spp: int = 64, seed: int = 0,
                 use_cache: bool = True) -> tuple[GBuffer, dict]:
    """Render ``channels`` of ``scene`` (``mask`` always included); timings ``{"gbuffer_s", "color_s",
    "gbuffer_cached", "color_cached"}``.

    The geometric channels and the path-traced colour are rendered and timed separately
    (``time.perf_counter`` around scene conversion and rendering, as the reference functions report them in
    ``info``; cache I/O excluded); either time is ``None`` when that part was not asked for. A part read from the
    render cache (``use_cache``) is flagged ``*_cached`` and its time is the one recorded when it was rendered
    (``None`` for entries that recorded none).
    """
    from .. import reference
    geo = tuple(dict.fromkeys([c for c in channels if c != "color"] + ["mask"]))
    info = {}
    g = reference.gbuffer(scene, width, height, channels=geo, spp=spp, seed=seed, use_cache=use_cache, info=info)
    timings = {"gbuffer_s": info.get("seconds"), "color_s": None, "gbuffer_cached": bool(info.get("cached")),
               "color_cached": False}
    if "color" in channels:
        info = {}
        col = reference.color(scene, g.width, g.height, spp=spp, seed=seed, use_cache=use_cache, info=info)
        timings.update(color_s=info.get("seconds"), color_cached=bool(info.get("cached")))
        g = GBuffer(g.camera, color=col, **g.as_dict())
    return g, timings


# ------------------------------------------------------------------------------------------ output
def _new_run_dir(out_root: str) -> tuple[str, str]:
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    for k in range(1000):
        name = stamp if k == 0 else f"{stamp}-{k}"
        path = os.path.join(out_root, name)
        try:
            os.makedirs(path)
            return name, path
        except FileExistsError:
            continue
    raise RuntimeError(f"out_root: could not create a fresh run directory in {out_root!r}")


def refresh_latest(run_dir: str, out_root: str) -> str:
    """Make ``<out_root>/latest`` a full copy of ``run_dir``, swapped in by rename (never half-written)."""
    latest = os.path.join(out_root, "latest")
    tmp = tempfile.mkdtemp(prefix=".latest-new-", dir=out_root)
    shutil.copytree(run_dir, tmp, dirs_exist_ok=True)
    return replace_dir(tmp, latest)


def user_scenes(paths: Iterable, taken: Iterable[str]) -> list:
    """A user's scene files (or scenes already loaded from them) as scenes named after their files (safe for
    paths, unique, never a catalog name: ``file_<name>`` then)."""
    import dataclasses
    import re
    from ..scenes import Scene, load
    if isinstance(paths, (str, os.PathLike)):
        raise TypeError("extra_scenes: expected a list of scene files, got one path")
    out, used = [], set(taken)
    for p in paths:
        sc = load(p if isinstance(p, Scene) else os.fspath(p))
        name = re.sub(r"[^A-Za-z0-9_.-]", "_", sc.name) or "scene"
        if name in used:
            name = f"file_{name}"
        while name in used:
            name += "_"
        used.add(name)
        out.append(dataclasses.replace(sc, name=name))
    return out


def _ao_section(run_dir, scenes, width, height, enabled, radius, rays, seed, use_cache, progress) -> dict:
    """The AO section's metadata (see :mod:`.ao_section`); a note instead whenever it cannot run."""
    if not enabled:
        return {"available": False, "note": "AO section turned off.", "notes": [], "summary_md": ""}
    try:
        from . import ao_beyond, ao_section
        out = ao_section.build_ao_section(run_dir, scenes, width, height, radius=radius, rays=rays, seed=seed,
                                          use_cache=use_cache, progress=progress)
        out["beyond"] = ao_beyond.build_ao_beyond(min(width, 160), min(height, 120), seed=seed, use_cache=use_cache,
                                                  progress=progress)
        out["extra_rows"] = {"ao_beyond": out["beyond"]["rows"]}
        out["summary_md"] = ao_section.summary_md(out)
    except Exception as e:                                   # the report must not crash on the AO slice
        note = f"AO section failed: {type(e).__name__}: {e}"
        out = {"available": False, "note": note, "notes": [], "summary_md": f"\n## Ambient occlusion\n\n{note}\n"}
    return out


def _ssr_section(run_dir, scenes, width, height, enabled, spp, seed, use_cache, gbuffers, progress) -> dict:
    """The SSR section's metadata (see :mod:`.ssr_section`); a note instead whenever it cannot run."""
    if not enabled:
        return {"available": False, "note": "SSR section turned off.", "notes": [], "summary_md": ""}
    try:
        from . import ssr_section
        out = ssr_section.build_ssr_section(run_dir, scenes, width, height, spp=spp, seed=seed,
                                            use_cache=use_cache, gbuffers=gbuffers, progress=progress)
        out["summary_md"] = ssr_section.summary_md(out)
    except Exception as e:                                   # the report must not crash on the SSR slice
        note = f"SSR section failed: {type(e).__name__}: {e}"
        out = {"available": False, "note": note, "notes": [],
               "summary_md": f"\n## Screen-space reflections\n\n{note}\n"}
    return out


def _implicit_section(run_dir, scenes, width, height, enabled, seed, use_cache) -> dict:
    """The implicit section's metadata (see :mod:`.implicit_section`); a note instead whenever it cannot run.

    ``enabled=None`` runs it for a full report only (``scenes`` None): a mesh-scene subset names no implicit
    scene. Its size is at most 160×120 (the report's, when smaller)."""
    return _optional_section("implicit", "Implicit surfaces", enabled, scenes, lambda m: m.build_implicit_section(
        run_dir, min(width, 96), min(height, 72), seed=seed, use_cache=use_cache))


def _optional_section(key, title, enabled, scenes, call) -> dict:
    """A section run by ``call(module)`` from ``ssbench.report.<key>_section``, guarded like the implicit one:
    ``enabled=None`` means on for a full report only; an ImportError or any failure becomes a note."""
    if enabled is None:
        enabled = scenes is None
    if not enabled:
        return {"available": False, "note": f"{title} section turned off.", "notes": [], "summary_md": ""}
    try:
        import importlib
        mod = importlib.import_module(f"{__package__}.{key}_section")
        out = call(mod)
        out["summary_md"] = mod.summary_md(out)
    except Exception as e:                                   # ImportError included: the module may not exist yet
        note = f"{title} section failed: {type(e).__name__}: {e}"
        out = {"available": False, "note": note, "notes": [], "summary_md": f"\n## {title}\n\n{note}\n"}
    return out


def _speed_section(run_dir, scenes, width, height, enabled, seed, use_cache, progress) -> dict:
    """The speed section's metadata (see :mod:`.speed_section`); a note instead whenever it cannot run."""
    return _optional_section("speed", "Speed", enabled, scenes, lambda m: m.build_speed_section(
        run_dir, width=width, height=height, seed=seed, use_cache=use_cache, progress=progress))


def _tuning_section(run_dir, scenes, width, height, enabled, seed, use_cache, progress) -> dict:
    """The tuning section's metadata (see :mod:`.tuning_section`); a note instead whenever it cannot run."""
    return _optional_section("tuning", "Tuning", enabled, scenes, lambda m: m.build_tuning_section(
        run_dir, width=width, height=height, seed=seed, use_cache=use_cache, progress=progress))


def build_report(out_root: str = "reports", scenes: Optional[Iterable[str]] = None, width: int = 640,
                 height: int = 360, spp: int = 64, seed: int = 0, *, use_cache: bool = True,
                 progress: Optional[bool] = None, ao: bool = True, ao_radius: float = 0.5,
                 ao_rays: int = 128, ssr: bool = True, ssr_spp: int = 16, implicit: Optional[bool] = None,
                 speed: Optional[bool] = None, tuning: Optional[bool] = None, calibration: Optional[bool] = None,
                 time_axis: Optional[bool] = None, glossy: Optional[bool] = None,
                 gt_cache: bool = True, extra_scenes: Iterable = ()) -> str:
    """Render every catalog scene (or ``scenes``) and write a report run; returns the run's ``index.html``.

    ``extra_scenes``: a user's scene files (Mitsuba ``.xml``, YAML, TOML) or the scenes loaded from them, added to
    the scene previews and to the AO and SSR sections (after their own scenes), each under its file's name
    (``file_`` in front when that is a catalog name).

    ``use_cache=True`` (default) reads the scene previews from the render cache when they are there (their times
    are then the ones recorded when they were rendered, flagged "cached" in the page); ``use_cache=False``
    renders and times them afresh. ``gt_cache=True`` (default) lets the sections read and write the ground-truth cache (a warm run
    reuses the ray-traced references; the sections' pass timings never come from a cache).
    ``ao`` adds the ambient-occlusion section (:mod:`ssbench.report.ao_section`; scenes: ``scenes`` or its
    small default subset) at radius ``ao_radius`` with ``ao_rays`` ground-truth rays per pixel; ``ssr`` the
    screen-space reflections section (:mod:`ssbench.report.ssr_section`; scenes: ``scenes`` or
    reflective_floor and fence) with ``ssr_spp`` samples for the mirror radiance, reusing the G-buffers
    rendered here; ``implicit`` the implicit-surface section (:mod:`ssbench.report.implicit_section`; default:
    on for a full report, off with a ``scenes`` subset); ``speed`` and ``tuning`` the speed and tuning sections
    (:mod:`ssbench.report.speed_section`, :mod:`ssbench.report.tuning_section`; defaults like ``implicit``);
    ``calibration`` the metric calibration section (:mod:`ssbench.report.calibration_section`; likewise);
    ``time_axis`` the time section (:mod:`ssbench.report.time_section`: flicker, ghosting and error over frames,
    raw and accumulated; likewise); ``glossy`` the glossy-reflections section (:mod:`ssbench.report.glossy_section`:
    every SSR method on rough surfaces against the path-traced lobe; likewise).
    No section ever fails the report (problems show as notes in the page). Each section's evaluation rows
    also go to ``rows/<section>.jsonl`` (see reports/README.md).
    """
    from tqdm import tqdm
    from .. import io
    from ..scenes import catalog, load
    t_start = time.perf_counter()
    known = catalog.names()
    names = known if scenes is None else list(dict.fromkeys(scenes))
    unknown = [n for n in names if n not in known]
    if unknown or not names:
        raise ValueError(f"scenes: unknown or empty {unknown or names}; built-in scenes: {', '.join(known)}")
    for k, v in (("width", width), ("height", height), ("spp", spp)):
        if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
            raise ValueError(f"{k}: must be a positive integer, got {v!r}")
    out_root = os.path.abspath(os.fspath(out_root))
    os.makedirs(out_root, exist_ok=True)
    t0 = time.perf_counter()
    env = environment()                                     # probes the backend and imports Mitsuba
    backend_init_s = time.perf_counter() - t0
    extras = user_scenes(extra_scenes, known)
    run, run_dir = _new_run_dir(out_root)
    descriptions = catalog.describe()
    rows, gbuffers = [], {}
    for spec in tqdm(names + extras, desc="report", unit="scene", disable=None if progress is None else not progress):
        sc = load(spec)
        name = sc.name
        g, timings = render_scene(sc, width, height, ALL_CHANNELS, spp=spp, seed=seed, use_cache=use_cache)
        if ssr and (scenes is not None or name in _SSR_SCENES or spec in extras):
            gbuffers[name] = g                              # reused by the SSR section
        t0 = time.perf_counter()
        images = {}
        for ch in ("color",) + PREVIEW_ROW:
            rel = f"img/{name}/{ch}.png"
            rgb = io.preview_rgb(ch, getattr(g, ch), mask=g.mask, camera=g.camera)
            shown = PREVIEW_WIDTH["color" if ch == "color" else "row"]           # as wide as the page shows it
            rgb = io.shrink_rgb(rgb, max(1, -(-g.width // shown)), nearest=ch in ("shape_id", "mask"))
            io.write_rgb_png(os.path.join(run_dir, *rel.split("/")), rgb)
            images[ch] = rel
        timings["preview_s"] = time.perf_counter() - t0
        rows.append({"name": name, "description": descriptions.get(name, sc.description), "images": images,
                     "timings": timings, "coverage": float(g.mask.float().mean()),
                     "camera": {k: getattr(g.camera, k) for k in ("eye", "target", "up", "fovy_deg", "width",
                                                                  "height", "near", "far")}})
    meta = {"run": run, "date": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "width": width, "height": height, "spp": spp, "seed": seed, "use_cache": use_cache,
            "git": git_state(), "environment": env, "backend_init_s": backend_init_s, "scenes": rows,
            "preview_row": list(PREVIEW_ROW)}
    sc_cache = use_cache or gt_cache                          # the sections' ground truth
    meta["gt_cache"] = sc_cache
    from .ao_section import AO_SCENES
    ao_scenes = list(AO_SCENES if scenes is None else names) + extras if extras else scenes
    ssr_scenes = list(_SSR_SCENES if scenes is None else names) + extras if extras else scenes
    meta["user_scenes"] = [{"name": sc.name, "file": sc.source} for sc in extras]
    meta["ao"] = _ao_section(run_dir, ao_scenes, width, height, ao, ao_radius, ao_rays, seed, sc_cache, progress)
    meta["ssr"] = _ssr_section(run_dir, ssr_scenes, width, height, ssr, ssr_spp, seed, sc_cache, gbuffers,
                               progress)
    del gbuffers
    meta["glossy"] = _optional_section("glossy", "Glossy reflections", glossy, scenes, lambda m: m.build_glossy_section(
        run_dir, min(width, 160), min(height, 120), seed=seed, use_cache=sc_cache, progress=progress))
    meta["implicit"] = _implicit_section(run_dir, scenes, width, height, implicit, seed, sc_cache)
    meta["speed"] = _speed_section(run_dir, scenes, width, height, speed, seed, sc_cache, progress)
    meta["tuning"] = _tuning_section(run_dir, scenes, width, height, tuning, seed, sc_cache, progress)
    meta["time"] = _optional_section("time", "Time", time_axis, scenes, lambda m: m.build_time_section(
        run_dir, min(width, 128), min(height, 96), use_cache=sc_cache, progress=progress))
    meta["calibration"] = _optional_section("calibration", "Metric calibration", calibration, scenes,
                                            lambda m: m.build_calibration_section(run_dir, use_cache=sc_cache,
                                                                                  progress=progress))
    meta["total_s"] = time.perf_counter() - t_start
    meta["images_mb"] = _folder_mb(os.path.join(run_dir, "img"))      # what the page loads, besides its HTML
    meta["explorer_mb"] = sum(_folder_mb(os.path.join(run_dir, "sweeps", d, "img"))   # what the explorers load
                              for d in (os.listdir(os.path.join(run_dir, "sweeps"))
                                        if os.path.isdir(os.path.join(run_dir, "sweeps")) else ()))
    from ..peer import proofs
    meta["peer_parity"] = proofs()
    meta["metadata_rows"] = summary.metadata_rows(meta)
    meta["glance"] = summary.glance(meta)
    raw = summary.rows_jsonl(meta)
    meta["rows_files"] = {key: f"rows/{key}.jsonl" for key in raw}
    for key, text in raw.items():                            # raw rows first: index.html links to them
        os.makedirs(os.path.join(run_dir, "rows"), exist_ok=True)
        write_text(os.path.join(run_dir, "rows", f"{key}.jsonl"), text)
    write_pages(run_dir, meta)
    write_text(os.path.join(run_dir, "meta.json"), json.dumps(meta, indent=2, default=str) + "\n")
    refresh_latest(run_dir, out_root)
    return os.path.join(run_dir, "index.html")


def _folder_mb(path: str) -> float:
    """Megabytes (10⁶ bytes) of the files under ``path`` (0 when it does not exist)."""
    total = sum(os.path.getsize(os.path.join(d, f)) for d, _, files in os.walk(path) for f in files)
    return total / 1e6


