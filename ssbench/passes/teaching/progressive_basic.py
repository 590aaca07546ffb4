"""The progressive method, one pixel at a time: progressive-tracing article's steps as plain functions over Python floats.

This file exists only to teach. It follows the article step by step (「陰的に定義された曲面の漸進的レイトレーシング」,
*Progressive Ray Tracing of Arbitrary Implicit Surfaces*, blog post, 2016, section 手法; demo
https://www.shadertoy.com/view/XsdSR7), one function per step, with its symbols (``t'``, ``d_f``, ``N``, ``s``,
``R``, ``ε``):

1. :func:`initialise` — 初期化: ``t' := d_f``.
2. :func:`ray_cast` — レイキャスティング: samples ``t_0 = 0``, ``t_k = sR + (k − 1)s`` and ``(1 + ε)t'``; the first
   ``f(t_i) ≥ 0 > f(t_{i+1})`` is the bracket.
3. :func:`invalidate` — 推定値の無効化: no bracket while ``t'`` held a found intersection → ``t' := d_f``, cast again.
4. :func:`refine` — 絞込み: bisection of the bracket.
5. shading and 6. 保存 ``t' := t`` — the normal comes from the vectorised
   :func:`~ssbench.passes.implicit.common.finish` (one gradient per hit), as in :func:`ssbench.passes.
   implicit.progressive.progressive`.

It draws ``R`` exactly as the vectorised pass (one ``torch.rand`` of :math:`(B, 1, H, W)` per frame), so the two
agree bit for bit on ``t``, ``hit``, ``termination`` and the evaluation counts (``tests/passes/
implicit/test_progressive.py``). Use the vectorised pass for anything but tiny images.
"""
from __future__ import annotations

import dataclasses
from typing import Optional

import torch

from ..implicit.common import HIT, INVALIDATED, MISS, ImplicitResult, camera_rays, finish, flat
from ..implicit.progressive import ProgressiveParams, ProgressiveState, frame_generator


def initialise(d_f: float) -> float:
    """Step 1 (初期化): the estimate starts at the far distance, ``t' := d_f``."""
    return d_f


def f_at(surface, o: list, d: list, t: float) -> float:
    """``f(o + t·d)`` of one point (one evaluation)."""
    p = torch.tensor([[o[i] + t * d[i] for i in range(3)]], dtype=torch.float64)
    return float(surface.f(p).reshape(-1)[0])


def ray_cast(surface, o: list, d: list, t_est: float, d_f: float, R: float, params: ProgressiveParams):
    """Step 2 (レイキャスティング): ``s = t'/N``; samples ``t_0 = 0``, ``t_k = sR + (k − 1)s`` for ``k = 1..N``, then
    ``min((1 + ε)t', d_f)``. Returns ``(found, t_lo, t_hi, evaluations)`` of the first bracket."""
    N = params.steps
    s = t_est / N
    samples = [s * R + (k - 1) * s for k in range(1, N + 1)] + [min((1.0 + params.epsilon) * t_est, d_f)]
    t_prev, f_prev, evaluations = 0.0, f_at(surface, o, d, 0.0), 1      # t_0 = 0: the ray origin
    for t_k in samples:
        f_k = f_at(surface, o, d, t_k)
        evaluations += 1
        if f_prev >= 0 > f_k:
            return True, t_prev, t_k, evaluations
        t_prev, f_prev = t_k, f_k
    return False, 0.0, 0.0, evaluations


def invalidate(found: bool, found_before: bool, t_prime: float, d_f: float) -> tuple[bool, bool]:
    """Step 3 (推定値の無効化): ``(invalid, cast_again)``. The cast failed although ``t'`` held a found
    intersection: the invariant broke (the object moved), so ``t' := d_f`` and cast again when ``t' < d_f``."""
    invalid = (not found) and found_before
    return invalid, invalid and t_prime < d_f


