"""Certified implicit-surface truth: closed forms, the dense-march cross-check, hard cases.

Scenes come from the implicit catalog at a tiny 24×18 resolution (same camera pose, fewer pixels).
"""
from dataclasses import replace

import numpy as np
import pytest
import torch

from ssbench.implicit.scene import load
from ssbench.passes.implicit.common import camera_rays
from ssbench.reference import backend
from ssbench.reference.implicit import ImplicitReference, implicit
from ssbench.reference.implicit_dense import dense_march

W, H = 24, 18
LEAF = 1e-7                                     # the reference's default leaf width (relative)


def scene(name, w=W, h=H):
    sc = load(name)
    return sc.surface(0), replace(sc.camera_at(0), width=w, height=h)


def rays(cam):
    r = camera_rays(cam, dtype=torch.float64)
    o = r.origin[0].permute(1, 2, 0).reshape(-1, 3).numpy()
    d = r.direction[0].permute(1, 2, 0).reshape(-1, 3).numpy()
    return o, d


def sphere_roots(cam, radius=1.0):
    """Both roots of |o + t d|² = radius² per pixel (nan where none) and the discriminant."""
    o, d = rays(cam)
    b = (o * d).sum(1)
    c = (o * o).sum(1) - radius ** 2
    disc = b * b - c
    s = np.sqrt(np.where(disc > 0, disc, np.nan))
    near = c / (-b + s)                                            # = −b − s without cancellation
    return near.reshape(H, W), (-b + s).reshape(H, W), disc.reshape(H, W)


def torus_first_roots(cam, R=1.0, r=0.35):
    """Smallest real positive root of the torus quartic (axis y) per pixel, and the root separation."""
    o, d = rays(cam)
    first, sep = np.full(len(o), np.nan), np.full(len(o), np.inf)
    for i, (oo, dd) in enumerate(zip(o, d)):
        a = oo @ oo + R * R - r * r
        b = oo @ dd
        oxz, dxz, odxz = oo[0] ** 2 + oo[2] ** 2, dd[0] ** 2 + dd[2] ** 2, oo[0] * dd[0] + oo[2] * dd[2]
        coef = [1.0, 4 * b, 4 * b * b + 2 * a - 4 * R * R * dxz, 4 * a * b - 8 * R * R * odxz,
                a * a - 4 * R * R * oxz]
        z = np.roots(coef)
        real = np.sort(z[np.abs(z.imag) < 1e-9].real)
        real = real[real > 0]
        if len(real):
            first[i] = real[0]
            sep[i] = np.min(np.diff(real)) if len(real) > 1 else np.inf
        if np.any((np.abs(z.imag) >= 1e-9) & (np.abs(z.imag) < 1e-3)):
            sep[i] = 0.0                                           # near-tangent: a complex pair close to real
    return first.reshape(H, W), sep.reshape(H, W)


#: both march engines (torch lock-step, one Dr.Jit kernel) answer every closed-form and behaviour test
ENGINES = ("torch", "drjit")


# ------------------------------------------------------------------------------------------ closed forms
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name", ["sphere", "badly_scaled"])
def test_unit_sphere_first_roots_match_the_quadratic(name, engine):
    surf, cam = scene(name)
    ref = implicit(surf, cam, exits=True, use_cache=False, engine=engine)
    near, far, disc = sphere_roots(cam)
    clear = np.abs(disc) > 1e-6                                    # skip exact grazing
    hit = ref.hit[0, 0].numpy()
    assert np.array_equal(hit[clear], (disc > 0)[clear]) and hit.sum() > 50
    m = hit & clear
    rel = np.abs(ref.t[0, 0].numpy()[m] - near[m]) / near[m]
    assert rel.max() <= 1e-6 and rel.max() < 1e-11                 # acceptance 1e-6; bisection gives ~1e-12
    rel_exit = np.abs(ref.t_exit[0, 0].numpy()[m] - far[m]) / far[m]
    assert rel_exit.max() < 1e-11                                  # exits=True: the chord end is the far root
    assert bool(ref.certified.all()) and not bool(ref.unfinished.any())
    assert torch.isinf(ref.ambiguous_t).all()
    n = ref.normal[0].permute(1, 2, 0).numpy()[m]
    p = (rays(cam)[0] + ref.t[0, 0].numpy().reshape(-1, 1) * rays(cam)[1]).reshape(H, W, 3)[m]
    assert np.abs(n - p).max() < 1e-9                              # unit sphere: normal = hit point
    assert (ref.object_index[ref.hit] == 0).all() and (ref.object_index[~ref.hit] == -1).all()


