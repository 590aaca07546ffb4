"""Compare two report runs: ``ssbench report --compare RUN_A RUN_B``.

A run is a report folder holding ``meta.json`` (and, from this version on, ``rows/<section>.jsonl``; older runs
keep their rows inside ``meta.json``), named by its path, by its name under the reports root (``--out``), or as
``latest``. The comparison lists

* metadata: commit, dirty flag, versions, Mitsuba variant, threads, machine, image size, spp, seed, scenes;
* per section: availability and row counts;
* results: every evaluation row keyed by effect / scene / method / parameters (plus the settings that tell
  two runs of one method apart), each field that changed beyond a relative tolerance ``rtol``, and the rows
  only one run has;
* timings: run, scene, section and row wall times that changed by more than ``time_rtol`` (relative).

It prints a text version and writes ``compare.md`` and ``compare.html`` to ``<root>/compare-<A>-vs-<B>/``
(written to a temporary folder and renamed into place; a comparison of the same pair replaces the older one;
runs themselves are only read).
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from typing import Any, Optional

from ..bench.rows import METADATA_FIELDS, is_volatile
from ..io import umask, replace_dir
from .summary import SECTIONS, clean_json

#: row fields that, with effect / scene / method / params, identify a row across runs
KEY_FIELDS = ("width", "height", "weighting", "blur", "radius", "rays", "spp", "k_px", "reflective", "frames",
              "truth_frames", "split", "seed", "setting")
#: (label, path in meta.json) of the compared metadata
META = (("git commit", ("git", "commit")), ("dirty", ("git", "dirty")),
        *((k, ("environment", k)) for k in ("ssbench", "python", "torch", "mitsuba", "drjit", "kornia", "numpy",
                                            "variant", "libllvm_major", "torch_threads", "drjit_threads", "node",
                                            "cpu_count", "platform")),
        ("width", ("width",)), ("height", ("height",)), ("spp", ("spp",)), ("seed", ("seed",)),
        ("render cache", ("use_cache",)))
_ATOL = 1e-12


# ------------------------------------------------------------------------------------------ loading
def resolve_run(spec: str, root: str, label: str = "RUN") -> str:
    """The folder of run ``spec`` (a path, a name under ``root``, or ``latest``); clear errors naming ``label``."""
    cands = [spec, os.path.join(root, spec)] if not os.path.isabs(spec) else [spec]
    path = next((c for c in cands if os.path.isdir(c)), None)
    if path is None:
        runs = sorted(n for n in os.listdir(root) if os.path.isfile(os.path.join(root, n, "meta.json"))) \
            if os.path.isdir(root) else []
        raise ValueError(f"{label}: no run {spec!r} (neither a folder nor a run under {root!r}; runs there: "
                         f"{', '.join(runs[-8:]) or 'none'})")
    if not os.path.isfile(os.path.join(path, "meta.json")):
        raise ValueError(f"{label}: {path!r} holds no meta.json (not a report run, or one that did not finish)")
    return os.path.abspath(path)


def load_run(path: str) -> dict:
    """``{"path", "name", "meta", "rows": {section: [row, ...]}}`` of the run folder ``path``."""
    with open(os.path.join(path, "meta.json"), encoding="utf-8") as f:
        meta = json.load(f)
    rows = {}
    for key, _ in SECTIONS:
        fn = os.path.join(path, "rows", f"{key}.jsonl")
        if os.path.isfile(fn):
            with open(fn, encoding="utf-8") as f:
                rows[key] = [json.loads(line) for line in f if line.strip()]
        elif isinstance((meta.get(key) or {}).get("rows"), list):      # runs written before rows/ existed
            rows[key] = [clean_json({"effect": key, **r}) for r in meta[key]["rows"]]
    name = str(meta.get("run") or os.path.basename(path.rstrip(os.sep)))
    return {"path": path, "name": name, "meta": meta, "rows": rows}


# ------------------------------------------------------------------------------------------ comparing
def _get(d: Any, path: tuple) -> Any:
    for k in path:
        d = d.get(k) if isinstance(d, dict) else None
    return d


def _num(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _close(a: Any, b: Any, rtol: float) -> bool:
    if _num(a) and _num(b):
        if math.isnan(a) or math.isnan(b):
            return math.isnan(a) and math.isnan(b)
        return a == b or abs(a - b) <= rtol * max(abs(a), abs(b)) + _ATOL
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y, rtol) for x, y in zip(a, b))
    return a == b


def _rel(a: Any, b: Any) -> Optional[float]:
    if _num(a) and _num(b) and math.isfinite(a) and math.isfinite(b) and max(abs(a), abs(b)) > 0:
        return (b - a) / max(abs(a), abs(b))
    return None


def row_keys(rows: list[dict]) -> dict[str, dict]:
    """Rows by identity: ``effect/scene/method {params} setting=value ...`` (``#2``… when a run repeats one)."""
    out: dict[str, dict] = {}
    for r in rows:
        params = json.dumps(r.get("params"), sort_keys=True, default=str)
        extra = " ".join(f"{k}={r[k]}" for k in KEY_FIELDS if r.get(k) is not None)
        key = f"{_short(r)} {params} {extra}".strip()
        k, n = key, 1
        while k in out:
            n += 1
            k = f"{key} #{n}"
        out[k] = r
    return out


def _short(r: dict) -> str:
    return f"{r.get('effect')}/{r.get('scene')}/{r.get('method')}"


def _labels(keyed: dict[str, dict]) -> dict[str, str]:
    """Readable labels of :func:`row_keys`' keys: ``effect/scene/method``, plus what tells apart rows that share
    it (differing parameters or settings)."""
    groups: dict[str, list[str]] = {}
    for k, r in keyed.items():
        groups.setdefault(_short(r), []).append(k)
    out = {}
    for short, keys in groups.items():
        flat = [{**{f"params.{a}": b for a, b in (keyed[k].get("params") or {}).items()},
                 **{f: keyed[k].get(f) for f in KEY_FIELDS}} for k in keys]
        differ = [f for f in dict.fromkeys(f for d in flat for f in d) if len({str(d.get(f)) for d in flat}) > 1]
        seen: dict[str, int] = {}
        for k, d in zip(keys, flat):
            lab = f"{short} {' '.join(f'{f}={d.get(f)}' for f in differ)}".strip()
            seen[lab] = seen.get(lab, 0) + 1
            out[k] = lab if seen[lab] == 1 else f"{lab} #{seen[lab]}"
    return out


def _cell(x: Any) -> str:
    if isinstance(x, float):
        return f"{x:.6g}"
    if isinstance(x, list):
        return f"[{len(x)} values]" if len(x) > 4 else json.dumps(x, default=str)
    return "–" if x is None else str(x)


def compare_runs(a: dict, b: dict, rtol: float = 1e-3, time_rtol: float = 0.25) -> dict:
    """The differences between loaded runs ``a`` and ``b`` (see the module docstring); plain dicts and lists."""
    if not (rtol >= 0 and time_rtol >= 0):
        raise ValueError(f"rtol/time_rtol: must be non-negative, got {rtol!r} / {time_rtol!r}")
    ma, mb = a["meta"], b["meta"]
    metadata = [{"what": label, "a": _cell(_get(ma, p)), "b": _cell(_get(mb, p)),
                 "changed": _get(ma, p) != _get(mb, p)} for label, p in META]
    sa, sb = [s.get("name") for s in ma.get("scenes", [])], [s.get("name") for s in mb.get("scenes", [])]
    metadata.append({"what": "scenes", "a": ", ".join(map(str, sa)), "b": ", ".join(map(str, sb)), "changed": sa != sb})
    sections = [{"what": title, "a": _section_cell(ma, a["rows"], key), "b": _section_cell(mb, b["rows"], key),
                 "changed": _section_cell(ma, a["rows"], key) != _section_cell(mb, b["rows"], key)}
                for key, title in SECTIONS]
    ka = row_keys([r for rs in a["rows"].values() for r in rs])
    kb = row_keys([r for rs in b["rows"].values() for r in rs])
    label = {**_labels(ka), **_labels({k: r for k, r in kb.items() if k not in ka})}
    results, timings, same = [], [], 0
    for key in (k for k in ka if k in kb):
        ra, rb, changed = ka[key], kb[key], False
        for field in dict.fromkeys([*ra, *rb]):
            if field in ("effect", "scene", "method", "params", *KEY_FIELDS, *METADATA_FIELDS):
                continue
            va, vb = ra.get(field), rb.get(field)
            if is_volatile(field) or "seconds" in field:        # a wall time: listed when it moved a lot
                if not field.startswith("gt_seconds") and _num(va) and _num(vb) and not _close(va, vb, time_rtol):
                    timings.append({"what": f"{label[key]} · {field}", "a": va, "b": vb})
            elif not _close(va, vb, rtol):
                changed = True
                results.append({"row": label[key], "field": field, "a": _cell(va), "b": _cell(vb),
                                "rel": _rel(va, vb)})
        same += not changed
    timings = _run_timings(ma, mb, time_rtol) + timings
    for t in timings:
        t["ratio"] = t["b"] / t["a"] if t["a"] else None
    return {"a": a["name"], "b": b["name"], "a_path": a["path"], "b_path": b["path"], "rtol": rtol,
            "time_rtol": time_rtol, "metadata": metadata, "sections": sections, "results": results,
            "added": [k for k in kb if k not in ka], "removed": [k for k in ka if k not in kb],
            "rows_compared": sum(k in kb for k in ka), "rows_unchanged": same, "timings": timings}


def _section_cell(meta: dict, rows: dict, key: str) -> str:
    sec = meta.get(key)
    if not isinstance(sec, dict):
        return "absent"
    return f"{len(rows.get(key, []))} rows" if sec.get("available") else "unavailable"


def _run_timings(ma: dict, mb: dict, time_rtol: float) -> list[dict]:
    pairs = [("total wall time", ma.get("total_s"), mb.get("total_s")),
             ("backend start-up", ma.get("backend_init_s"), mb.get("backend_init_s"))]
    scenes_b = {s.get("name"): s for s in mb.get("scenes", [])}
    for s in ma.get("scenes", []):
        t = scenes_b.get(s.get("name"))
        if t:
            pairs += [(f"scene {s['name']} · {k}", _get(s, ("timings", k)), _get(t, ("timings", k)))
                      for k in ("gbuffer_s", "color_s", "preview_s")]
    pairs += [(f"section {title}", _get(ma, (key, "seconds")), _get(mb, (key, "seconds"))) for key, title in SECTIONS]
    return [{"what": w, "a": x, "b": y} for w, x, y in pairs if _num(x) and _num(y) and not _close(x, y, time_rtol)]


# ------------------------------------------------------------------------------------------ output
def _table(headers: list[str], rows: list[list[str]]) -> list[str]:
    w = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(headers)]
    line = lambda r: "  ".join(c.ljust(w[i]) for i, c in enumerate(r)).rstrip()   # noqa: E731
    return [line(headers), line(["-" * x for x in w])] + [line(r) for r in rows]


