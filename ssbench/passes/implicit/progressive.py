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

The notes (補足): :func:`progressive_secondary` runs the same core on arbitrary ray bundles with their own
``t'`` buffer (二次レイ); :func:`txaa_jitter` and :func:`silhouette_mask` measure the TXAA case (sub-pixel
jitter makes silhouette pixels leave and re-enter the object, so their estimates are invalidated often — and,
measured, interior pixels too while ε is smaller than the depth change of a half-pixel shift on a sloped
surface: 38 % per frame on a unit ball at ε = 1e-3, 4 % at 1e-2, 0 at 1e-1, see lesson 08 step 8);
supersampling is :func:`ssbench.passes.implicit.gbuffer.supersample`.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Iterator, Optional, Union

import torch
import torch.nn.functional as F
from torch import nn

from ..common import length
from .common import (HIT, INVALIDATED, MISS, CameraRays, ImplicitResult, as_rays, bisect,
                              camera_rays, check_surface, finish, flat, unflat)
from .fixed import check_int, march_lattice
from ..registry import Method, SpeedPanel

#: the caster carries ``t'`` between frames (``result.state`` → ``state=``): evaluations run its frames in order
STATEFUL = True

__all__ = ["METHOD", "STATEFUL", "ProgressiveParams", "ProgressiveState", "progressive", "progressive_secondary",
           "reflection_bundle", "run_progressive", "txaa_jitter", "silhouette_mask", "Progressive"]


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


