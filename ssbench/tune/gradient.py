"""Gradient steps through a torch pass, for the parameters it is differentiable in.

The passes take frozen params dataclasses of Python floats. :func:`inject` puts 0-d tensors into such an
instance (validated first with the float values, then the fields are swapped in place of a copy), so the
pass's arithmetic on those fields stays on the autograd tape. Whether a pass is differentiable in a parameter
is *measured*, not declared: :func:`probe` runs autograd and calls a parameter differentiable when the
gradient is finite and non-zero. "No autograd path" means the output does not depend on the tensor through
differentiable operations: the pass casts it to a Python number or uses it only in
comparisons and integer indices (SSAO's kernel radius and depth range check, which only change a count). A
zero gradient means the output is piecewise constant in it (GTAO's ``sample_distribution_power`` only moves
rounded sample offsets). :func:`refine` then runs ``torch.optim.Adam`` on
those parameters, mapped to [0, 1] over their bounds and clamped there after every step.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import warnings
from typing import Callable, Mapping, Sequence

import torch

__all__ = ["inject", "probe", "refine", "RefineResult"]


def inject(params, tensors: Mapping[str, torch.Tensor]):
    """A copy of the frozen dataclass ``params`` whose fields ``tensors`` hold the given tensors.

    The copy skips ``__post_init__`` on purpose: validate the float values first (e.g. with
    :func:`dataclasses.replace`); passes must use the fields arithmetically for gradients to flow.
    """
    names = {f.name for f in dataclasses.fields(params)}
    unknown = [k for k in tensors if k not in names]
    if unknown:
        raise ValueError(f"tensors: unknown field(s) {', '.join(unknown)} of {type(params).__name__}")
    out = copy.copy(params)
    for k, t in tensors.items():
        object.__setattr__(out, k, t)
    return out


def probe(loss_fn: Callable[[dict], torch.Tensor], values: Mapping[str, float], names: Sequence[str],
          dtype: torch.dtype = torch.float64) -> dict[str, dict]:
    """Autograd gradient of ``loss_fn`` in each of ``names`` at ``values``, one parameter at a time.

    ``loss_fn({name: 0-d tensor})`` returns a 0-d tensor. Returns ``{name: {"differentiable", "grad", "why"}}``:
    differentiable when the gradient is finite and non-zero; ``why`` says what was found otherwise.
    """
    out = {}
    for n in names:
        x = torch.tensor(float(values[n]), dtype=dtype, requires_grad=True)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)           # e.g. "converting a tensor ... to a scalar"
            loss = loss_fn({n: x})
            g = (torch.autograd.grad(loss, x, allow_unused=True)[0]
                 if isinstance(loss, torch.Tensor) and loss.requires_grad else None)
        if g is None:
            out[n] = {"differentiable": False, "grad": None, "why": "no autograd path"}
        elif not bool(torch.isfinite(g)):
            out[n] = {"differentiable": False, "grad": float(g), "why": "non-finite gradient"}
        elif float(g) == 0.0:
            out[n] = {"differentiable": False, "grad": 0.0, "why": "zero gradient (piecewise constant)"}
        else:
            out[n] = {"differentiable": True, "grad": float(g), "why": ""}
    return out


@dataclasses.dataclass(frozen=True)
class RefineResult:
    """Outcome of :func:`refine`: the best point seen (start included), its loss, and every step's
    ``{"values", "loss"}``."""

    best: dict
    value: float
    history: list


def refine(loss_fn: Callable[[dict], torch.Tensor], start: Mapping[str, float], names: Sequence[str],
           bounds: Mapping[str, tuple], *, steps: int = 10, lr: float = 0.05,
           dtype: torch.dtype = torch.float32) -> RefineResult:
    """``steps`` Adam steps on ``loss_fn`` over ``names`` from ``start`` (other parameters stay at ``start``).

    Each parameter is optimised as ``u ∈ [0, 1]`` with ``x = lo + u·(hi − lo)`` (so ``lr`` is a fraction of
    its range) and clamped to [0, 1] after each step. ``loss_fn`` gets ``{name: 0-d tensor}`` for ``names`` only.
    The loss is evaluated ``steps + 1`` times; the lowest seen (the start included) is returned.
    """
    for arg, v, ok in (("steps", steps, isinstance(steps, int) and steps >= 0),
                       ("lr", lr, isinstance(lr, (int, float)) and math.isfinite(lr) and lr > 0)):
        if isinstance(v, bool) or not ok:
            raise ValueError(f"{arg}: must be {'an integer >= 0' if arg == 'steps' else 'a number > 0'}, got {v!r}")
    names = list(names)
    if not names:
        raise ValueError("names: no parameter to refine")
    lo = torch.tensor([float(bounds[n][0]) for n in names], dtype=dtype)
    span = torch.tensor([float(bounds[n][1]) - float(bounds[n][0]) for n in names], dtype=dtype)
    u0 = ((torch.tensor([float(start[n]) for n in names], dtype=dtype) - lo) / span).clamp(0, 1)
    u = u0.clone().requires_grad_(True)
    opt = torch.optim.Adam([u], lr=lr)
    best, best_v, history = dict(start), math.inf, []
    for i in range(steps + 1):
        x = lo + u * span
        loss = loss_fn({n: x[j] for j, n in enumerate(names)})
        v = float(loss.detach())
        point = {**dict(start), **{n: float(x[j].detach()) for j, n in enumerate(names)}}
        history.append({"values": point, "loss": v})
        if math.isfinite(v) and v < best_v:
            best, best_v = point, v
        if i == steps or not loss.requires_grad:
            break
        opt.zero_grad()
        loss.backward()
        opt.step()
        with torch.no_grad():
            u.clamp_(0.0, 1.0)
    return RefineResult(best, best_v, history)