def _views(c: dict) -> dict:
    """Row lists of every table, shared by the text, Markdown and HTML versions."""
    pct = lambda x: "–" if x is None else f"{x:+.2%}"               # noqa: E731
    sec = lambda x: f"{x:.3f}"                                      # noqa: E731
    return {"metadata": [[("* " if m["changed"] else "") + m["what"], m["a"], m["b"]] for m in c["metadata"]],
            "sections": [[("* " if s["changed"] else "") + s["what"], s["a"], s["b"]] for s in c["sections"]],
            "results": [[r["row"], r["field"], r["a"], r["b"], pct(r["rel"])] for r in c["results"]],
            "timings": [[t["what"], sec(t["a"]), sec(t["b"]),
                         "–" if t["ratio"] is None else f"×{t['ratio']:.2f}"] for t in c["timings"]]}


_HEAD = {"metadata": ["metadata", "A", "B"], "sections": ["section", "A", "B"],
         "results": ["row", "field", "A", "B", "Δ rel"], "timings": ["timing (s)", "A", "B", "B/A"]}


def _headline(c: dict) -> str:
    return (f"{c['rows_compared']} rows in both runs, {c['rows_compared'] - c['rows_unchanged']} changed beyond "
            f"rtol {c['rtol']:g} ({len(c['results'])} fields); {len(c['added'])} only in B, {len(c['removed'])} "
            f"only in A; {len(c['timings'])} timings changed by more than {c['time_rtol']:.0%}.")


