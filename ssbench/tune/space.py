"""What :mod:`ssbench.tune` may change: the continuous parameters of each AO method, their ranges, the baseline.

Only *continuous* parameters are tuned (:data:`SPACES`); discrete ones (sample counts, quality presets, noise)
set the cost and stay as given (``fixed``). A radius range is relative to the ground-truth radius
(``relative=True``: ``lo·R … hi·R``), every other range is absolute. The *baseline* ("default") is the pass's
defaults with ``fixed`` applied and its radius parameter set to the ground-truth radius, i.e. exactly what
``ssbench ao --radius R`` evaluates; only the pass's parameters are tuned, the ground truth never moves.
"""
from __future__ import annotations

import dataclasses
import difflib
import math
from typing import Any, Mapping, Optional, Sequence

__all__ = ["Tunable", "SPACES", "tunable_names", "method_parts", "resolve_space", "baseline", "with_values",
           "coerce_fixed"]


@dataclasses.dataclass(frozen=True)
class Tunable:
    """A continuous parameter and its search range (``relative``: multiples of the ground-truth radius)."""

    name: str
    lo: float
    hi: float
    relative: bool = False

    def bounds(self, gt_radius: float) -> tuple[float, float]:
        """``(lo, hi)`` in the parameter's units."""
        s = gt_radius if self.relative else 1.0
        return (self.lo * s, self.hi * s)


_SSAO = (Tunable("kernel_radius", 0.25, 4.0, relative=True), Tunable("min_distance", 0.0, 0.005),
         Tunable("max_distance", 0.002, 0.1), Tunable("strength", 0.5, 2.0))
#: tunable parameters per AO method (``ssbench.passes.AO_METHODS``)
SPACES: dict[str, tuple[Tunable, ...]] = {
    "gtao": (Tunable("radius", 0.25, 3.0, relative=True), Tunable("falloff_range", 0.05, 1.0),
             Tunable("final_value_power", 0.5, 4.0)),
    "hbao": (Tunable("radius", 0.25, 3.0, relative=True), Tunable("tan_angle_bias", 0.0, 1.0),
             Tunable("ao_strength", 0.5, 2.5)),
    "ssao": _SSAO,
    "crytek": _SSAO,
}


def _hint(name: str, valid: Sequence[str]) -> str:
    close = difflib.get_close_matches(str(name), list(valid), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def method_parts(method: str):
    """``(function, ParamsClass, REQUIRES, module)`` of an AO method; ``ValueError`` listing the known ones."""
    import importlib
    from ..passes import AO_METHODS, ao_method
    if method not in AO_METHODS or method not in SPACES:
        known = [m for m in AO_METHODS if m in SPACES]
        raise ValueError(f"method: unknown AO method {method!r}{_hint(method, known)}; known: {', '.join(known)}")
    fn, cls, requires = ao_method(method)
    return fn, cls, tuple(requires), importlib.import_module(fn.__module__)


def tunable_names(method: str) -> list[str]:
    """Names of the continuous parameters of ``method`` that can be tuned."""
    method_parts(method)
    return [t.name for t in SPACES[method]]


def resolve_space(method: str, gt_radius: float, names: Optional[Sequence[str]] = None,
                  bounds: Optional[Mapping[str, tuple[float, float]]] = None,
                  fixed: Optional[Mapping[str, Any]] = None) -> dict[str, tuple[float, float]]:
    """``{name: (lo, hi)}`` to search: ``names`` (default: every tunable not in ``fixed``) with their ranges,
    ``bounds`` overriding some. Unknown names raise ``ValueError`` listing the tunable ones."""
    table = {t.name: t for t in SPACES[method]} if method in SPACES else None
    if table is None:
        method_parts(method)                                  # raises naming the known methods
    fixed = dict(fixed or {})
    chosen = list(dict.fromkeys(names)) if names is not None else [n for n in table if n not in fixed]
    for arg, given in (("names", chosen), ("bounds", list(bounds or {}))):
        for n in given:
            if n not in table:
                raise ValueError(f"{arg}: {n!r} is not a tunable parameter of {method}{_hint(n, list(table))}; "
                                 f"tunable: {', '.join(table)}")
    clash = [n for n in chosen if n in fixed]
    if clash:
        raise ValueError(f"names: {', '.join(clash)} both fixed (params) and tuned; drop one")
    if not chosen:
        raise ValueError(f"names: nothing to tune for {method}; tunable: {', '.join(table)}")
    out = {}
    for n in chosen:
        lo, hi = (bounds or {}).get(n, table[n].bounds(gt_radius))
        if not (isinstance(lo, (int, float)) and isinstance(hi, (int, float)) and math.isfinite(lo)
                and math.isfinite(hi) and lo < hi):
            raise ValueError(f"bounds: {n} needs finite lo < hi, got ({lo!r}, {hi!r})")
        out[n] = (float(lo), float(hi))
    return out


def coerce_fixed(method: str, fixed: Optional[Mapping[str, Any]]) -> dict:
    """``fixed`` checked against the method's params dataclass: known names (``ValueError`` listing them) and
    ints widened to float for float fields."""
    _, cls, _, _ = method_parts(method)
    defaults = cls()
    known = {f.name: getattr(defaults, f.name) for f in dataclasses.fields(cls)}
    out = {}
    for k, v in (fixed or {}).items():
        if k not in known:
            raise ValueError(f"params: unknown parameter {k!r} for {method}{_hint(k, list(known))}; "
                             f"known: {', '.join(known)}")
        d = known[k]
        out[k] = float(v) if isinstance(d, float) and isinstance(v, int) and not isinstance(v, bool) else v
    return out


def baseline(method: str, gt_radius: float, fixed: Optional[Mapping[str, Any]] = None):
    """The "default" configuration: the pass's defaults, ``fixed`` applied, its radius set to ``gt_radius``
    (unless ``fixed`` sets the radius itself)."""
    from ..evaluate import radius_param
    _, cls, _, module = method_parts(method)
    if isinstance(gt_radius, bool) or not isinstance(gt_radius, (int, float)) or not gt_radius > 0 \
            or not math.isfinite(gt_radius):
        raise ValueError(f"gt_radius: must be a finite number > 0, got {gt_radius!r}")
    values = coerce_fixed(method, fixed)
    rname = radius_param(cls, module)
    if rname is not None and rname not in values:
        values[rname] = float(gt_radius)
    return dataclasses.replace(cls(), **values)


def with_values(params, values: Mapping[str, float]):
    """``params`` with the tuned ``values`` (floats) set; the dataclass validates them (``ValueError``)."""
    return dataclasses.replace(params, **{k: float(v) for k, v in values.items()})
