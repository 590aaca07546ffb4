"""Grid values of a sweep file: ranges, log ranges, lists; type coercion to a parameter's field type; the
:class:`SweepError` and its ``file:line: field: message`` context (the scene files' ``Ctx``, reused)."""
from __future__ import annotations

import dataclasses
import difflib
import json
import math
import typing
from typing import Any, Optional

from ..scenes.schema import Ctx, path_str

__all__ = ["SweepError", "expand_range", "expand_logrange", "MAX_GRID"]

#: most values one grid may expand to (a typo like ``range: [0, 1000000, 1]`` is an error, not a hang)
MAX_GRID = 10_000


class SweepError(ValueError):
    """A sweep file is invalid; the message starts with ``file:line:``."""


class SweepCtx(Ctx):
    def fail(self, path: tuple, msg: str) -> SweepError:  # type: ignore[override]
        return SweepError(f"{self.locate(path)}: {path_str(path)}: {msg}")


def _g12(x: float) -> float:
    return float(f"{x:.12g}")


def expand_range(start, stop, step) -> list:
    """Arithmetic grid from ``start`` to ``stop`` *inclusive* by ``step`` (ints stay ints).

    Example:
        >>> expand_range(4, 16, 4), expand_range(0.1, 0.3, 0.1), expand_range(3, 1, -1)
        ([4, 8, 12, 16], [0.1, 0.2, 0.3], [3, 2, 1])
    """
    if step == 0 or (stop - start) * step < 0:
        raise ValueError(f"step {step!r} does not lead from {start!r} to {stop!r}")
    n = int(math.floor((stop - start) / step + 1e-9)) + 1
    if n > MAX_GRID:
        raise ValueError(f"{n} values (more than {MAX_GRID}); use a larger step")
    if all(isinstance(v, int) for v in (start, stop, step)):
        return [start + i * step for i in range(n)]
    return [_g12(start + i * step) for i in range(n)]


def expand_logrange(lo, hi, n: int) -> list[float]:
    """``n`` geometrically spaced values from ``lo`` to ``hi``, both included.

    Example:
        >>> expand_logrange(1, 100, 3)
        [1.0, 10.0, 100.0]
    """
    if not (lo > 0 and hi > 0):
        raise ValueError(f"bounds must be > 0, got {lo!r}, {hi!r}")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"the count must be an integer >= 1, got {n!r}")
    if n > MAX_GRID:
        raise ValueError(f"{n} values (more than {MAX_GRID})")
    if n == 1:
        return [float(lo)]
    return [_g12(lo * (hi / lo) ** (i / (n - 1))) for i in range(n)]


# ------------------------------------------------------------------------------------------ grids
def field_kinds(params_cls: type) -> dict[str, tuple[Optional[type], bool]]:
    """``name -> (base type or None for 'anything', nullable)`` from the dataclass's type hints."""
    try:
        hints = typing.get_type_hints(params_cls)
    except Exception:                                       # pragma: no cover - unresolvable annotations
        hints = {}
    out = {}
    for f in dataclasses.fields(params_cls):
        h = hints.get(f.name, Any)
        args = typing.get_args(h)
        nullable = typing.get_origin(h) is typing.Union and type(None) in args
        if nullable:
            rest = [a for a in args if a is not type(None)]
            h = rest[0] if len(rest) == 1 else Any
        out[f.name] = (h if h in (bool, int, float, str) else None, nullable)
    return out


def coerce_value(c: SweepCtx, v: Any, kind: tuple, path: tuple) -> Any:
    base, nullable = kind
    if v is None:
        if nullable or base is None:
            return None
        raise c.fail(path, "must not be null")
    if base is bool and not isinstance(v, bool):
        raise c.fail(path, f"expected true or false, got {v!r}")
    if base is int:
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            raise c.fail(path, f"expected an integer, got {v!r}")
    if base is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise c.fail(path, f"expected a number, got {v!r}")
        v = float(v)
    if isinstance(v, float) and not math.isfinite(v):
        raise c.fail(path, f"must be finite, got {v!r}")
    if base is str and not isinstance(v, str):
        raise c.fail(path, f"expected a string, got {v!r}")
    return v


def grid_values(c: SweepCtx, v: Any, path: tuple, check) -> list:
    """Values of a grid: a scalar, a list, ``{range: [a, b, step]}``, ``{logrange: [lo, hi, n]}`` or
    ``{values: [...]}``; ``check(value, path)`` validates and coerces each value."""
    if isinstance(v, dict):
        if len(v) != 1 or next(iter(v)) not in ("range", "logrange", "values"):
            raise c.fail(path, f"a grid mapping has one key of range, logrange, values; got {sorted(v)}")
        (form, args), = v.items()
        p = path + (form,)
        if form == "values":
            if not isinstance(args, list):
                raise c.fail(p, f"expected a list of values, got {args!r}")
            vals = list(args)
        else:
            if not isinstance(args, list) or len(args) != 3 or any(
                    isinstance(a, bool) or not isinstance(a, (int, float)) for a in args):
                what = "start, stop, step" if form == "range" else "lo, hi, n"
                raise c.fail(p, f"expected [{what}] (three numbers), got {args!r}")
            try:
                vals = expand_range(*args) if form == "range" else expand_logrange(*args)
            except ValueError as e:
                raise c.fail(p, str(e)) from None
            if form == "logrange" and getattr(check, "integer", False):
                vals = list(dict.fromkeys(int(round(x)) for x in vals))
        vals = [check(x, p) for x in vals]
    elif isinstance(v, list):
        vals = [check(x, path + (i,)) for i, x in enumerate(v)]
    else:
        vals = [check(v, path)]
    if not vals:
        raise c.fail(path, "empty grid (give at least one value)")
    return dedupe(vals)


def dedupe(vals: list) -> list:
    seen, out = set(), []
    for x in vals:
        key = json.dumps(x, sort_keys=True)
        if key not in seen:
            seen.add(key)
            out.append(x)
    return out


def names_hint(name: str, valid) -> str:
    close = difflib.get_close_matches(str(name), list(valid), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""
