"""SSR marchers at equal depth-read budgets: what each traversal gets right for the same number of reads.

A march's cost on a GPU is mostly its depth reads, so the fair comparison of a linear march, a DDA and a Hi-Z
traversal gives each the same read budget ``N`` per ray, at the shared equal settings (ray length and thickness
scaled to the scene, :func:`ssbench.evaluate.equal_settings`), and counts the per-pixel classes against the exact
mirror hit (:mod:`ssbench.metrics.ssr`). Each SSR method declares, beside its code, the parameter that caps its
reads and the settings that make every read count (``READ_BUDGET = (param, fixed)``, e.g. the DDA fits its stride
so ``N`` samples span the ray and refines nothing); methods that declare none are left out. With ``layers`` the
marchers that support layered depth test each texel as a slab down to its back face (``"back_faces"``: linear,
DDA, Hi-Z) or also test the surface behind it (``"second_layer"``: DDA, Hi-Z), so the depth models can be
compared at equal reads too.
"""
from __future__ import annotations

from typing import Iterable, Optional

__all__ = ["READ_BUDGETS", "LAYERS", "read_budget", "layered", "budget_params", "equal_read_rows", "equal_read_table"]

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


#: the depth models of a comparison: layer name -> the parameter that turns it on (None: the front depth alone)
LAYERS = {"front": None, "back_faces": "use_back_face_depth", "second_layer": "use_second_layer"}


def layered(method: str, layers: str = "back_faces") -> bool:
    """Whether SSR ``method`` supports the depth model ``layers`` (:data:`LAYERS`: its parameters have the field)."""
    import dataclasses

    from ..passes import ssr_method
    field = LAYERS[layers]
    return field is None or any(f.name == field for f in dataclasses.fields(ssr_method(method)[1]))


def budget_params(method: str, budget: int, gbuffer, layers: str = "front") -> dict:
    """The overrides that run ``method`` with ``budget`` reads per ray at the equal settings of ``gbuffer``, with
    the depth model ``layers``: ``"front"`` (the depth buffer), ``"back_faces"`` (each texel a slab down to
    ``back_z``, plus the equal thickness) or ``"second_layer"`` (also the surface behind the first, ``second_z``)."""
    if layers not in LAYERS:
        raise ValueError(f"layers: expected one of {tuple(LAYERS)}, got {layers!r}")
    from ..evaluate import equal_settings
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < 1:
        raise ValueError(f"budget: must be a positive integer, got {budget!r}")
    decl = read_budget(method)
    if decl is None:
        raise ValueError(f"method: {method!r} declares no READ_BUDGET in its module")
    param, fixed = decl
    if not layered(method, layers):
        raise ValueError(f"method: {method!r} has no layered depth of kind {layers!r} ({LAYERS[layers]})")
    extra = {LAYERS[layers]: True} if LAYERS[layers] else {}
    return {**equal_settings(method, gbuffer), **fixed, **extra, param: budget}


def equal_read_rows(scene, gbuffer, truth, *, budgets: Iterable[int] = READ_BUDGETS,
                    methods: Optional[Iterable[str]] = None, layers: str = "front", progress: Optional[bool] = None,
                    **run_kw) -> list[dict]:
    """One :func:`ssbench.evaluate.run_ssr` row per method × budget on ``scene`` with its ``gbuffer`` and
    ``truth`` (reused), each with ``budget``, ``reads_mean`` (mean depth reads per reflective pixel) and
    ``layers``.

    ``methods`` defaults to every SSR method that declares ``READ_BUDGET`` (with ``layers`` other than
    ``"front"``: those of them that support it; ``gbuffer`` then needs ``back_z`` / ``second_z``); ``run_kw``
    goes to ``run_ssr`` (defaults: one untimed-warm-up run, no ꟻLIP, ``reflective="specular"``).
    """
    from tqdm import tqdm

    from ..evaluate import run_ssr
    from ..passes import SSR_METHODS
    names = [m for m in (SSR_METHODS if methods is None else methods) if read_budget(m) is not None
             and layered(m, layers)]
    budgets = [int(b) for b in budgets]
    kw = {"repeats": 1, "warmup": False, "flip": False, "reflective": "specular", **run_kw}
    rows = []
    jobs = [(m, b) for b in budgets for m in names]
    for m, b in tqdm(jobs, desc="equal reads", unit="run", disable=None if progress is None else not progress):
        ev = run_ssr(scene, m, budget_params(m, b, gbuffer, layers), gbuffer=gbuffer, truth=truth, **kw)
        rows.append({**ev.row, "budget": b, "reads_mean": ev.row["steps_mean"], "layers": layers})
    return rows


def equal_read_table(rows: list[dict]) -> str:
    """A plain-text table of :func:`equal_read_rows` rows: scene, budget, method, reads, the four classes."""
    head = f"{'scene':<18}{'budget':>7}  {'method':<26}{'reads':>7}" + "".join(f"{label:>15}" for _, label in CLASSES)
    lines = [head]
    for r in sorted(rows, key=lambda r: (r["scene"], r["budget"])):
        name = r["method"] + (f" ({r['layers'].replace('_', ' ')})" if r.get("layers", "front") != "front" else "")
        lines.append(f"{r['scene']:<18}{r['budget']:>7}  {name:<26}{r['reads_mean']:>7.1f}"
                     + "".join(f"{r.get(k, float('nan')):>15.1%}" for k, _ in CLASSES))
    return "\n".join(lines)
