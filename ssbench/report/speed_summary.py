"""The speed section in words: its lines of the report's at-a-glance table and its part of ``summary.md``, both
read from the section's metadata (:func:`ssbench.report.speed_section.build_speed_section`), so a re-render
(``--from``) computes nothing."""
from __future__ import annotations

from .ao_section import fmt

__all__ = ["glance_lines", "summary_md"]


#: the ground truth's cost knob in words, by the equal-error ladder's kind (ssbench.analysis.equal_error)
_GT_WORDS = {"rays": "ray-traced AO at {n} rays/px", "spp": "the path-traced reflection at {n} spp",
             "steps": "a dense fixed-step march of {n} steps"}


def glance_lines(speed: dict) -> list[dict]:
    """Lines of the report's at-a-glance table, in words: per effect and method, the size the sweeps ran at, the
    error of its best configuration on each scene, what ground truth is as good (the equal-error cost), and the
    mean time of those configurations in seconds (``{method, headline, seconds, scenes}``; ``method`` is the
    registry key, so the table can name it in words)."""
    out = []
    for e in speed["effects"]:
        if not e.get("available"):
            continue
        eq = {(q["scene"], q["method"]): q for q in e["equal_error"]}
        for m in dict.fromkeys(s["method"] for s in e["summary"]):
            mine = [s for s in e["summary"] if s["method"] == m]
            errs = ", ".join(f"{s['scene']} {s['error']}" for s in mine)
            same = [(s["scene"], eq[(s["scene"], m)]) for s in mine if (s["scene"], m) in eq]
            gt = "; ".join(f"{scene}: " + _GT_WORDS.get(q["kind"], "{n} " + q["kind"]).format(n=q["n_text"])
                           for scene, q in same)
            out.append({"method": m, "scenes": len(mine),
                        "headline": f"{e.get('title', e['name'])} at {speed.get('size', '?')}, best configuration: "
                                    f"{e['metric']} {errs}" + (f" · as good as {gt}" if gt else ""),
                        "seconds": fmt(sum(s["time_s"] for s in mine) / len(mine), "{:.4f}")})
    return out


def summary_md(speed: dict) -> str:
    """The speed section of ``summary.md``: per effect the best configuration of each method, then equal error."""
    lines = ["", "## Speed against error", ""]
    if not speed.get("available"):
        return "\n".join(lines + [speed.get("note") or "Speed section unavailable."]
                         + [f"- {e['note']}" for e in speed.get("effects", []) if e.get("note")]) + "\n"
    lines.append(f"Sweeps at {speed['size']}, passes on {speed['threads']} torch thread(s), ground truth on "
                 f"{speed.get('gt_threads') or '?'} Dr.Jit thread(s); section {speed['seconds']:.1f} s. "
                 "Time: ms per call of the pass (median over interleaved rounds; AO blur included); overview timings "
                 "(a few short rounds in one process; a sweep's default pools 3 processes).")
    for e in speed["effects"]:
        lines += ["", f"### {e['title']}", ""]
        if not e["available"]:
            lines.append(e["note"])
            continue
        lines += [f"{e['rows']} configurations ({e['errors']} failed); rows: `{e['files']['jsonl']}`. "
                  f"Best configuration per method by {e['metric']}:", "",
                  "| scene | method | best config | error | time ms | floor ratio | on front |",
                  "|---|---|---|---:|---:|---:|---|"]
        lines += [f"| {s['scene']} | {s['method']} | {s['config']} | {s['error']} | {s['time']} | "
                  f"{s['floor_ratio']} | {s['front']} |" for s in e["summary"]]
        if e["equal_error"]:
            k = e["equal_error"][0]["kind"]
            lines += ["", f"Equal-error cost ({e['eq_metric']}; ground-truth {k} reaching the same error):", "",
                      f"| scene | method | best config | error | time ms | GT {k} | GT ms | GT / method time |",
                      "|---|---|---|---:|---:|---:|---:|---:|"]
            lines += [f"| {q['scene']} | {q['method']} | {q['config']} | {q['error']} | {q['time_ms']} | "
                      f"{q['n_text']} | {q['gt_ms']} | {q['ratio']} |" for q in e["equal_error"]]
        lines += [f"- {n}" for n in e["notes"]]
    return "\n".join(lines) + "\n"