def to_text(c: dict) -> str:
    """The comparison as aligned plain text (``*`` marks a changed line)."""
    v, out = _views(c), [f"ssbench report comparison: A = {c['a']}  vs  B = {c['b']}", _headline(c)]
    for name in ("metadata", "sections", "results", "timings"):
        if v[name]:
            out += [""] + _table(_HEAD[name], v[name])
    for label, keys in (("only in B", c["added"]), ("only in A", c["removed"])):
        out += [""] + [f"{label}: {k}" for k in keys] if keys else []
    return "\n".join(out) + "\n"


def to_markdown(c: dict) -> str:
    """The comparison as Markdown (``compare.md``)."""
    v = _views(c)
    out = [f"# ssbench report comparison: {c['a']} vs {c['b']}", "", f"A: `{c['a_path']}`  ", f"B: `{c['b_path']}`",
           "", _headline(c)]
    for name in ("metadata", "sections", "results", "timings"):
        if v[name]:
            h = _HEAD[name]
            out += ["", "| " + " | ".join(h) + " |", "|" + "---|" * len(h)]
            out += ["| " + " | ".join(x.replace("|", "/") for x in r) + " |" for r in v[name]]
    for label, keys in (("Only in B", c["added"]), ("Only in A", c["removed"])):
        out += ["", f"## {label}", ""] + [f"- {k}" for k in keys] if keys else []
    return "\n".join(out) + "\n"


