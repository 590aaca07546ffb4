r"""Fixed-step ray marching, the article's baseline (progressive-tracing article, 背景 / レイキャスティング and 結果).

.. math::
    t_{n+1} = t_n + s, \qquad s = t_{far} / N, \qquad t_n \in [0, t_{far}]

The march stops at the first sign change :math:`f(t_i) \ge 0 > f(t_{i+1})` (the article's test) and
bisects the bracket (二分法による絞込み). A slab whose chord along the ray is shorter than ``s`` can fall
between two samples: the ray *punches through* (the article's right-hand image). The probability of that
depends on where the samples fall; with the same ``N`` this is the method the progressive method is compared
with (結果: "同じステップサイズでレイキャスティングを行った場合").

``jitter=True`` (an ablation, not in the article's baseline) draws ``R ~ U[0, 1)`` per pixel and samples
``0, sR, sR + s, …, sR + (N−1)s, t_far`` — exactly the progressive method's first frame without its state.

:func:`march_lattice` is the marching core shared with :mod:`.progressive` (primary and secondary
rays): it works on flat lists of arbitrary rays.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...indices import flat_nonzero
from ..common import make_generator
from .common import (HIT, MISS, ImplicitResult, as_rays, bisect, check_stateless, check_surface, finish, flat)
from ..inference import autograd_free
from ..registry import Method, SpeedPanel

__all__ = ["METHOD", "FixedStepParams", "fixed_step", "march_lattice", "FixedStep"]


def check_int(value, name: str, lo: int) -> None:
    """``ValueError`` naming ``name`` unless ``value`` is an int ``>= lo``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise ValueError(f"{name}: must be >= {lo}, got {value!r}")


@dataclass(frozen=True)
class FixedStepParams:
    """Parameters of :func:`fixed_step`.

    Attributes:
        steps: ``N``, equal steps over ``[0, t_far]`` (``s = t_far / N``; ``N + 1`` samples).
        refine_iterations: bisection iterations on the bracket (0 = report the bracket's midpoint).
        jitter: start offset ``s·R`` with ``R ~ U[0, 1)`` per pixel (ablation; see the module docstring).
        seed: seeds the jitter when no generator is passed.
    """

    steps: int = 64
    refine_iterations: int = 20
    jitter: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        check_int(self.steps, "steps", 1)
        check_int(self.refine_iterations, "refine_iterations", 0)
        check_int(self.seed, "seed", 0)
        if not isinstance(self.jitter, bool):
            raise ValueError(f"jitter: expected a bool, got {self.jitter!r}")


def march_lattice(surface, origin: torch.Tensor, direction: torch.Tensor, offset: torch.Tensor,
                  step: torch.Tensor, count: int, last: Optional[torch.Tensor] = None):
    """Sample ``f`` along rays at ``t_0 = 0``, ``t_k = offset + (k − 1)·step`` (``k = 1..count``) and then
    ``last`` (if given), in this order, stopping each ray at its first bracket ``f(t_i) ≥ 0 > f(t_{i+1})``.

    Only rays without a bracket are evaluated at the next sample, so the evaluation count is honest.

    Args:
        surface: the surface protocol (``f``).
        origin, direction: (n, 3) rays (unit directions).
        offset, step: (n,) per-ray first lattice sample and spacing.
        count: number of lattice samples (the same for all rays).
        last: optional (n,) extra final sample (the progressive method's ``(1 + ε)t'`` probe).

    Returns:
        ``(found, lo, hi, steps)``: (n,) bool, the bracket (0 where none) and int32 samples evaluated.

    Example:
        >>> wall = lambda p: 3.0 - p[..., 0]                    # f ≥ 0 before x = 3, f < 0 beyond
        >>> from ssbench.passes.implicit.common import FunctionSurface
        >>> o, d = torch.zeros(1, 3), torch.tensor([[1.0, 0.0, 0.0]])
        >>> found, lo, hi, n = march_lattice(FunctionSurface(wall), o, d, torch.ones(1), torch.ones(1), 8)
        >>> found.item(), lo.item(), hi.item(), n.item()
        (True, 3.0, 4.0, 5)
    """
    n = origin.shape[0]
    dev = origin.device
    total = count + (1 if last is not None else 0)
    found = torch.zeros(n, dtype=torch.bool, device=dev)
    lo, hi = origin.new_zeros(n), origin.new_zeros(n)
    steps = torch.full((n,), total + 1, dtype=torch.int32, device=dev)   # t_0 and every sample: no bracket
    ids = torch.arange(n, device=dev)
    o, d, off, st, la = origin, direction, offset, step, last             # the rays still marching (compacted)
    t_prev = origin.new_zeros(n)
    f_prev = surface.f(origin)                                        # t_0 = 0, the ray origin
    for k in range(1, total + 1):
        if ids.numel() == 0:
            break
        t_k = off + (k - 1) * st if k <= count else la
        f_k = surface.f(o + t_k.unsqueeze(-1) * d)
        br = (f_prev >= 0) & (f_k < 0)
        done = flat_nonzero(br)                                       # integer indices: one nonzero per step
        if done.numel():
            sel = ids.index_select(0, done)
            found[sel], lo[sel], hi[sel] = True, t_prev.index_select(0, done), t_k.index_select(0, done)
            steps[sel] = k + 1                                        # t_0 and samples 1..k
            keep = flat_nonzero(~br)
            ids, o, d, off, st, t_k, f_k = (x.index_select(0, keep) for x in (ids, o, d, off, st, t_k, f_k))
            la = la.index_select(0, keep) if la is not None else None
        t_prev, f_prev = t_k, f_k
    return found, lo, hi, steps


