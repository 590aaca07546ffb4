"""What :mod:`ssbench.tune` may change: the continuous parameters of each AO method, their ranges, the baseline.

Only *continuous* parameters are tuned (:data:`SPACES`); discrete ones (sample counts, quality presets, noise)
set the cost and stay as given (``fixed``). A radius range is relative to the ground-truth radius
(``relative=True``: ``lo·R … hi·R``), every other range is absolute. The *baseline* ("default") is the pass's
defaults with ``fixed`` applied and its radius parameter set to the ground-truth radius, i.e. exactly what
``ssbench ao --radius R`` evaluates; only the pass's parameters are tuned, the ground truth never moves.

With a blur (``blur=`` one of :data:`BLUR_SPACES`, the blurs of ``ssbench ao --blur``) the objective scores the
blurred AO and the blur's continuous parameters join the space, namespaced ``blur_*`` (:data:`BLUR_SPACES`,
defaults :data:`BLUR_DEFAULTS` = the blur's own); its integer sizes (``kernel_size``, ``kernel_radius``) stay fixed.
"""
from __future__ import annotations

import dataclasses
import difflib
import math
from typing import Any, Mapping, Optional, Sequence

__all__ = ["Tunable", "SPACES", "declared_spaces",
           "BLUR_SPACES", "BLUR_DEFAULTS", "check_blur", "tunable_names", "method_parts",
           "resolve_space", "baseline", "blur_defaults", "split_values", "with_values", "coerce_fixed"]


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


def declared_spaces() -> dict[str, tuple[Tunable, ...]]:
    """Tunable parameters per AO method, as each pass module declares them in ``TUNABLE`` (``name -> (lo, hi,
    relative)``); methods that declare none are not tunable."""
    from ..passes import AO_METHODS, ao_method, declared
    out = {}
    for m in AO_METHODS:
        decl = declared(ao_method(m)[0], "TUNABLE")
        if decl:
            out[m] = tuple(Tunable(name, float(lo), float(hi), bool(rel)) for name, (lo, hi, rel) in decl.items())
    return out


#: tunable parameters per AO method (``ssbench.passes.AO_METHODS``), from each module's ``TUNABLE``
SPACES: dict[str, tuple[Tunable, ...]] = declared_spaces()


#: tunable parameters of each named blur (``ssbench.evaluate.BLUR_NAMES``), at its fixed size (box 5×5, cross-
#: bilateral radius 15, joint bilateral 5×5); ``blur_sigma_space`` is one width for both axes
BLUR_SPACES: dict[str, tuple[Tunable, ...]] = {
    "box": (),
    "cross_bilateral": (Tunable("blur_falloff", 0.0, 0.1), Tunable("blur_threshold", 0.01, 0.5)),
    "joint_bilateral": (Tunable("blur_sigma_color", 0.001, 0.05), Tunable("blur_sigma_space", 0.5, 4.0)),
}
#: the blurs' defaults (``ssbench.passes.blur``): falloff ``1/(2σ²)``, ``σ = (15 + 1)/2``
BLUR_DEFAULTS: dict[str, dict[str, float]] = {
    "box": {},
    "cross_bilateral": {"blur_falloff": 1.0 / 128.0, "blur_threshold": 0.1},
    "joint_bilateral": {"blur_sigma_color": 0.01, "blur_sigma_space": 1.5},
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


def check_blur(blur: Optional[str]) -> Optional[str]:
    """``blur`` if ``None`` or a known blur name, else ``ValueError`` listing the names."""
    if blur is not None and (not isinstance(blur, str) or blur not in BLUR_SPACES):
        raise ValueError(f"blur: unknown blur {blur!r}{_hint(str(blur), list(BLUR_SPACES))}; "
                         f"known: {', '.join(BLUR_SPACES)}")
    return blur


def _table(method: str, blur: Optional[str]) -> dict[str, Tunable]:
    method_parts(method)                                      # raises naming the known methods
    extra = BLUR_SPACES[check_blur(blur)] if blur is not None else ()
    return {t.name: t for t in SPACES[method] + extra}


def tunable_names(method: str, blur: Optional[str] = None) -> list[str]:
    """Names of the continuous parameters of ``method`` (and of ``blur``: ``blur_*``) that can be tuned."""
    return list(_table(method, blur))


def blur_defaults(blur: Optional[str]) -> dict[str, float]:
    """The ``blur_*`` defaults of ``blur`` (``{}`` without one)."""
    return dict(BLUR_DEFAULTS[check_blur(blur)]) if blur is not None else {}


def split_values(values: Mapping[str, Any]) -> tuple[dict, dict]:
    """``values`` as ``(pass values, blur_* values)``."""
    return ({k: v for k, v in values.items() if not k.startswith("blur_")},
            {k: v for k, v in values.items() if k.startswith("blur_")})


def resolve_space(method: str, gt_radius: float, names: Optional[Sequence[str]] = None,
                  bounds: Optional[Mapping[str, tuple[float, float]]] = None,
                  fixed: Optional[Mapping[str, Any]] = None, blur: Optional[str] = None
                  ) -> dict[str, tuple[float, float]]:
    """``{name: (lo, hi)}`` to search: ``names`` (default: every tunable not in ``fixed``, the ``blur_*`` ones of
    ``blur`` included) with their ranges, ``bounds`` overriding some. Unknown names raise ``ValueError`` listing
    the tunable ones."""
    table = _table(method, blur)                              # raises naming the known methods / blurs
    fixed = dict(fixed or {})
    chosen = list(dict.fromkeys(names)) if names is not None else [n for n in table if n not in fixed]
    for arg, given in (("names", chosen), ("bounds", list(bounds or {}))):
        for n in given:
            if n not in table:
                what = method + (f" with blur {blur}" if blur is not None else "")
                extra = ("" if blur is not None or not str(n).startswith("blur_") else
                         f" (blur_* parameters need a blur: {', '.join(BLUR_SPACES)})")
                raise ValueError(f"{arg}: {n!r} is not a tunable parameter of {what}{_hint(n, list(table))}; "
                                 f"tunable: {', '.join(table)}{extra}")
    clash = [n for n in chosen if n in fixed]
    if clash:
        raise ValueError(f"names: {', '.join(clash)} both fixed (params) and tuned; drop one")
    if not chosen:
        raise ValueError(f"names: nothing to tune for {method}; tunable: {', '.join(table) or 'none'}")
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
