"""Passes run without autograd's bookkeeping when no gradient can flow: :func:`autograd_free`.

Every eager torch operation passes through autograd's dispatch even when no input requires a gradient: it checks
the inputs, bumps version counters and carries the view and in-place bookkeeping. For a pass of large operations
that is noise; for the SSR marchers, whose steps run many small operations on a shrinking working set, it is a
share of the time that measures PyTorch, not the method. Under :class:`torch.inference_mode` that work is skipped.
Measured side by side at 640×360 (1 thread, heap held, the same bits): eager DDA 0.82–0.96× the time, visibility
bitmask 0.82–0.92×, three.js SSR 0.89–0.99×, linear march 0.92–0.94×, GTAO 0.94×, SSAO 0.98×; sphere tracing
0.79–0.87× (``thin_shell`` at 320×240, ``gyroid_sheet`` at 160×120); ``torch.no_grad`` alone gives nothing
(0.98–1.03×). The implicit casters take their normals by autograd: :func:`ssbench.implicit.shading.shade_hits`
leaves inference mode for that.

Tensors made under inference mode are *inference tensors*: autograd refuses to save them for a backward pass and
in-place changes to them outside inference mode. So a decorated pass hands back normal tensors: its result's
inference tensors are cloned (:func:`as_normal`). Where a gradient can flow — grad mode on and some tensor of the
arguments requiring one (:func:`wants_grad`) — the pass runs as it is, and so it does with its kernels compiled
(:mod:`ssbench.passes.compiled`: they already run without per-operation dispatch, and measured 1.01–1.04× the time
under inference mode, which also compiles them anew), inside ``torch.compile`` and when the caller is already in
inference mode (its result then stays as the caller's mode makes it).
"""
from __future__ import annotations

import dataclasses
import functools
from typing import Any, Callable

import torch

from .compiled import enabled as compiling_enabled

__all__ = ["wants_grad", "as_normal", "autograd_free"]

#: how deep :func:`wants_grad` looks into dataclasses and containers (a G-buffer's channels are one level down)
DEPTH = 3


def wants_grad(value: Any, depth: int = DEPTH) -> bool:
    """Whether ``value`` (a tensor, a dataclass such as a G-buffer or a parameter set, a tuple, list or dict of
    them, nested up to ``depth`` levels) holds a tensor that requires a gradient.

    Example:
        >>> from ssbench.camera import Camera
        >>> wants_grad((torch.ones(2), {"r": torch.ones(1, requires_grad=True)}))
        True
        >>> wants_grad(Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0))
        False
    """
    if isinstance(value, torch.Tensor):
        return value.requires_grad
    if depth == 0:
        return False
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return any(wants_grad(getattr(value, f.name), depth - 1) for f in dataclasses.fields(value))
    if isinstance(value, (tuple, list)):
        return any(wants_grad(v, depth - 1) for v in value)
    if isinstance(value, dict):
        return any(wants_grad(v, depth - 1) for v in value.values())
    return False


def as_normal(value: Any) -> Any:
    """``value`` with each inference tensor in it replaced by a normal clone (tensors, frozen dataclasses, tuples,
    lists and dicts, at any depth); anything else, normal tensors included, is returned as it is, not copied.

    Example:
        >>> with torch.inference_mode():
        ...     made = {"ao": torch.ones(2)}
        >>> made["ao"].is_inference(), as_normal(made)["ao"].is_inference()
        (True, False)
    """
    if isinstance(value, torch.Tensor):
        return value.clone() if value.is_inference() else value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        changed = {}
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            w = as_normal(v)
            if w is not v:
                changed[f.name] = w
        return dataclasses.replace(value, **changed) if changed else value
    if isinstance(value, tuple) and hasattr(value, "_fields"):                    # a named tuple
        items = [as_normal(v) for v in value]
        return value if all(a is b for a, b in zip(items, value)) else type(value)(*items)
    if isinstance(value, (tuple, list)):
        items = [as_normal(v) for v in value]
        return value if all(a is b for a, b in zip(items, value)) else type(value)(items)
    if isinstance(value, dict):
        items = {k: as_normal(v) for k, v in value.items()}
        return value if all(items[k] is value[k] for k in value) else type(value)(items)
    return value


def autograd_free(fn: Callable) -> Callable:
    """Decorator of a pass: run ``fn`` under :class:`torch.inference_mode` unless a gradient can flow through it
    (module docstring), and return its result with normal tensors (:func:`as_normal`). The same operations on
    the same values: the same bits.

    Example:
        >>> @autograd_free
        ... def double(x):
        ...     return {"y": x * 2}
        >>> y = double(torch.ones(2))["y"]
        >>> y.is_inference(), y.requires_grad
        (False, False)
        >>> double(torch.ones(2, requires_grad=True))["y"].requires_grad
        True
    """
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if (torch.is_inference_mode_enabled() or torch.compiler.is_compiling() or compiling_enabled()
                or (torch.is_grad_enabled() and (wants_grad(args) or wants_grad(kwargs)))):
            return fn(*args, **kwargs)
        with torch.inference_mode():
            out = fn(*args, **kwargs)
        return as_normal(out)
    wrapper.autograd_free = True                                 # type: ignore[attr-defined]  (tests look for it)
    return wrapper