@pytest.mark.parametrize("engine", ENGINES)
def test_torus_first_roots_match_the_quartic(engine):
    surf, cam = scene("torus")
    ref = implicit(surf, cam, use_cache=False, engine=engine)
    first, sep = torus_first_roots(cam)
    clear = sep > 1e-4
    hit = ref.hit[0, 0].numpy()
    assert np.array_equal(hit[clear], np.isfinite(first)[clear]) and hit.sum() > 50
    m = hit & clear
    rel = np.abs(ref.t[0, 0].numpy()[m] - first[m]) / first[m]
    assert rel.max() <= 1e-6 and rel.max() < 1e-9
    assert bool(ref.certified.all()) and not bool(ref.unfinished.any())


@pytest.mark.parametrize("engine", ENGINES)
def test_double_root_is_seen_by_intervals_but_is_no_hit(engine):
    """(‖p‖−1)² ≥ 0 everywhere: no sign change, so no hit; interval arithmetic still flags it (ambiguous_t)."""
    surf, cam = scene("double_root")
    ref = implicit(surf, cam, use_cache=False, engine=engine)
    near, _, disc = sphere_roots(cam)
    assert not bool(ref.hit.any()) and not bool(ref.unfinished.any())
    amb = ref.ambiguous_t[0, 0].numpy()
    clear = np.abs(disc) > 1e-6
    assert np.array_equal(np.isfinite(amb)[clear], (disc > 0)[clear])
    m = np.isfinite(amb) & clear
    assert np.all(amb[m] <= near[m]) and np.all(near[m] - amb[m] <= 1e-4 * near[m])  # the run starts at the root
    assert not bool(ref.certified[0, 0][torch.from_numpy(m)].any())
    assert bool(ref.certified[0, 0][torch.from_numpy(~np.isfinite(amb))].all())
    dm = dense_march(surf, cam, steps=20_000)
    assert not bool(dm.hit.any())                                  # sign-change methods cannot see it


# ------------------------------------------------------------------------------------------ dense march
HARD = ["thin_shell", "thin_plate", "tangent_sphere", "badly_scaled",
        pytest.param("displaced_torus", marks=pytest.mark.slow), pytest.param("gyroid_sheet", marks=pytest.mark.slow),
        pytest.param("barth_sextic", marks=pytest.mark.slow)]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name", HARD)
def test_reference_never_misses_a_root_the_dense_march_finds(name, engine):
    surf, cam = scene(name)
    ref = implicit(surf, cam, use_cache=False, engine=engine)
    dm = dense_march(surf, cam, steps=100_000)
    assert not bool(ref.unfinished.any())
    slack = LEAF * dm.t_hi.clamp(min=1.0)                          # the hit leaf may straddle t_hi
    caught = ref.hit & (ref.t <= dm.t_hi + slack)
    assert bool(caught[dm.hit].all()), f"{name}: {int((dm.hit & ~caught).sum())} dense roots missed"
    assert int(dm.hit.sum()) > 20
    # where both hit, the reference's root is in or before the dense bracket (never after it)
    assert bool((ref.t[dm.hit] >= ref.t_start[dm.hit]).all())


def test_dense_march_backends_agree():
    surf, cam = scene("thin_shell")
    if not backend.is_jit():
        pytest.skip("no vectorised Dr.Jit variant")
    a = dense_march(surf, cam, steps=20_000, backend="drjit")
    b = dense_march(surf, cam, steps=20_000, backend="torch", chunk=200_000)
    assert a.backend == "drjit" and b.backend == "torch"
    assert torch.equal(a.hit, b.hit) and int(a.hit.sum()) > 50
    assert torch.allclose(a.t_lo, b.t_lo, rtol=1e-12, atol=0) and torch.allclose(a.t_hi, b.t_hi, rtol=1e-12, atol=0)
    assert torch.equal(a.t_start, b.t_start) and torch.equal(a.t_end, b.t_end)