def txaa_jitter(generator: torch.Generator, batch: int = 1, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """:math:`(B, 2, 1, 1)` TXAA sub-pixel offset, ``U[−0.5, 0.5)`` pixels, the same for all pixels of a frame
    (補足: アンチエイリアシング); pass it as ``jitter`` to :func:`progressive`."""
    return torch.rand(batch, 2, 1, 1, generator=generator, dtype=torch.float64).to(dtype) - 0.5


def frame_generator(params: ProgressiveParams, frame: int) -> torch.Generator:
    g = torch.Generator(device="cpu")
    g.manual_seed(params.seed * 1_000_003 + frame)
    return g


def _core(surface, o, d, t_far, t_prime, found_prev, R, params: ProgressiveParams, active):
    """Steps 2.1–2.3 on flat rays (n, 3); returns per-ray hit, t, evaluations, steps, termination, debug."""
    n, dev, N = o.shape[0], o.device, params.steps
    t_p = torch.minimum(t_prime, t_far)
    ids = active.nonzero().squeeze(1)
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
    again = (invalid & (t_p < t_far)).nonzero().squeeze(1)          # t' := d_f and cast again
    cast(again, t_far[again])
    h = found.nonzero().squeeze(1)
    lo[h], hi[h] = bisect(surface, o[h], d[h], lo[h], hi[h], params.refine_iterations)   # 2.3
    evaluations = steps + found.to(torch.int32) * params.refine_iterations
    term = torch.where(found, HIT, torch.where(invalid, INVALIDATED, MISS)).to(torch.int8)
    return found, 0.5 * (lo + hi), evaluations, steps, term, invalid, torch.stack([lo, hi], 1)


def _run(surface, o, d, t_far, shape, state, params, generator, active) -> ImplicitResult:
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
        jitter: :math:`(B, 2, 1, 1)` sub-pixel camera offset, e.g. :func:`txaa_jitter` (with a Camera).
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
    return _run(surface, o, d, flat(rays.t_far).squeeze(1), (B, H, W), state, params, generator,
                torch.ones(o.shape[0], dtype=torch.bool, device=o.device))


def progressive_secondary(surface, origins: torch.Tensor, directions: torch.Tensor,
                          t_max: Union[float, torch.Tensor], params: ProgressiveParams = ProgressiveParams(), *,
                          state: Optional[ProgressiveState] = None, generator: Optional[torch.Generator] = None,
                          active: Optional[torch.Tensor] = None) -> ImplicitResult:
    r"""The progressive method on an arbitrary ray bundle with its own ``t'`` buffer (補足: 二次レイ).

    Args:
        origins: :math:`(B, 3, H, W)` world ray origins (offset them off the surface they leave).
        directions: :math:`(B, 3, H, W)` world directions (normalised here; ``t`` is in world units).
        t_max: the ray's ``d_f``: a number or :math:`(B, 1, H, W)`.
        state: the bundle's own previous ``result.state`` (None: ``t' := t_max``).
        active: :math:`(B, 1, H, W)` bool, pixels that cast a ray (e.g. the primary hits); others are MISS
            with 0 evaluations.

    Returns:
        :class:`~.common.ImplicitResult` with the bundle's next ``state``, as :func:`progressive`.
    """
    for name, x in (("origins", origins), ("directions", directions)):
        if not isinstance(x, torch.Tensor) or x.dim() != 4 or x.shape[1] != 3:
            raise ValueError(f"{name}: expected shape (B, 3, H, W), got {getattr(x, 'shape', type(x))}")
    B, _, H, W = directions.shape
    o, d = flat(origins), flat(directions)
    nd = length(d)
    d = torch.where(nd > 0, d / torch.where(nd > 0, nd, torch.ones_like(nd)), torch.zeros_like(d))
    tm = torch.as_tensor(t_max, dtype=o.dtype, device=o.device)
    t_far = flat(tm.expand(B, 1, H, W)).squeeze(1) if tm.dim() else torch.full_like(o[:, 0], float(tm))
    if not bool(torch.isfinite(t_far).all()) or bool((t_far <= 0).any()):
        raise ValueError("t_max: must be finite and > 0")
    act = torch.ones(B * H * W, dtype=torch.bool, device=o.device) if active is None else flat(active).squeeze(1)
    act = act & (nd.squeeze(1) > 0)
    return _run(surface, o, d, t_far, (B, H, W), state, params, generator, act)


def reflection_bundle(rays: CameraRays, result: ImplicitResult, offset: float = 1e-3):
    """Mirror rays of the primary hits: ``(origins, directions, active)`` with origins moved ``offset`` along
    the normal (turned toward the eye) off the surface; ``active`` = hits with a non-zero normal."""
    d, n = rays.direction, result.normal
    n = torch.where((n * d).sum(1, keepdim=True) > 0, -n, n)
    r = d - 2.0 * (n * d).sum(1, keepdim=True) * n
    origins = rays.origin + result.t * d + offset * n
    return origins, r, result.hit & (n.abs().sum(1, keepdim=True) > 0)


def silhouette_mask(result: ImplicitResult, radius: int = 1) -> torch.Tensor:
    """:math:`(B, 1, H, W)` bool: pixels whose ``(2r+1)²`` neighbourhood holds another label (miss or another
    object index), i.e. both sides of every silhouette. Use it on converged frames: punch-through holes of a
    half-converged thin shell are label changes too and are marked as silhouettes."""
    check_int(radius, "radius", 1)
    lab = torch.where(result.hit, result.object_index, -1).to(torch.float64)
    k = 2 * radius + 1
    pad = F.pad(lab, (radius,) * 4, mode="replicate")
    return F.max_pool2d(pad, k, 1) != -F.max_pool2d(-pad, k, 1)


def run_progressive(scene_or_callables, frames, params: ProgressiveParams = ProgressiveParams(), seed: int = 0,
                    jitter_mode: Optional[str] = None, progress: bool = True, *,
                    dtype: torch.dtype = torch.float32, device=None
                    ) -> Iterator[tuple[int, ImplicitResult, ProgressiveState]]:
    """Animate the progressive method: yields ``(frame, result, state)`` per frame (tqdm bar if ``progress``).

    Args:
        scene_or_callables: an ``ImplicitScene`` (``surface(frame)``, ``camera_at(frame)``) or a pair of
            callables ``(surface_at, camera_at)``.
        frames: a count (frames ``0..frames−1``) or an iterable of frame indices.
        seed: seeds ``R`` (one generator) and the TXAA jitter (a second one), so runs with and without jitter
            draw the same ``R``.
        jitter_mode: None or ``"txaa"`` (:func:`txaa_jitter` every frame).

    ``result.debug`` also holds ``"camera"`` and ``"rays"`` of the frame (for :func:`to_gbuffer`).
    """
    from tqdm.auto import tqdm
    if jitter_mode not in (None, "txaa"):
        raise ValueError(f"jitter_mode: expected None or 'txaa', got {jitter_mode!r}")
    check_int(seed, "seed", 0)
    if hasattr(scene_or_callables, "surface") and hasattr(scene_or_callables, "camera_at"):
        surface_at, camera_at = scene_or_callables.surface, scene_or_callables.camera_at
    else:
        surface_at, camera_at = scene_or_callables
    seq = list(range(frames)) if isinstance(frames, int) else list(frames)
    g_r, g_j = torch.Generator().manual_seed(seed), torch.Generator().manual_seed(seed + 1)
    state = None
    for k in tqdm(seq, disable=not progress, desc="progressive", unit="frame"):
        cam = camera_at(k)
        jit = txaa_jitter(g_j, 1, dtype) if jitter_mode == "txaa" else None
        rays = camera_rays(cam, jitter=jit, dtype=dtype, device=device)
        res = progressive(surface_at(k), rays, params, state=state, generator=g_r)
        state = res.state
        res.debug.update(camera=cam, rays=rays)
        yield k, res, state


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
