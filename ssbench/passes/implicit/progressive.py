r"""The article's progressive ray casting of arbitrary implicit surfaces (progressive-tracing article, 手法, steps 1–2.5).

Per pixel a distance estimate ``t'`` is carried across frames (:class:`ProgressiveState`):

1. **初期化** ``t' := d_f`` (``t_far``, the camera-to-far-plane distance along the ray).
2. Every frame:

   1. **レイキャスティング** ``s = t'/N``, ``R ~ U[0, 1)`` per pixel per frame, samples
      ``t_0 = 0, t_k = sR + (k − 1)s`` (``k = 1..N``) and the extra sample ``(1 + ε)t'`` (capped at
      ``t_far``); the bracket is the first ``f(t_i) ≥ 0 > f(t_{i+1})`` over that list.
   2. **推定値の無効化** no bracket while ``t'`` held a found intersection → ``t' := d_f`` and cast again
      (same ``R``); still nothing → transparent (``INVALIDATED``; ``MISS`` when ``t'`` was already ``d_f``).
   3. **絞込み** bisection of the bracket. 4. **シェーディング** normal from ∇f. 5. **保存** ``t' := t``.

**Why the (1+ε)t' probe detects a scene change.** The invariant (不変条件) says ``t'`` is the smallest root
found so far, so the object occupies ``t'`` and, ε being small, also ``(1 + ε)t'`` (f < 0 there). The ray start
is outside (f ≥ 0), so the sample list starts at f ≥ 0 and ends at f < 0: *some* consecutive pair must change
sign, and the march cannot come back empty. If it does, the invariant is broken: the object moved away (or
the camera moved), ``t'`` may now lie in front of every root, and it is reset to ``d_f``. Any root in front of
``t'`` is caught by the jittered lattice with probability ``min(1, w/h)`` per frame (``w`` its chord,
``h = t'/N``), so ``t'`` only shrinks toward the first root.

**Why ε must be smaller than the slab chord.** The probe has to land *inside* the object: if ``εt'`` exceeds
the chord ``w`` of the slab at ``t'`` (thin shells, grazing rays near a silhouette), ``(1+ε)t'`` lies beyond
the slab in f ≥ 0, the march finds nothing, the estimate is invalidated, found again on a later frame and
invalidated again: the pixel flickers. (A probe that falls inside a *farther* object still brackets; the root
is then re-found by the lattice only with probability ``w/h``.)

The article's notes (補足) — secondary rays with their own ``t'`` buffer, TXAA jitter, the frame loop — are in
:mod:`ssbench.passes.implicit.progressive_notes`; supersampling is :func:`ssbench.passes.implicit.gbuffer.supersample`.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...indices import flat_nonzero
from .common import HIT, INVALIDATED, MISS, ImplicitResult, as_rays, bisect, check_surface, finish, flat, unflat
from .fixed import check_int, march_lattice
from ..inference import autograd_free
from ..registry import Method, SpeedPanel

#: the caster carries ``t'`` between frames (``result.state`` → ``state=``): evaluations run its frames in order
STATEFUL = True

__all__ = ["METHOD", "STATEFUL", "ProgressiveParams", "ProgressiveState", "progressive", "run_frame",
           "frame_generator", "Progressive"]


@dataclass(frozen=True)
class ProgressiveParams:
    """Parameters of :func:`progressive` (the article's symbols).

    Attributes:
        steps: ``N``, the number of lattice samples over ``[0, t']``.
        epsilon: ``ε`` of the extra sample ``(1 + ε)t'`` (smaller than the chords of the slabs, see above).
        refine_iterations: bisection iterations (二分法).
        seed: with no generator, frame ``k`` draws ``R`` from a CPU generator seeded with ``(seed, k)``.
    """

    steps: int = 32
    epsilon: float = 1e-3
    refine_iterations: int = 20
    seed: int = 0

    def __post_init__(self) -> None:
        check_int(self.steps, "steps", 1)
        check_int(self.refine_iterations, "refine_iterations", 0)
        check_int(self.seed, "seed", 0)
        if isinstance(self.epsilon, bool) or not isinstance(self.epsilon, (int, float)) or not (
                math.isfinite(self.epsilon) and self.epsilon > 0):
            raise ValueError(f"epsilon: must be a finite number > 0, got {self.epsilon!r}")


@dataclass(frozen=True)
class ProgressiveState:
    """The per-pixel estimate carried across frames.

    Attributes:
        t_prime: :math:`(B, 1, H, W)` ``t'`` (``t_far`` where no intersection was found).
        frame: number of frames rendered with this state.
        found: :math:`(B, 1, H, W)` bool, ``t'`` holds a found intersection (the invariant's "発見されている
            交点"); None: derived as ``t' < t_far``.
    """

    t_prime: torch.Tensor
    frame: int = 0
    found: Optional[torch.Tensor] = None

    @classmethod
    def initial(cls, camera, batch: int = 1, dtype: Optional[torch.dtype] = None, device=None) -> "ProgressiveState":
        """Step 1 (初期化): ``t' := d_f`` for the pixel-centre rays of ``camera`` (Camera or CameraRays), or
        for a :math:`(B, 1, H, W)` tensor of far distances (secondary rays)."""
        t_far = camera if isinstance(camera, torch.Tensor) else as_rays(camera, None, dtype, device, batch).t_far
        return cls(t_far.clone(), 0, torch.zeros_like(t_far, dtype=torch.bool))


def frame_generator(params: ProgressiveParams, frame: int) -> torch.Generator:
    g = torch.Generator(device="cpu")
    g.manual_seed(params.seed * 1_000_003 + frame)
    return g


def _core(surface, o, d, t_far, t_prime, found_prev, R, params: ProgressiveParams, active):
    """Steps 2.1–2.3 on flat rays (n, 3); returns per-ray hit, t, evaluations, steps, termination, debug."""
    n, dev, N = o.shape[0], o.device, params.steps
    t_p = torch.minimum(t_prime, t_far)
    ids = flat_nonzero(active)
    found, lo, hi = torch.zeros(n, dtype=torch.bool, device=dev), o.new_zeros(n), o.new_zeros(n)
    steps = torch.zeros(n, dtype=torch.int32, device=dev)

    def cast(sel, t_est):                                           # 2.1 on rays `sel` with estimate t_est
        if sel.numel() == 0:
            return found[sel]
        s = t_est / N
        probe = torch.minimum((1.0 + params.epsilon) * t_est, t_far[sel])
        f, a, b, k = march_lattice(surface, o[sel], d[sel], s * R[sel], s, N, last=probe)
        found[sel], lo[sel], hi[sel] = f, a, b
        steps[sel] += k
        return f

    f1 = cast(ids, t_p[ids])
    invalid = torch.zeros(n, dtype=torch.bool, device=dev)
    invalid[ids] = ~f1 & found_prev[ids]                            # 2.2 the estimate failed the probe
    again = flat_nonzero(invalid & (t_p < t_far))                   # t' := d_f and cast again
    cast(again, t_far[again])
    h = flat_nonzero(found)
    lo[h], hi[h] = bisect(surface, o[h], d[h], lo[h], hi[h], params.refine_iterations)   # 2.3
    evaluations = steps + found.to(torch.int32) * params.refine_iterations
    term = torch.where(found, HIT, torch.where(invalid, INVALIDATED, MISS)).to(torch.int8)
    return found, 0.5 * (lo + hi), evaluations, steps, term, invalid, torch.stack([lo, hi], 1)


def run_frame(surface, o: torch.Tensor, d: torch.Tensor, t_far: torch.Tensor, shape: tuple,
              state: Optional[ProgressiveState], params: ProgressiveParams, generator: Optional[torch.Generator],
              active: torch.Tensor) -> ImplicitResult:
    """One frame (steps 2.1–2.5) on flat rays: origins ``o`` and unit directions ``d`` :math:`(n, 3)`, far
    distances ``t_far`` :math:`(n,)`, ``shape = (B, H, W)`` with ``n = B·H·W``, ``active`` :math:`(n,)` bool (rays
    cast; the others are MISS with 0 evaluations). :func:`progressive` and
    :func:`ssbench.passes.implicit.progressive_notes.progressive_secondary` build the rays and call this."""
    check_surface(surface)
    if not isinstance(params, ProgressiveParams):
        raise TypeError(f"params: expected ProgressiveParams, got {type(params).__name__}")
    B, H, W = shape
    if state is None:
        state = ProgressiveState(unflat(t_far, shape), 0, torch.zeros(B, 1, H, W, dtype=torch.bool,
                                                                      device=o.device))
    if not isinstance(state, ProgressiveState):
        raise TypeError(f"state: expected ProgressiveState or None, got {type(state).__name__}")
    if tuple(state.t_prime.shape) != (B, 1, H, W):
        raise ValueError(f"state: t_prime has shape {tuple(state.t_prime.shape)}, expected {(B, 1, H, W)}")
    if state.found is not None and tuple(state.found.shape) != (B, 1, H, W):
        raise ValueError(f"state: found has shape {tuple(state.found.shape)}, expected {(B, 1, H, W)}")
    g = generator if generator is not None else frame_generator(params, state.frame)
    R = flat(torch.rand(B, 1, H, W, generator=g, dtype=torch.float64).to(o.dtype).to(o.device)).squeeze(1)
    t_prime = flat(state.t_prime.to(dtype=o.dtype, device=o.device)).squeeze(1)
    found_prev = flat(state.found).squeeze(1).to(o.device) if state.found is not None else t_prime < t_far
    hit, t, ev, st, term, invalid, bracket = _core(surface, o, d, t_far, t_prime, found_prev, R, params, active)
    dbg = {"invalidated": unflat(invalid, shape), "t_prime_before": state.t_prime.clone(),
           "bracket": unflat(bracket, shape), "R": unflat(R, shape)}
    res = finish(shape, origin=o, direction=d, t_far=t_far, surface=surface, hit=hit, t=t, evaluations=ev,
                 steps=st, termination=term, debug=dbg)
    return dataclasses.replace(res, state=ProgressiveState(res.t.clone(), state.frame + 1, res.hit.clone()))  # 2.5


@autograd_free
def progressive(surface, camera, params: ProgressiveParams = ProgressiveParams(), *,
                state: Optional[ProgressiveState] = None, generator: Optional[torch.Generator] = None,
                jitter: Optional[torch.Tensor] = None, dtype: Optional[torch.dtype] = None,
                device=None) -> ImplicitResult:
    r"""One frame of the article's progressive method (progressive-tracing article, 手法 2.1–2.5) for camera rays.

    Args:
        surface: the surface protocol at this frame.
        camera: :class:`~ssbench.camera.Camera` (plus ``jitter``) or :class:`~.common.CameraRays`.
        params: :class:`ProgressiveParams`.
        state: the previous frame's ``result.state`` (None: step 1, ``t' := d_f``).
        generator: draws ``R`` :math:`(B, 1, H, W)` (one ``torch.rand``, float64).
        jitter: :math:`(B, 2, 1, 1)` sub-pixel camera offset, e.g.
            :func:`~ssbench.passes.implicit.progressive_notes.txaa_jitter` (with a Camera).
        dtype, device: of the rays built from a Camera (default: the state's dtype, else float32).

    Returns:
        :class:`~.common.ImplicitResult` whose ``state`` (a :class:`ProgressiveState`, 2.5 ``t' := t``) is the
        next frame's ``state=``; ``result.debug``: ``"invalidated"`` :math:`(B, 1, H, W)` bool (2.2 fired),
        ``"t_prime_before"``, ``"bracket"`` :math:`(B, 2, H, W)`, ``"R"``. ``evaluations`` counts both casts,
        the bisection and the normal's gradient.

    Example:
        >>> from ssbench.camera import Camera
        >>> from ssbench.passes.implicit.common import FunctionSurface
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 45.0, 8, 6, 0.1, 10.0)
        >>> ball = FunctionSurface(lambda p: p.norm(dim=-1) - 1.0)
        >>> g = torch.Generator().manual_seed(0)
        >>> r = progressive(ball, cam, ProgressiveParams(), generator=g, dtype=torch.float64)
        >>> r = progressive(ball, cam, ProgressiveParams(), state=r.state, generator=g)
        >>> int(r.hit.sum()), r.state.frame, bool(r.debug["invalidated"].any())
        (12, 2, False)
    """
    if dtype is None and state is not None:
        dtype = state.t_prime.dtype
    rays = as_rays(camera, jitter, dtype, device, state.t_prime.shape[0] if state is not None else 1)
    B, _, H, W = rays.direction.shape
    o, d = flat(rays.origin), flat(rays.direction)
    return run_frame(surface, o, d, flat(rays.t_far).squeeze(1), (B, H, W), state, params, generator,
                torch.ones(o.shape[0], dtype=torch.bool, device=o.device))


class Progressive(nn.Module):
    """Stateful ``nn.Module`` wrapper of :func:`progressive`: keeps the state between ``forward`` calls."""

    def __init__(self, params: ProgressiveParams = ProgressiveParams()) -> None:
        super().__init__()
        self.params, self.state = params, None

    def reset(self) -> None:
        """Forget ``t'`` (step 1 at the next frame)."""
        self.state = None

    def forward(self, surface, camera, generator: Optional[torch.Generator] = None,
                jitter: Optional[torch.Tensor] = None) -> ImplicitResult:
        res = progressive(surface, camera, self.params, state=self.state, generator=generator, jitter=jitter)
        self.state = res.state
        return res


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("progressive", progressive, ProgressiveParams, Progressive, order=30,
                title="progressive ray casting (t\u2032 across frames)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"frames": [{"steps": [8, 32]}]}
SPEED_PANELS = (SpeedPanel("punch", "steps"), SpeedPanel("punch", "frame", metric="punch_through_per_frame"))
