"""Fixed-step march (progressive-tracing article, the article's baseline): closed-form roots, punch-through of thin slabs when
the chord is shorter than the step and never when longer, honest evaluation counts, jitter, no NaN."""
from __future__ import annotations

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes.implicit.analytic import analytic_sphere, sphere_roots
from ssbench.passes.implicit.common import HIT, MISS, FunctionSurface, camera_rays
from ssbench.passes.implicit.fixed import FixedStep, FixedStepParams, fixed_step, march_lattice

BALL = FunctionSurface(lambda p: p.norm(dim=-1) - 1.0, lipschitz=1.0)


def shell(w, R=1.0):
    return FunctionSurface(lambda p: (p.norm(dim=-1) - R).abs() - w, lipschitz=1.0)


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def cam(w=48, h=36, far=8.0, eye=(0.0, 0.0, 4.0)):
    return Camera.from_look_at(eye, (0, 0, 0), (0, 1, 0), 45.0, w, h, 0.1, far)


def shell_truth(rays, R, w):
    """First root (outer sphere R + w) and the chord through the front wall, per pixel (closed form)."""
    o, d = rays.origin.permute(0, 2, 3, 1), rays.direction.permute(0, 2, 3, 1)
    z = torch.zeros(3, dtype=o.dtype)
    a0, a1, oka = sphere_roots(o, d, z, R + w)
    b0, _, okb = sphere_roots(o, d, z, R - w)
    chord = torch.where(okb, b0 - a0, a1 - a0)
    return a0.unsqueeze(1), oka.unsqueeze(1), chord.unsqueeze(1)


def test_small_step_finds_sphere_roots_within_bisection_tolerance():
    c = cam(eye=(0.5, 0.8, 3.5))
    rays = camera_rays(c, dtype=torch.float64)
    truth = analytic_sphere(rays, (0, 0, 0), 1.0)
    res = fixed_step(BALL, rays, FixedStepParams(steps=400, refine_iterations=30))
    s = rays.t_far / 400
    chord = truth.debug["roots"][:, 1:] - truth.debug["roots"][:, :1]
    sure = truth.hit & (chord >= s)                                # a sample must land inside
    assert sure.sum().item() > 400
    assert torch.equal(res.hit & sure, sure)
    assert not bool((res.hit & ~truth.hit).any())                  # never a false hit
    err = (res.t - truth.t).abs()[res.hit]
    assert err.max().item() <= (s.max().item() / 2 ** 30) + 1e-12
    lo, hi = res.debug["bracket"][:, :1], res.debug["bracket"][:, 1:]
    p = lambda t: rays.origin + t * rays.direction                 # noqa: E731
    assert bool((BALL.f(p(lo).permute(0, 2, 3, 1))[res.hit[:, 0]] >= 0).all())
    assert bool((BALL.f(p(hi).permute(0, 2, 3, 1))[res.hit[:, 0]] < 0).all())
    assert torch.allclose(res.normal[res.hit.expand(-1, 3, -1, -1)],
                          truth.normal[res.hit.expand(-1, 3, -1, -1)], atol=1e-6)


def test_thin_shell_punches_through_when_chord_shorter_than_step():
    rays = camera_rays(cam(), dtype=torch.float64)
    w = 0.01
    first, on, chord = shell_truth(rays, 1.0, w)
    s = rays.t_far / 32
    assert bool((chord[on] < s[on]).all())                         # w ≪ s everywhere on the shell
    res = fixed_step(shell(w), rays, FixedStepParams(steps=32))
    correct = res.hit & ((res.t - first).abs() < 1e-6)
    rate = (on & ~correct).sum().item() / on.sum().item()
    predicted = 1 - (chord / s)[on].mean().item()                  # 1 − w/h averaged over the shell pixels
    assert rate > 0.5 and abs(rate - predicted) < 0.1, (rate, predicted)


def test_never_punches_through_when_step_shorter_than_chord():
    rays = camera_rays(cam(), dtype=torch.float64)
    w = 0.02
    first, on, chord = shell_truth(rays, 1.0, w)
    res = fixed_step(shell(w), rays, FixedStepParams(steps=400))
    s = rays.t_far / 400
    thick = on & (chord >= s)
    assert thick.sum().item() > 0.9 * on.sum().item()
    assert bool(((res.t - first).abs()[thick] < 1e-6).all()) and bool(res.hit[thick].all())
    plate = FunctionSurface(lambda p: p[..., 2].abs() - w)        # face-on slab: chord 2w/cos ≥ 0.04 > s
    res = fixed_step(plate, rays, FixedStepParams(steps=400))
    t_true = (4.0 - w) / -rays.direction[:, 2:3]
    assert bool(res.hit.all()) and ((res.t - t_true).abs() <= s / 2 ** 21 + 1e-12).all()   # 20 halvings