def test_dense_march_bracket_contains_the_sphere_root():
    surf, cam = scene("sphere")
    dm = dense_march(surf, cam, steps=1000, backend="torch")
    near, _, disc = sphere_roots(cam)
    m = dm.hit[0, 0].numpy() & (np.abs(disc) > 1e-6)
    assert np.all(dm.t_lo[0, 0].numpy()[m] <= near[m]) and np.all(near[m] < dm.t_hi[0, 0].numpy()[m])


# ------------------------------------------------------------------------------------------ behaviour
@pytest.mark.parametrize("engine", ENGINES)
def test_deterministic_and_batched(engine):
    surf, cam = scene("torus", 12, 9)
    a, a2 = implicit(surf, cam, use_cache=False, engine=engine), implicit(surf, cam, use_cache=False, engine=engine)
    b = implicit(surf, cam, use_cache=False, batch=2, engine=engine)
    assert isinstance(a, ImplicitReference) and a.t.shape == (1, 1, 9, 12) and b.t.shape == (2, 1, 9, 12)
    fields = ("t", "hit", "certified", "ambiguous_t", "t_exit", "normal", "object_index", "interval_evaluations",
              "point_evaluations", "unfinished", "t_start", "t_end")
    for f in fields:                                              # same input, same bits
        assert torch.equal(getattr(a, f), getattr(a2, f)), f
        assert torch.equal(getattr(b, f)[0], getattr(b, f)[1]), f
    # another batch size changes the lane schedule (cost), not the answer beyond epsilon
    assert torch.equal(a.hit[0], b.hit[0]) and torch.equal(a.certified[0], b.certified[0])
    assert torch.allclose(a.t[0], b.t[0], rtol=1e-11, atol=0)
    jit = implicit(surf, cam, use_cache=False, jitter=torch.full((1, 2, 1, 1), 0.25), engine=engine)
    assert not torch.equal(jit.t, a.t)


@pytest.mark.parametrize("engine", ENGINES)
def test_iteration_cap_marks_unfinished_never_a_silent_miss(engine):
    surf, cam = scene("sphere", 12, 9)
    ref = implicit(surf, cam, max_iterations=2, use_cache=False, engine=engine)
    full = implicit(surf, cam, use_cache=False, engine=engine)
    assert bool(ref.unfinished[full.hit].all()) and not bool(ref.hit.any())
    assert not bool(ref.certified[ref.unfinished].any())
    assert torch.equal(ref.t, camera_rays(cam, dtype=torch.float64).t_far)


class UnknownPlate:
    """|z| − 0.01 whose interval says "unknown" (NaN) everywhere: only leaf point signs can decide."""
    bounds = ((-1.0, -1.0, -0.5), (1.0, 1.0, 0.5))

    def f(self, p):
        return p[..., 2].abs() - 0.01

    def f_and_grad(self, p):
        return self.f(p), torch.stack([0 * p[..., 0], 0 * p[..., 1], torch.sign(p[..., 2])], -1)

    def interval(self, lo, hi):
        nan = torch.full(lo.shape[:-1], float("nan"), dtype=torch.float64)
        return nan, nan


def test_nan_enclosure_may_hold_a_root_and_is_never_certified():
    from ssbench.camera import Camera
    cam = Camera.from_look_at((0, 0, 2), (0, 0, 0), (0, 1, 0), 20.0, 3, 2, 0.1, 10.0)
    ref = implicit(UnknownPlate(), cam, tolerance=1e-3, use_cache=False)
    assert bool(ref.hit.all()) and not bool(ref.unfinished.any())
    assert torch.allclose(ref.t, 1.99 / -camera_rays(cam, dtype=torch.float64).direction[:, 2:3], rtol=1e-12)
    assert not bool(ref.certified.any()) and bool((ref.isolation > 0.4).all())   # no interval excluded anything
    capped = implicit(UnknownPlate(), cam, tolerance=1e-3, max_iterations=5, use_cache=False)
    assert bool(capped.unfinished.all()) and not bool(capped.hit.any())


