"""Report summaries: the "at a glance" table per effect, ``summary.md``'s head, the metadata rows, raw rows.

Everything here reads the plain dicts the sections return (``meta["ao"]``, ``meta["ssr"]``, …) and tolerates a
section that is off, failed, or still being written: its line in the table then carries its note.

A section may supply its own glance lines as ``out["glance"]``: a list of ``{"method", "headline", "seconds",
"scenes"}`` dicts (strings or numbers; missing keys show as ``–``); :func:`glance` uses them as they are.
"""
from __future__ import annotations

import json
import math
import statistics
from typing import Any, Iterable, Optional

#: (meta key, title) of every report section, in page order
SECTIONS = (("ao", "Ambient occlusion"), ("ssr", "Screen-space reflections"), ("implicit", "Implicit surfaces"),
            ("glossy", "Glossy reflections"),
            ("time", "Time"), ("speed", "Speed"), ("tuning", "Tuning"), ("calibration", "Metric calibration"))


def fmt(s: Optional[float], spec: str = "{:.3f}") -> str:
    """A cell: ``–`` for None or NaN, else ``spec``."""
    if s is None or (isinstance(s, float) and math.isnan(s)):
        return "–"
    return spec.format(s)


def _mean(values: Iterable[Any]) -> Optional[float]:
    v = [float(x) for x in values if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)]
    return statistics.fmean(v) if v else None


def _by_method(rows: list[dict]) -> dict[str, list[dict]]:
    out: dict[str, list[dict]] = {}
    for r in rows:
        out.setdefault(str(r.get("method")), []).append(r)
    return out


def _size(rows: list[dict]) -> str:
    """``"at W×H, "`` of rows that share one size, else ``""``."""
    sizes = {(r.get("width"), r.get("height")) for r in rows}
    if len(sizes) != 1 or None in next(iter(sizes)):
        return ""
    w, h = next(iter(sizes))
    return f"at {w}×{h}, "


def _ao_lines(ao: dict) -> list[dict]:
    return [{"method": m, "headline": f"{_size(rs)}defaults: RMSE {fmt(_mean(r.get('rmse_cos') for r in rs), '{:.4f}')}"
                                      " vs cosine GT",
             "seconds": fmt(_mean(r.get("seconds") for r in rs)), "scenes": len({r.get("scene") for r in rs})}
            for m, rs in _by_method(ao.get("rows") or []).items()]


def _ssr_lines(ssr: dict) -> list[dict]:
    lines = []
    for m, rs in _by_method([r for r in ssr.get("rows") or [] if r.get("setting", "defaults") == "defaults"]).items():
        parts = [f"{label} {fmt(_mean(r.get(k) for r in rs), '{:.1%}')}" for k, label in
                 (("frac_correct", "correct"), ("frac_missed", "missed"), ("frac_false_hit", "false hit"),
                  ("frac_misplaced_hit", "misplaced hit"), ("frac_punch_through", "punch-through"),
                  ("frac_unfixable_hit", "hit on unfixable target"))]
        lines.append({"method": m, "headline": f"{_size(rs)}defaults: " + " · ".join(parts),
                      "seconds": fmt(_mean(r.get("seconds") for r in rs)),
                      "scenes": len({r.get("scene") for r in rs})})
    return lines


def _implicit_lines(imp: dict) -> list[dict]:
    compared = {c.get("name") for c in imp.get("comparisons") or []}
    rows = [r for r in imp.get("rows") or [] if r.get("scene") in compared]
    lines = []
    for m, rs in _by_method(rows).items():
        last = _mean((r.get("punch_through_per_frame") or [None])[-1] for r in rs)
        lines.append({"method": m, "headline": f"{_size(rs)}punch-through {fmt(last, '{:.2%}')} on the last of "
                                               f"{imp.get('frames')} frames · "
                                               f"{fmt(_mean(r.get('evaluations_mean') for r in rs), '{:.1f}')} "
                                               "evaluations/px",
                      "seconds": fmt(_mean(r.get("seconds_per_frame") for r in rs)), "scenes": len(compared)})
    return lines


_LINES = {"ao": _ao_lines, "ssr": _ssr_lines, "implicit": _implicit_lines}


def _title(method) -> str:
    """``ssbench.passes.title`` of a method key, or ``""`` (not a declared method, e.g. a calibration line)."""
    try:
        from ..passes import title
        t = title(str(method))
    except Exception:                                        # the summary must not crash the report
        return ""
    return "" if t == str(method) else t


def glance(meta: dict) -> list[dict]:
    """One block per section: ``{"key", "title", "available", "note", "lines": [{method, what, headline, seconds,
    scenes}]}`` (``what``: the method in words, ``""`` when it is no declared method); an unavailable section has
    no lines and its note. Never raises on a malformed section."""
    out = []
    for key, title in SECTIONS:
        sec = meta.get(key) or {"available": False, "note": f"{title} section not run."}
        block = {"key": key, "title": title, "available": bool(sec.get("available")),
                 "note": sec.get("note") or "", "lines": []}
        if block["available"]:
            try:
                custom = sec.get("glance")
                lines = custom if isinstance(custom, list) else _LINES.get(key, lambda s: [])(sec)
                block["lines"] = [{k: d.get(k, "–") if isinstance(d, dict) else "–"
                                   for k in ("method", "headline", "seconds", "scenes")} for d in lines]
                for d in block["lines"]:                     # the method in words, from its declaration
                    d["what"] = _title(d["method"])
            except Exception as e:                           # the summary must not crash the report
                block["note"] = f"summary failed: {type(e).__name__}: {e}"
        out.append(block)
    return out


