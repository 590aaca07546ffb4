"""SSR marchers at equal depth-read budgets: what each traversal gets right for the same number of reads.

A march's cost on a GPU is mostly its depth reads, so the fair comparison of a linear march, a DDA and a Hi-Z
traversal gives each the same read budget ``N`` per ray, at the shared equal settings (ray length and thickness
scaled to the scene, :func:`ssbench.evaluate.equal_settings`), and counts the per-pixel classes against the exact
mirror hit (:mod:`ssbench.metrics.ssr`). Each SSR method declares, beside its code, the parameter that caps its
reads and the settings that make every read count (``READ_BUDGET = (param, fixed)``, e.g. the DDA fits its stride
so ``N`` samples span the ray and refines nothing); methods that declare none are left out. With ``back_faces``
the marchers that support layered depth (linear, DDA, Hi-Z) test each texel as a slab down to its back face
(``back_z``), so the thickness models can be compared at equal reads too.
"""
from __future__ import annotations

from typing import Iterable, Optional

__all__ = ["READ_BUDGETS", "read_budget", "layered", "budget_params", "equal_read_rows", "equal_read_table"]

#: the read budgets compared by default (reads per ray)
READ_BUDGETS = (8, 32, 128)
#: (row key, label) of the classes shown
CLASSES = (("frac_correct", "correct"), ("frac_missed", "missed"), ("frac_false_hit", "false"),
           ("frac_punch_through", "punch-through"))


def read_budget(method: str) -> Optional[tuple[str, dict]]:
    """``(param, fixed)`` that SSR ``method`` declares as ``READ_BUDGET``, or ``None``."""
    from ..passes import declared, ssr_method
    decl = declared(ssr_method(method)[0], "READ_BUDGET")
    if decl is None:
        return None
    param, fixed = decl
    return str(param), dict(fixed)


def layered(method: str) -> bool:
    """Whether SSR ``method`` can test against layered depth (its parameters have ``use_back_face_depth``)."""
    import dataclasses

    from ..passes import ssr_method
    return any(f.name == "use_back_face_depth" for f in dataclasses.fields(ssr_method(method)[1]))


def budget_params(method: str, budget: int, gbuffer, back_faces: bool = False) -> dict:
    """The overrides that run ``method`` with ``budget`` reads per ray at the equal settings of ``gbuffer``;
    ``back_faces``: with layered depth (each texel a slab down to ``back_z``, plus the equal thickness)."""
    from ..evaluate import equal_settings
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 1:
        raise ValueError(f"budget: must be a positive integer, got {budget!r}")
    decl = read_budget(method)
    if decl is None:
        raise ValueError(f"method: {method!r} declares no READ_BUDGET in its module")
    param, fixed = decl
    if back_faces and not layered(method):
        raise ValueError(f"method: {method!r} has no layered depth (use_back_face_depth)")
    extra = {"use_back_face_depth": True} if back_faces else {}
    return {**equal_settings(method, gbuffer), **fixed, **extra, param: budget}


def equal_read_rows(scene, gbuffer, truth, *, budgets: Iterable[int] = READ_BUDGETS,
                    methods: Optional[Iterable[str]] = None, back_faces: bool = False, progress: Optional[bool] = None,
                    **run_kw) -> list[dict]:
    """One :func:`ssbench.evaluate.run_ssr` row per method × budget on ``scene`` with its ``gbuffer`` and
    ``truth`` (reused), each with ``budget``, ``reads_mean`` (mean depth reads per reflective pixel) and
    ``back_faces``.

    ``methods`` defaults to every SSR method that declares ``READ_BUDGET`` (with ``back_faces``: those of them
    with layered depth; ``gbuffer`` then needs ``back_z``); ``run_kw`` goes to ``run_ssr`` (defaults: one
    untimed-warm-up run, no ꟻLIP, ``reflective="specular"``).
    """
    from tqdm import tqdm

    from ..evaluate import run_ssr
    from ..passes import SSR_METHODS
    names = [m for m in (SSR_METHODS if methods is None else methods) if read_budget(m) is not None
             and (layered(m) or not back_faces)]
    budgets = [int(b) for b in budgets]
    kw = {"repeats": 1, "warmup": False, "flip": False, "reflective": "specular", **run_kw}
    rows = []
    jobs = [(m, b) for b in budgets for m in names]
    for m, b in tqdm(jobs, desc="equal reads", unit="run", disable=None if progress is None else not progress):
        ev = run_ssr(scene, m, budget_params(m, b, gbuffer, back_faces), gbuffer=gbuffer, truth=truth, **kw)
        rows.append({**ev.row, "budget": b, "reads_mean": ev.row["steps_mean"], "back_faces": back_faces})
    return rows


def equal_read_table(rows: list[dict]) -> str:
    """A plain-text table of :func:`equal_read_rows` rows: scene, budget, method, reads, the four classes."""
    head = f"{'scene':<18}{'budget':>7}  {'method':<26}{'reads':>7}" + "".join(f"{label:>15}" for _, label in CLASSES)
    lines = [head]
    for r in sorted(rows, key=lambda r: (r["scene"], r["budget"])):
        name = r["method"] + (" (back faces)" if r.get("back_faces") else "")
        lines.append(f"{r['scene']:<18}{r['budget']:>7}  {name:<26}{r['reads_mean']:>7.1f}"
                     + "".join(f"{r.get(k, float('nan')):>15.1%}" for k, _ in CLASSES))
    return "\n".join(lines)