@pytest.mark.parametrize("engine", ENGINES)
def test_ray_starting_inside_finds_the_next_entering_root(engine):
    """Eye inside a shell's wall region: the exit crossing is no hit; the next entry is, uncertified."""
    from ssbench.camera import Camera
    surf, _ = scene("thin_shell")
    cam = Camera.from_look_at((0, 0, 1.0), (0, 0, -1), (0, 1, 0), 10.0, 2, 2, 0.001, 10.0)   # inside the wall
    ref = implicit(surf, cam, use_cache=False, engine=engine)
    dm = dense_march(surf, cam, steps=100_000, backend="torch")
    assert bool(ref.hit.all()) and bool(dm.hit.all()) and bool((ref.t <= dm.t_hi).all())
    assert bool((ref.t > 1.9).all()) and not bool(ref.certified.any())          # the far wall, ~2 away


def test_cache_round_trip():
    surf, cam = scene("sphere", 12, 9)
    a = implicit(surf, cam)
    b = implicit(surf, cam)
    assert all(torch.equal(getattr(a, f), getattr(b, f)) for f in ("t", "hit", "normal", "certified"))
    assert a.iterations == b.iterations


def test_bad_input_names_the_argument():
    surf, cam = scene("sphere", 4, 3)
    with pytest.raises(ValueError, match="epsilon"):
        implicit(surf, cam, epsilon=-1.0)
    with pytest.raises(ValueError, match="max_iterations"):
        implicit(surf, cam, max_iterations=0)
    with pytest.raises(ValueError, match="tolerance"):
        implicit(surf, cam, tolerance=1e-20)
    with pytest.raises(TypeError, match="surface"):
        implicit(object(), cam)
    with pytest.raises(ValueError, match="steps"):
        dense_march(surf, cam, steps=0)
    with pytest.raises(ValueError, match="backend"):
        dense_march(surf, cam, backend="cuda")


RING = {"id": "ring", "f": "length(vec3(length(vec3(x, 0, z)) - 1, y, 0)) - 0.3",
        "bounds": [[-1.4, -0.4, -1.4], [1.4, 0.4, 1.4]]}


@pytest.mark.parametrize("engine, budget", [("torch", 1000), ("drjit", 4000)])   # lock-step its / ray segments
@pytest.mark.parametrize("f", ["max(length(p) - 1, 0)",                      # f = 0 on a solid ball
                               "length(p) - 0.5 + 0*log(length(p) - 1)"])   # NaN everywhere inside |p| < 1
def test_degenerate_regions_end_in_bounded_iterations(f, engine, budget):
    """Regression: a zero or NaN region was walked one leaf per iteration (10 of 10 CLI runs past 60 s
    at 40×30); a long unresolved run is now crossed with doubling leaves. Such rays are never certified,
    the ring behind the ball is still found, and nothing is unfinished."""
    sc = load({"name": "degenerate", "camera": {"eye": [0, 2, 5], "target": [0, 0, 0], "up": [0, 1, 0],
                                                 "fovy": 45, "width": 40, "height": 30, "near": 0.1, "far": 12},
               "implicit": [{"id": "a", "f": f, "bounds": [[-1.4, -1.4, -1.4], [1.4, 1.4, 1.4]]}, RING]})
    for exits in (False, True):
        ref = implicit(sc.surface(0), sc.camera_at(0), exits=exits, use_cache=False, engine=engine)
        assert ref.iterations <= budget, ref.iterations                   # torch: was the 20000 cap, ~5 min
        assert not bool(ref.unfinished.any())
        through = torch.isfinite(ref.ambiguous_t)                            # rays that met the region
        assert int(through.sum()) > 50 and not bool(ref.certified[through].any())
        assert int((ref.hit & (ref.object_index == 1)).sum()) > 50                # the ring is hit
