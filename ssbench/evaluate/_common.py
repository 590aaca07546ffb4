"""Helpers shared by the evaluation rows: parameter resolution, timing, float conversion."""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Callable, Mapping, Union

import torch

__all__ = ["resolve_params"]


def resolve_params(params_cls: type, params: Union[None, Mapping[str, Any], Any] = None, method: str = "method"):
    """A ``params_cls`` instance from ``None`` (defaults), an instance, or a dict of overrides.

    Overrides go through :func:`dataclasses.replace`, so the class's own validation runs; an unknown name
    raises ``ValueError`` naming it.
    """
    if params is None:
        return params_cls()
    if isinstance(params, params_cls):
        return params
    if isinstance(params, Mapping):
        known = [f.name for f in dataclasses.fields(params_cls)]
        unknown = [k for k in params if k not in known]
        if unknown:
            raise ValueError(f"params: unknown parameter(s) {', '.join(map(repr, unknown))} for {method} "
                             f"({params_cls.__name__}); known: {', '.join(known)}")
        return dataclasses.replace(params_cls(), **dict(params))
    raise TypeError(f"params: expected None, a dict or a {params_cls.__name__}, got {type(params).__name__}")


def params_as_dict(p) -> dict:
    """The fields of parameter dataclass ``p`` as a dict (tuples as lists): its own fields first, then the
    keyword-only ones it inherits (e.g. the SSR fades of ``FadeParams``)."""
    out = {}
    for f in sorted(dataclasses.fields(p), key=lambda f: bool(f.kw_only)):
        v = getattr(p, f.name)
        out[f.name] = list(v) if isinstance(v, tuple) else v
    return out


def as_float(x) -> float:
    return float(x) if x is not None else math.nan


def sync_device(device) -> None:
    if torch.device(device).type == "cuda":
        torch.cuda.synchronize()


def timed_runs(call: Callable[[], Any], repeats: int, device, warmup: bool = True) -> tuple[Any, list[float]]:
    """One untimed warm-up call (unless ``warmup=False`` and the passes run eager: a compiled kernel's first call
    compiles, which is never timed, :mod:`ssbench.passes.compiled`), then ``repeats`` timed calls; returns the
    last output and the times."""
    from ..passes import compiled
    if warmup or compiled.enabled():
        call()
        sync_device(device)
    out, times = None, []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = call()
        sync_device(device)
        times.append(time.perf_counter() - t0)
    return out, times