def write_comparison(c: dict, root: str) -> str:
    """Write ``compare.md``/``compare.html``/``compare.json`` into ``root/compare-<A>-vs-<B>/`` (temp + rename)."""
    import jinja2
    safe = lambda s: re.sub(r"[^A-Za-z0-9_.-]+", "_", s)            # noqa: E731
    dest = os.path.join(root, f"compare-{safe(c['a'])}-vs-{safe(c['b'])}")
    os.makedirs(root, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=".compare-new-", dir=root)
    try:
        env = jinja2.Environment(loader=jinja2.FileSystemLoader(os.path.join(os.path.dirname(__file__), "templates")),
                                 autoescape=True, undefined=jinja2.StrictUndefined)
        html = env.get_template("compare.html.j2").render(c=c, v=_views(c), head=_HEAD, headline=_headline(c))
        for name, text in (("compare.md", to_markdown(c)), ("compare.html", html),
                           ("compare.json", json.dumps(c, indent=2, default=str) + "\n")):
            with open(os.path.join(tmp, name), "w", encoding="utf-8") as f:
                f.write(text)
        os.chmod(tmp, 0o777 & ~umask())                     # mkdtemp's 0o700 → a normal directory
        replace_dir(tmp, dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return dest


def cmd_compare(args, parser) -> int:
    """``ssbench report --compare RUN_A RUN_B``: print the comparison and write it under ``--out``."""
    building = [d for d, v in vars(args).items() if d not in ("command", "out", "compare", "rtol", "time_rtol",
                                                              "report_parser", "compile")   # compile: global
                and v != parser.get_default(d)]
    if building:
        parser.error("--compare cannot be combined with report-building options "
                     f"({', '.join('--' + d.replace('_', '-') for d in building)})")
    root = os.path.abspath(args.out)
    runs = [load_run(resolve_run(s, root, label)) for s, label in zip(args.compare, ("RUN_A", "RUN_B"))]
    c = compare_runs(*runs, rtol=args.rtol, time_rtol=args.time_rtol)
    print(to_text(c), end="")
    print(f"\nwritten: {os.path.join(write_comparison(c, root), 'compare.html')}")
    return 0