@autograd_free
def fixed_step(surface, camera, params: FixedStepParams = FixedStepParams(), *, state: None = None,
               generator: Optional[torch.Generator] = None, jitter: Optional[torch.Tensor] = None,
               dtype: Optional[torch.dtype] = None, device=None) -> ImplicitResult:
    r"""Fixed-step march over ``[0, t_far]`` with ``N`` steps, first sign change, bisection (progressive-tracing article, 背景).

    Args:
        surface: the surface protocol (``f``, ``f_and_grad``, ``object_index``).
        camera: a :class:`~ssbench.camera.Camera` or :class:`~.common.CameraRays` with
            :math:`(B, 3, H, W)` rays.
        params: :class:`FixedStepParams`.
        state: must be ``None`` (the march keeps nothing between frames; the implicit casters share one call).
        generator: draws ``R`` when ``params.jitter`` (default: CPU generator seeded with ``params.seed``).
        jitter: optional :math:`(B, 2, 1, 1)` or :math:`(B, 2, H, W)` sub-pixel camera offsets (with a Camera).
        dtype, device: of the rays built from a Camera (default float32).

    Returns:
        :class:`~.common.ImplicitResult`; ``evaluations`` = samples + bisection + 1 gradient on hits;
        ``debug["bracket"]`` :math:`(B, 2, H, W)`, ``debug["R"]`` (the jitter, or None).

    Example:
        >>> from ssbench.camera import Camera
        >>> from ssbench.passes.implicit.common import FunctionSurface
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 45.0, 8, 6, 0.1, 10.0)
        >>> ball = FunctionSurface(lambda p: p.norm(dim=-1) - 1.0)
        >>> r = fixed_step(ball, cam, FixedStepParams(steps=64), dtype=torch.float64)
        >>> r.t.shape, int(r.hit.sum()), int(r.evaluations.max())        # a miss evaluates all N + 1 samples
        (torch.Size([1, 1, 6, 8]), 12, 65)
    """
    check_surface(surface)
    check_stateless(state, "fixed_step")
    if not isinstance(params, FixedStepParams):
        raise TypeError(f"params: expected FixedStepParams, got {type(params).__name__}")
    rays = as_rays(camera, jitter, dtype, device)
    B, _, H, W = rays.direction.shape
    o, d, t_far = flat(rays.origin), flat(rays.direction), flat(rays.t_far).squeeze(1)
    N = params.steps
    s = t_far / N
    R = None
    if params.jitter:
        R = torch.rand(B, 1, H, W, generator=make_generator(params.seed, generator), dtype=torch.float64)
        R = R.to(dtype=o.dtype, device=o.device)
        found, lo, hi, steps = march_lattice(surface, o, d, s * flat(R).squeeze(1), s, N, last=t_far)
    else:
        found, lo, hi, steps = march_lattice(surface, o, d, s, s, N)
    h = flat_nonzero(found)
    lo[h], hi[h] = bisect(surface, o[h], d[h], lo[h], hi[h], params.refine_iterations)
    evaluations = steps + found.to(torch.int32) * params.refine_iterations
    term = torch.where(found, HIT, MISS).to(torch.int8)
    dbg = {"bracket": torch.stack([lo, hi], 1).reshape(B, H, W, 2).permute(0, 3, 1, 2).contiguous(), "R": R}
    return finish((B, H, W), origin=o, direction=d, t_far=t_far, surface=surface, hit=found, t=0.5 * (lo + hi),
                  evaluations=evaluations, steps=steps, termination=term, debug=dbg)


class FixedStep(nn.Module):
    """``nn.Module`` wrapper of :func:`fixed_step`; ``forward(surface, camera)`` returns its result."""

    def __init__(self, params: FixedStepParams = FixedStepParams()) -> None:
        super().__init__()
        self.params = params

    def forward(self, surface, camera, generator: Optional[torch.Generator] = None,
                jitter: Optional[torch.Tensor] = None) -> ImplicitResult:
        return fixed_step(surface, camera, self.params, generator=generator, jitter=jitter)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("fixed", fixed_step, FixedStepParams, FixedStep, order=10, title="fixed-step march + bisection")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"frames": [{"steps": [16, 64], "jitter": True}], "static": [{"steps": [16, 64]}]}
SPEED_PANELS = (SpeedPanel("punch", "steps"),
                SpeedPanel("punch", "frame", (("jitter", True),), metric="punch_through_per_frame"))