def refine(surface, o: list, d: list, t_lo: float, t_hi: float, iterations: int) -> float:
    """Step 4 (絞込み): bisection keeping ``f(t_lo) ≥ 0 > f(t_hi)``; ``t`` is the bracket's midpoint."""
    for _ in range(iterations):
        mid = 0.5 * (t_lo + t_hi)
        if f_at(surface, o, d, mid) >= 0:
            t_lo = mid
        else:
            t_hi = mid
    return 0.5 * (t_lo + t_hi)


def progressive_basic(surface, camera, params: ProgressiveParams = ProgressiveParams(), *,
                      state: Optional[ProgressiveState] = None,
                      generator: Optional[torch.Generator] = None) -> ImplicitResult:
    """One frame of the progressive method per pixel, in float64, called and returning like
    :func:`~ssbench.passes.implicit.progressive.progressive` (``result.state`` for the next frame; ``debug``
    holds ``"invalidated"`` only).

    Example:
        >>> from ssbench.camera import Camera
        >>> from ssbench.passes.implicit.common import FunctionSurface
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 45.0, 4, 3, 0.1, 10.0)
        >>> ball = FunctionSurface(lambda p: p.norm(dim=-1) - 1.0)
        >>> r = progressive_basic(ball, cam)
        >>> int(r.hit.sum()), r.state.frame
        (2, 1)
    """
    rays = camera_rays(camera, dtype=torch.float64)
    B, _, H, W = rays.direction.shape
    origin, direction, far = flat(rays.origin), flat(rays.direction), flat(rays.t_far).squeeze(1)
    if state is None:
        state = ProgressiveState(rays.t_far.clone(), 0, torch.zeros(B, 1, H, W, dtype=torch.bool))
    g = generator if generator is not None else frame_generator(params, state.frame)
    R_all = flat(torch.rand(B, 1, H, W, generator=g, dtype=torch.float64)).squeeze(1).tolist()
    t_primes = flat(state.t_prime.double()).squeeze(1).tolist()
    founds = (flat(state.found).squeeze(1) if state.found is not None else flat(state.t_prime) < far).tolist()
    out = {"hit": [], "t": [], "evaluations": [], "steps": [], "termination": [], "invalidated": []}
    for i, (o, d, d_f) in enumerate(zip(origin.tolist(), direction.tolist(), far.tolist())):
        t_prime = min(t_primes[i], d_f)
        found, t_lo, t_hi, steps = ray_cast(surface, o, d, t_prime, d_f, R_all[i], params)
        invalid, cast_again = invalidate(found, founds[i], t_prime, d_f)
        if cast_again:
            t_prime = initialise(d_f)
            found, t_lo, t_hi, more = ray_cast(surface, o, d, t_prime, d_f, R_all[i], params)
            steps += more
        t = refine(surface, o, d, t_lo, t_hi, params.refine_iterations) if found else 0.5 * (t_lo + t_hi)
        out["hit"].append(found)
        out["t"].append(t)
        out["steps"].append(steps)
        out["evaluations"].append(steps + (params.refine_iterations if found else 0))
        out["termination"].append(HIT if found else (INVALIDATED if invalid else MISS))
        out["invalidated"].append(invalid)
    as_t = lambda k, dt: torch.tensor(out[k], dtype=dt)                      # noqa: E731
    res = finish((B, H, W), origin=origin, direction=direction, t_far=far, surface=surface,
                 hit=as_t("hit", torch.bool), t=as_t("t", torch.float64),
                 evaluations=as_t("evaluations", torch.int32), steps=as_t("steps", torch.int32),
                 termination=as_t("termination", torch.int8),
                 debug={"invalidated": as_t("invalidated", torch.bool).reshape(B, H, W, 1).permute(0, 3, 1, 2)})
    return dataclasses.replace(res, state=ProgressiveState(res.t.clone(), state.frame + 1,      # 保存: t' := t
                                                           res.hit.clone()))
