r"""Sphere tracing (Hart 1996) and over-relaxed sphere tracing (Keinert et al. 2014), the distance-field
baseline the article's background cites (progressive-tracing article, 背景: 距離場によるレイマーチング).

With a declared Lipschitz bound ``λ ≥ sup |∇f|``, ``|f(p)|/λ`` is the radius of a ball around ``p`` free of
the surface ("unbounding sphere"), so the step ``t += |f|/λ`` never passes the surface. A ray hits when
``|f|/λ < ε·max(t, t_near)`` (a relative test as curv's ``0.0005·t``; ``t_near`` keeps it meaningful at the
eye) and misses past ``t_far``; it is ``OUT_OF_STEPS`` after ``max_steps`` (never a silent miss).

**Over-relaxation** (Keinert): step ``ω·|f|/λ`` with ``1 ≤ ω < 2``. If the unbounding spheres of two
consecutive points no longer overlap (``r_prev + r_new < step``), the step may have skipped the surface:
step back to the previous point and continue with ``ω = 1`` for the rest of the ray.

**Overshoot.** With a *valid* λ a step from ``f ≥ 0`` cannot land at ``f < 0``. With an invalid one (the
displaced torus, whose declared λ = 1 is false) it can: we record it in ``debug["overshoot"]`` and bisect back
to the crossing instead of reporting an interior point. Rays starting inside (``f(0) < 0``) or within ε of
the surface are *unarmed*: they step ``|f|/λ + ε·t`` (always forward) and may not report a distance hit until
they are clearly outside, so only the first **entering** crossing is a hit, as for the sign-change methods.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...indices import flat_nonzero
from .common import (HIT, MISS, OUT_OF_STEPS, ImplicitResult, as_rays, bisect, check_stateless, check_surface,
                     finish, flat, unflat)
from .fixed import check_int
from ..inference import autograd_free
from ..registry import Method, SpeedPanel

__all__ = ["METHOD", "SphereTraceParams", "sphere_trace", "SphereTrace"]


@dataclass(frozen=True)
class SphereTraceParams:
    """Parameters of :func:`sphere_trace`.

    Attributes:
        lipschitz: ``λ`` (None: the surface's declared ``lipschitz``).
        omega: Keinert's relaxation ``ω`` in [1, 2) (1 = Hart's sphere tracing; 1.2–1.6 typical).
        max_steps: step budget per ray.
        epsilon: relative hit threshold, ``|f|/λ < ε·max(t, t_near)``.
        refine_iterations: bisection iterations on a crossing (overshoot or unarmed ray).
        safeguard: catch a step that lands inside (``f ≥ 0 → f < 0``) and bisect back to the crossing
            (default). ``False`` is plain Hart sphere tracing: the march goes on with ``|f|/λ`` from wherever it
            landed, so with an invalid λ it tunnels through thin features and reports the far side or a miss —
            the article's holes (progressive-tracing article, 背景), which ``safeguard=True`` hides.
    """

    lipschitz: Optional[float] = None
    omega: float = 1.0
    max_steps: int = 256
    epsilon: float = 1e-4
    refine_iterations: int = 20
    safeguard: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.safeguard, bool):
            raise ValueError(f"safeguard: must be True or False, got {self.safeguard!r}")
        if self.lipschitz is not None and (isinstance(self.lipschitz, bool) or not isinstance(
                self.lipschitz, (int, float)) or not (math.isfinite(self.lipschitz) and self.lipschitz > 0)):
            raise ValueError(f"lipschitz: must be a finite number > 0 or None, got {self.lipschitz!r}")
        if isinstance(self.omega, bool) or not isinstance(self.omega, (int, float)) or not 1 <= self.omega < 2:
            raise ValueError(f"omega: must lie in [1, 2), got {self.omega!r}")
        if isinstance(self.epsilon, bool) or not isinstance(self.epsilon, (int, float)) or not (
                0 < self.epsilon < 1):
            raise ValueError(f"epsilon: must lie in (0, 1), got {self.epsilon!r}")
        check_int(self.max_steps, "max_steps", 1)
        check_int(self.refine_iterations, "refine_iterations", 0)


@autograd_free
def sphere_trace(surface, camera, params: SphereTraceParams = SphereTraceParams(), *, state: None = None,
                 generator: Optional[torch.Generator] = None, jitter: Optional[torch.Tensor] = None,
                 dtype: Optional[torch.dtype] = None, device=None) -> ImplicitResult:
    r"""Sphere tracing with a declared Lipschitz bound, optionally over-relaxed (Hart; Keinert et al.).

    .. math::
        t_{i+1} = t_i + \omega\,\frac{|f(\vec s + t_i \vec d)|}{\lambda}

    Args:
        surface: the surface protocol (``f``, ``f_and_grad``, ``object_index``, ``lipschitz``).
        camera: a :class:`~ssbench.camera.Camera` or :class:`~.common.CameraRays`,
            :math:`(B, 3, H, W)` rays.
        params: :class:`SphereTraceParams`.
        state: must be ``None`` (stateless; the implicit casters share one call).
        generator: unused (sphere tracing draws nothing); accepted so every caster takes the same call.
        jitter, dtype, device: sub-pixel offsets and ray dtype/device when ``camera`` is a Camera.

    Returns:
        :class:`~.common.ImplicitResult`. ``debug``: ``"overshoot"`` :math:`(B, 1, H, W)` bool (a
        step from ``f ≥ 0`` landed at ``f < 0`` on an armed ray: λ is invalid), ``"fallbacks"`` int32 (Keinert
        fallbacks taken), ``"t_last"`` (the last accepted t, also for misses and ``OUT_OF_STEPS``).

    Raises:
        ValueError: no λ in ``params`` and none declared by the surface (names ``lipschitz``).

    Example:
        >>> from ssbench.camera import Camera
        >>> from ssbench.passes.implicit.common import FunctionSurface
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 45.0, 8, 6, 0.1, 10.0)
        >>> ball = FunctionSurface(lambda p: p.norm(dim=-1) - 1.0, lipschitz=1.0)
        >>> r = sphere_trace(ball, cam, dtype=torch.float64)
        >>> int(r.hit.sum()), bool(r.debug["overshoot"].any())
        (12, False)
    """
    check_surface(surface)
    check_stateless(state, "sphere_trace")
    if not isinstance(params, SphereTraceParams):
        raise TypeError(f"params: expected SphereTraceParams, got {type(params).__name__}")
    lam = params.lipschitz if params.lipschitz is not None else getattr(surface, "lipschitz", None)
    if lam is None:
        raise ValueError("lipschitz: sphere tracing needs a Lipschitz bound; set SphereTraceParams.lipschitz "
                         "or declare one on the surface")
    lam = float(lam)
    rays = as_rays(camera, jitter, dtype, device)
    B, _, H, W = rays.direction.shape
    o, d = flat(rays.origin), flat(rays.direction)
    t_near, t_far = flat(rays.t_near).squeeze(1), flat(rays.t_far).squeeze(1)
    n, dev, eps = o.shape[0], o.device, params.epsilon
    term = torch.full((n,), OUT_OF_STEPS, dtype=torch.int8, device=dev)
    t_out, lo, hi = o.new_zeros(n), o.new_zeros(n), o.new_zeros(n)
    crossing = torch.zeros(n, dtype=torch.bool, device=dev)
    overshoot = torch.zeros(n, dtype=torch.bool, device=dev)
    fallbacks = torch.zeros(n, dtype=torch.int32, device=dev)
    evaluations = torch.ones(n, dtype=torch.int32, device=dev)
    steps = torch.zeros(n, dtype=torch.int32, device=dev)

    # ---- per-active-ray state (compacted as rays finish) ----
    ids = torch.arange(n, device=dev)
    t = o.new_zeros(n)
    fa = surface.f(o)                                                  # f at the accepted point t
    omega = torch.full_like(t, float(params.omega))
    armed = fa / lam > eps * t_near                                    # clearly outside at the eye

    def retire(mask, code):                                            # integer indices: one nonzero each
        nonlocal ids, t, fa, omega, armed
        gone = flat_nonzero(mask)
        if gone.numel() == 0:
            return
        sel = ids.index_select(0, gone)
        term[sel], t_out[sel] = code, t.index_select(0, gone)
        keep = flat_nonzero(~mask)
        ids, t, fa, omega, armed = (x.index_select(0, keep) for x in (ids, t, fa, omega, armed))

    retire(torch.isnan(fa), MISS)                                      # NaN at the eye: nothing to trace
    for _ in range(params.max_steps):
        if ids.numel() == 0:
            break
        tau = eps * torch.maximum(t, t_near[ids])
        r = fa.abs() / lam
        retire(armed & (r < tau), HIT)                                # distance hit (Hart)
        retire(t >= t_far[ids], MISS)                                 # left [0, t_far]
        if ids.numel() == 0:
            break
        tau = eps * torch.maximum(t, t_near[ids])
        r = fa.abs() / lam
        tn = torch.minimum(t + torch.where(armed, omega * r, r + tau), t_far[ids])
        fn = surface.f(o[ids] + tn.unsqueeze(-1) * d[ids])
        evaluations[ids] += 1
        steps[ids] += 1
        fail = armed & (omega > 1) & (r + fn / lam < tn - t)          # spheres do not overlap (Keinert)
        cross = ~fail & (fa >= 0) & (fn < 0)
        if not params.safeguard:                                      # plain Hart: no crossing test
            cross = cross & ~armed
        ci = flat_nonzero(cross)
        if ci.numel():
            sel = ids.index_select(0, ci)
            crossing[sel], overshoot[sel] = True, armed.index_select(0, ci)
            lo[sel], hi[sel] = t.index_select(0, ci), tn.index_select(0, ci)
        fi = flat_nonzero(fail)
        if fi.numel():
            fallbacks[ids.index_select(0, fi)] += 1
        omega = torch.where(fail, torch.ones_like(omega), omega)       # step back, continue with ω = 1
        acc = ~fail & ~cross
        t, fa = torch.where(acc, tn, t), torch.where(acc, fn, fa)
        armed = armed | (acc & (fn / lam > eps * torch.maximum(tn, t_near[ids])))
        nan = acc & torch.isnan(fn)
        retire(cross, HIT)
        retire(nan[~cross], MISS)
    if ids.numel() > 0:                                                # the last step may have converged
        retire(armed & (fa.abs() / lam < eps * torch.maximum(t, t_near[ids])), HIT)
        retire(t >= t_far[ids], MISS)
    term[ids] = OUT_OF_STEPS
    t_out[ids] = t

    h = flat_nonzero(crossing)                                         # bisect crossings back to the root
    lo[h], hi[h] = bisect(surface, o[h], d[h], lo[h], hi[h], params.refine_iterations)
    evaluations = evaluations + crossing.to(torch.int32) * params.refine_iterations
    t_hit = torch.where(crossing, 0.5 * (lo + hi), t_out)
    hit = term == HIT
    shape = (B, H, W)
    dbg = {"overshoot": unflat(overshoot, shape), "fallbacks": unflat(fallbacks, shape),
           "t_last": unflat(t_out, shape)}
    return finish(shape, origin=o, direction=d, t_far=t_far, surface=surface, hit=hit, t=t_hit,
                  evaluations=evaluations, steps=steps, termination=term, debug=dbg)


class SphereTrace(nn.Module):
    """``nn.Module`` wrapper of :func:`sphere_trace`; ``forward(surface, camera)`` returns its result."""

    def __init__(self, params: SphereTraceParams = SphereTraceParams()) -> None:
        super().__init__()
        self.params = params

    def forward(self, surface, camera, jitter: Optional[torch.Tensor] = None) -> ImplicitResult:
        return sphere_trace(surface, camera, self.params, jitter=jitter)


#: the parameter a ``--steps N`` option sets (a cap on the steps, not a fixed count)
STEPS_PARAM = "max_steps"

#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("sphere", sphere_trace, SphereTraceParams, SphereTrace, order=20, title="sphere tracing (Hart 1996)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"static": [{"max_steps": [8, 32]}]}
SPEED_PANELS = (SpeedPanel("punch", "max_steps"),)