def glance_md(blocks: list[dict]) -> str:
    """The glance table as Markdown."""
    lines = ["## At a glance", "", "Mean over the section's scenes; time is the mean per run (implicit: per frame).",
             "", "| effect | method | result | time s | scenes |", "|---|---|---|---:|---:|"]
    for b in blocks:
        if not b["lines"]:
            note = (b["note"] or "no results").replace("|", "/").replace("\n", " ")
            lines.append(f"| {b['title']} | – | {note} | – | – |")
        for d in b["lines"]:
            what = f" ({d['what']})" if d.get("what") else ""
            lines.append(f"| {b['title']} | {d['method']}{what} | {d['headline']} | {d['seconds']} | {d['scenes']} |")
    return "\n".join(lines) + "\n"


def metadata_rows(meta: dict) -> list[tuple[str, Any]]:
    """(label, value) pairs of the metadata footer and of summary.md."""
    env, git = meta["environment"], meta["git"]
    return [("date", meta["date"]), ("git commit", git["commit"]),
            ("dirty", {True: "yes", False: "no", None: "unknown"}[git["dirty"]]),
            ("ssbench", env["ssbench"]), ("python", env["python"]), ("torch", env["torch"]),
            ("mitsuba", env["mitsuba"]), ("drjit", env["drjit"]), ("kornia", env["kornia"]),
            ("numpy", env["numpy"]), ("Mitsuba variant", env["variant"]),
            ("libLLVM", f"{env['libllvm']} (major {env['libllvm_major']})" if env["libllvm"] else "none"),
            ("torch threads", env["torch_threads"]), ("Dr.Jit threads", env["drjit_threads"]),
            ("machine", f"{env['node']} · {env['processor']} · {env['machine']} · {env['cpu_count']} CPUs"),
            ("platform", env["platform"]), ("image size", f"{meta['width']}×{meta['height']}"),
            ("spp / seed", f"{meta['spp']} / {meta['seed']}"), ("render cache", "on" if meta["use_cache"] else "off"),
            ("ground-truth cache", "on" if meta.get("gt_cache") else "off"),
            ("backend start-up s", fmt(meta["backend_init_s"])), ("total wall time s", fmt(meta["total_s"])),
            ("page weight (images)", f"{fmt(meta.get('images_mb'), '{:.1f}')} MB"),
            ("sweep explorers (images)", f"{fmt(meta.get('explorer_mb'), '{:.1f}')} MB"),
            ("peer parity (tests/peer)", "; ".join(meta.get("peer_parity") or ["not recorded"]))]


def summary_md(meta: dict) -> str:
    """The head of ``summary.md``: title, the glance table, the scenes table, the metadata table."""
    lines = [f"# ssbench reference report {meta['run']}", "", glance_md(meta["glance"]), "## Scenes", ""]
    lines += [f"{meta['width']}×{meta['height']}, {meta['spp']} spp, seed {meta['seed']}; times in seconds "
              "(first calls include Dr.Jit kernel compilation when its cache is cold).", "",
              "| scene | G-buffer s | colour s | coverage | description |", "|---|---:|---:|---:|---|"]
    for s in meta["scenes"]:
        t = s["timings"]
        g, c = (fmt(t[k + "_s"]) + (" (cached)" if t.get(k + "_cached") else "") for k in ("gbuffer", "color"))
        lines.append(f"| {s['name']} | {g} | {c} | {s['coverage']:.1%} | {s['description']} |")
    lines += ["", "## Metadata", "", "| key | value |", "|---|---|"]
    for k, v in meta["metadata_rows"]:
        lines.append(f"| {k} | {str(v).replace('|', '/')} |")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------ raw rows
def clean_json(x: Any) -> Any:
    """``x`` as strict JSON values: NaN and ±inf → None, tensors/arrays → lists, tuples/sets → lists."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): clean_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, set, frozenset)):
        return [clean_json(v) for v in x]
    if x is None or isinstance(x, (bool, int, str)):
        return x
    if hasattr(x, "tolist"):                                 # torch / numpy values
        return clean_json(x.tolist())
    return str(x)


def rows_jsonl(meta: dict) -> dict[str, str]:
    """``{section key: JSON-lines text}`` of every section holding a ``rows`` list (one row per line, each with
    ``"effect"`` set to the section key first, strict JSON: NaN → null), plus ``{name: text}`` for each list of a
    section's ``extra_rows`` dict (rows of another shape, e.g. the AO section's bent-normal table)."""
    out = {}
    lines = lambda key, rows: "".join(json.dumps(clean_json({"effect": key, **r}), allow_nan=False) + "\n"  # noqa
                                      for r in rows if isinstance(r, dict))
    for key, _ in SECTIONS:
        sec = meta.get(key) or {}
        if isinstance(sec.get("rows"), list):
            out[key] = lines(key, sec["rows"])
        for name, rows in (sec.get("extra_rows") or {}).items():
            if isinstance(rows, list):
                out[name] = lines(key, rows)
    return out


def unavailable_md(lines: list, out: dict, name: str) -> str:
    """A section's ``summary.md`` part when it did not run: its heading ``lines``, its note and its notes."""
    return "\n".join(lines + [out.get("note") or f"{name} section unavailable."]
                     + [f"- {n}" for n in out.get("notes", [])]) + "\n"