def test_evaluation_count_is_honest():
    rays = camera_rays(cam(16, 12), dtype=torch.float64)
    N, K = 40, 7
    res = fixed_step(BALL, rays, FixedStepParams(steps=N, refine_iterations=K))
    s = rays.t_far / N
    for y in range(12):
        for x in range(16):
            t = [k * s[0, 0, y, x].item() for k in range(N + 1)]
            o, d = rays.origin[0, :, y, x], rays.direction[0, :, y, x]
            f = [BALL.f(o + ti * d).item() for ti in t]
            first = next((i for i in range(N) if f[i] >= 0 > f[i + 1]), None)
            if first is None:
                assert res.evaluations[0, 0, y, x] == N + 1 and res.termination[0, 0, y, x] == MISS
            else:                                                  # samples, bisection, one gradient
                assert res.evaluations[0, 0, y, x] == first + 2 + K + 1
                assert res.steps[0, 0, y, x] == first + 2 and res.termination[0, 0, y, x] == HIT


def test_march_lattice_counts_and_last_sample():
    wall = FunctionSurface(lambda p: 3.0 - p[..., 0])
    o, d = torch.zeros(2, 3), torch.tensor([[1.0, 0, 0], [-1.0, 0, 0]])
    found, lo, hi, n = march_lattice(wall, o, d, torch.full((2,), 0.5), torch.ones(2), 2,
                                     last=torch.full((2,), 3.5))
    assert found.tolist() == [True, False] and lo[0].item() == 1.5 and hi[0].item() == 3.5
    assert n.tolist() == [4, 4]


def test_jitter_is_seeded_and_changes_the_samples():
    rays = camera_rays(cam(24, 18), dtype=torch.float64)
    p = FixedStepParams(steps=32, jitter=True)
    g = lambda s: torch.Generator().manual_seed(s)                 # noqa: E731
    a, b, c = (fixed_step(shell(0.01), rays, p, generator=g(s)) for s in (1, 1, 2))
    assert torch.equal(a.t, b.t) and torch.equal(a.debug["R"], b.debug["R"])
    assert not torch.equal(a.debug["R"], c.debug["R"])
    assert torch.equal(fixed_step(shell(0.01), rays, FixedStepParams(steps=32, jitter=True, seed=1)).t, a.t)
    assert fixed_step(BALL, rays).debug["R"] is None


def test_float32_matches_float64_and_module():
    c = cam(24, 18, eye=(0.3, 0.5, 3.5))
    a = fixed_step(BALL, c, FixedStepParams(steps=64), dtype=torch.float64)
    b = fixed_step(BALL, c, FixedStepParams(steps=64), dtype=torch.float32)
    assert torch.equal(a.hit, b.hit) and b.t.dtype == torch.float32
    assert torch.allclose(a.t.float(), b.t, rtol=1e-5, atol=1e-5)
    assert torch.equal(FixedStep(FixedStepParams(steps=64))(BALL, camera_rays(c, dtype=torch.float64)).t, a.t)


@pytest.mark.parametrize("f", [
    lambda p: torch.where(p.norm(dim=-1) < 1, -1.0, 1.0).to(p.dtype),     # zero gradient at the hit
    lambda p: (p.norm(dim=-1) ** 2 - 1) ** 3,                             # vanishing gradient (triple root)
    lambda p: p.norm(dim=-1) - 10.0,                                      # the eye starts inside
    lambda p: torch.sqrt(p.norm(dim=-1) - 1.5) - 0.1,                     # NaN inside a ball
    lambda p: torch.ones_like(p[..., 0]),                                 # nothing at all
])
def test_no_nan(f):
    res = fixed_step(FunctionSurface(f), cam(16, 12), FixedStepParams(steps=32), dtype=torch.float64)
    for x in (res.t, res.normal):
        assert bool(torch.isfinite(x).all())
    n = res.normal.norm(dim=1, keepdim=True)
    assert bool((((n - 1).abs() < 1e-9) | (n == 0)).all())          # unit, or 0 where ∇f = 0 / no hit
    assert bool((n[~res.hit] == 0).all())


def test_bad_input():
    with pytest.raises(ValueError, match="steps: must be >= 1, got 0"):
        FixedStepParams(steps=0)
    with pytest.raises(ValueError, match="refine_iterations"):
        FixedStepParams(refine_iterations=-1)
    with pytest.raises(ValueError, match="jitter"):
        FixedStepParams(jitter=1)
    with pytest.raises(TypeError, match="surface"):
        fixed_step(object(), cam())
    with pytest.raises(TypeError, match="params"):
        fixed_step(BALL, cam(), {"steps": 3})


def test_every_caster_takes_one_call_and_returns_its_state():
    """``(surface, camera, params, *, state=None, generator=None)`` for fixed step, sphere tracing and the
    progressive method, found through the registry; only the stateful one hands a state back, and handing a
    state to a stateless one is an error naming ``state``."""
    from ssbench.passes import IMPLICIT_METHODS, declared, implicit_method
    rays = camera_rays(cam(12, 9), dtype=torch.float64)
    surf = FunctionSurface(lambda q: q.norm(dim=-1) - 1.0, lipschitz=1.0)
    for name in IMPLICIT_METHODS:
        fn, params_cls = implicit_method(name)
        res = fn(surf, rays, params_cls(), state=None, generator=torch.Generator().manual_seed(0))
        assert int(res.hit.sum()) > 0, name
        if declared(fn, "STATEFUL", False):
            again = fn(surf, rays, params_cls(), state=res.state, generator=torch.Generator().manual_seed(1))
            assert res.state is not None and again.state.frame == res.state.frame + 1, name
        else:
            assert res.state is None, name
            with pytest.raises(ValueError, match="state"):
                fn(surf, rays, params_cls(), state=object())
