"""Supercover DDA SSR: every crossed pixel once (SSR article Fig. 11), against an independent grid traversal."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes import ssr_method
from ssbench.passes.ssr.common import BEHIND_CAMERA, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS
from ssbench.passes.ssr.dda import DDASSRParams, ssr_dda
from ssbench.passes.ssr.dda_supercover import (REQUIRES, SupercoverDDASSR, SupercoverDDASSRParams,
                                               ssr_dda_supercover)
from ssbench.passes.ssr.visits import visit_map
from ssbench.passes.teaching.ssr_dda_supercover_basic import ssr_dda_supercover_basic
from tests.passes.ssr_scenes import FLOOR, WALL, analytic, one_ray, raycast, room

F64 = torch.float64
P = SupercoverDDASSRParams


def at(t: torch.Tensor, x: int, y: int) -> int:
    return int(t[0, 0, y, x])


def near_corner(cell, p0, p1, tol=1e-6) -> bool:
    """Does the segment pass within ``tol`` px of a corner of ``cell = (row, col)``? (ties at a lattice corner
    may go either way in floating point)"""
    (x0, y0), (x1, y1) = p0, p1
    dx, dy = x1 - x0, y1 - y0
    for cx in (cell[1], cell[1] + 1):
        for cy in (cell[0], cell[0] + 1):
            t = min(max(((cx - x0) * dx + (cy - y0) * dy) / (dx * dx + dy * dy), 0.0), 1.0)
            if math.hypot(x0 + t * dx - cx, y0 + t * dy - cy) < tol:
                return True
    return False


def assert_exactly_the_crossed(m, origin):
    """Visits = the crossed pixels minus the origin, once each (up to lattice-corner ties)."""
    visits, crossed = m["visits"], m["crossed"].clone()
    crossed[origin[1], origin[0]] = False
    assert int(visits.max()) == 1 and visits[origin[1], origin[0]] == 0
    diff = (visits.bool() ^ crossed).nonzero().tolist()
    assert all(near_corner(c, m["p0"], m["p1"]) for c in diff), diff
    return visits, crossed


# ----------------------------------------------------------------------------- visits (SSR article Fig. 11)
@pytest.mark.parametrize("deg", [0.0, 17.0, 45.0, 63.0, 80.0, 90.0, 135.0, 200.0, 271.0, 333.0])
def test_visits_every_crossed_pixel_exactly_once(deg):
    """Stride 1 by construction: the fetched pixels are exactly the pixels the segment crosses, each once; the
    article's DDA fetches a subset of them (one per major-axis line)."""
    a = math.radians(deg)
    g = one_ray((math.cos(a), math.sin(a), 0.0), w=49, h=41)              # lateral: depth stays −5, no hit
    m = visit_map(g, P(max_ray_distance=1.8), pixel=(24, 20))
    assert m["termination"] == MAX_DISTANCE
    visits, crossed = assert_exactly_the_crossed(m, (24, 20))
    dda = visit_map(g, DDASSRParams(max_ray_distance=1.8), pixel=(24, 20))["visits"]
    assert bool((dda.bool() <= visits.bool()).all()) and int(visits.sum()) >= int(dda.sum()) >= 12
    (x0, y0), (x1, y1) = m["p0"], m["p1"]
    if math.floor(x0) != math.floor(x1) and math.floor(y0) != math.floor(y1):   # crosses rows and columns:
        assert int(visits.sum()) > int(dda.sum())                          # it clips corners the DDA skips


def test_random_rays_visit_exactly_the_crossed_pixels():
    gen = torch.Generator().manual_seed(11)
    terms = set()
    for _ in range(40):
        d = torch.randn(3, generator=gen, dtype=F64)
        x, y = (int(v) for v in torch.randint(2, 30, (2,), generator=gen))
        g = one_ray(tuple(d.tolist()), w=32, h=32, pixel=(x, y))
        m = visit_map(g, P(max_ray_distance=20.0, max_steps=4096), pixel=(x, y))
        terms.add(m["termination"])
        assert m["termination"] in (MAX_DISTANCE, OFF_SCREEN, BEHIND_CAMERA)
        assert_exactly_the_crossed(m, (x, y))
    assert {OFF_SCREEN, MAX_DISTANCE} <= terms


def test_corner_pixel_occluder_is_caught_only_by_the_supercover():
    """A one-texel occluder on a pixel whose corner the ray clips: the DDA (stride 1) steps past it, the
    supercover fetches it and hits."""
    a = math.radians(17.0)
    g = one_ray((math.cos(a), math.sin(a), 0.0), w=49, h=41)
    m, dda = visit_map(g, P(max_ray_distance=1.8), (24, 20)), visit_map(g, DDASSRParams(max_ray_distance=1.8), (24, 20))
    corner = (m["visits"].bool() & ~dda["visits"].bool()).nonzero().tolist()
    assert corner
    y, x = corner[len(corner) // 2]
    vz, mask, nrm = g.view_z.clone(), g.mask.clone(), g.normal.clone()
    vz[0, 0, y, x], mask[0, 0, y, x], nrm[0, :, y, x] = -4.98, True, torch.tensor([0.0, 0.0, 1.0], dtype=F64)
    occ = GBuffer(g.camera, view_z=vz, normal=nrm, mask=mask, color=g.color)
    s = ssr_dda_supercover(occ, P(max_ray_distance=1.8))
    d = ssr_dda(occ, DDASSRParams(max_ray_distance=1.8))
    assert at(s.termination, 24, 20) == HIT and s.hit_pixel[0, :, 20, 24].floor().tolist() == [x, y]
    assert at(d.termination, 24, 20) == MAX_DISTANCE                       # punched through the corner pixel


# ----------------------------------------------------------------------------- closed form
def test_mirror_floor_hits_wall_closed_form():
    """Floor → wall reflections: hit texel and point against the exact ray/plane intersection. The crossing of
    the texel plane is exact in its cell, so the error is the texel's depth quantisation, below the DDA's."""
    g = room()
    target, ok = analytic(g, [FLOOR, WALL])
    pix = g.camera.view_to_pixel(target)
    W, H = g.width, g.height
    inside = ok & (g.shape_id == 0) & (pix[:, :1] > 1) & (pix[:, :1] < W - 1) & (pix[:, 1:] > 1) & (pix[:, 1:] < H - 1)
    s = ssr_dda_supercover(g, P(max_ray_distance=50.0))
    d = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, refinement="none"))
    assert int(inside.sum()) > 300 and bool(s.hit[inside].all())
    err_s = (s.hit_pixel - pix).norm(dim=1, keepdim=True)[inside]
    err_d = (d.hit_pixel - pix).norm(dim=1, keepdim=True)[inside & d.hit]
    assert float(err_s.max()) < 1.0 and float(err_s.mean()) < 0.5 * float(err_d.mean()), (err_s.mean(), err_d.mean())
    assert bool(((s.hit_pixel[:, :1].floor() - pix[:, :1].floor()).abs() <= 1)[inside].all())


# ----------------------------------------------------------------------------- hard cases
def finite(r) -> bool:
    return all(bool(torch.isfinite(t).all()) for t in (r.color, r.hit_pixel, r.hit_view, r.fade, r.raw_color))


def test_toward_camera_and_near_plane():
    g = one_ray(normal=(0.0, 0.0, 1.0), z=-3.0, near=1.0, pixel=(17, 12))
    r = ssr_dda_supercover(g, P(max_ray_distance=10.0))
    assert finite(r) and at(r.termination, 17, 12) == BEHIND_CAMERA and at(r.steps, 17, 12) >= 1
    assert int(r.termination.ne(NO_RAY).sum()) == 1                       # background: no ray
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 45.0, 16, 12, 0.1, 100.0)
    n = torch.zeros(1, 3, 12, 16, dtype=F64)
    n[:, 2] = 1.0
    near = GBuffer(cam, view_z=torch.full((1, 1, 12, 16), -0.105, dtype=F64), normal=n,
                   mask=torch.ones(1, 1, 12, 16, dtype=torch.bool), color=torch.ones(1, 3, 12, 16, dtype=F64))
    r = ssr_dda_supercover(near)                                          # 0.005 of ray, then the near plane
    assert finite(r) and bool((r.termination[..., 1:-1, 1:-1] == BEHIND_CAMERA).all())
    assert set(r.termination.unique().tolist()) == {BEHIND_CAMERA, OFF_SCREEN}   # border rays leave the screen
    #                                                                       before the near plane


@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_grazing_degenerate_and_off_screen(dtype):
    g = one_ray(normal=(0.0, 1.0, 0.0), pixel=(16, 12))                   # R = I: |ΔP| < 0.01 px, nudged
    r = ssr_dda_supercover(g.to(dtype=dtype))
    assert finite(r) and at(r.termination, 16, 12) == MAX_DISTANCE
    cam = Camera.from_look_at((0, 0.02, 0), (0, 0.02, -1), (0, 1, 0), 60.0, 32, 24, 0.01, 100.0)
    low = raycast(cam, [(*FLOOR, None)], dtype)                           # a floor seen edge-on
    r = ssr_dda_supercover(low, P(max_ray_distance=100.0))
    assert finite(r) and bool((r.termination[~low.mask] == NO_RAY).all())
    assert set(r.termination[low.mask].unique().tolist()) <= {HIT, OFF_SCREEN, MAX_DISTANCE, OUT_OF_STEPS}
    off = ssr_dda_supercover(one_ray((1.0, 0.2, 0.0)).to(dtype=dtype), P(max_ray_distance=50.0))
    assert at(off.termination, 16, 12) == OFF_SCREEN and not bool(off.hit.any()) and finite(off)


def test_out_of_steps_is_never_a_hit():
    g = room()
    full, short = ssr_dda_supercover(g, P(max_ray_distance=50.0)), ssr_dda_supercover(g, P(max_ray_distance=50.0,
                                                                                              max_steps=3))
    far = full.hit & (full.steps > 3)
    assert int(far.sum()) > 100
    assert bool((short.termination[far] == OUT_OF_STEPS).all()) and not bool(short.hit[far].any())
    near = full.hit & (full.steps <= 3)
    assert torch.equal(short.hit_pixel[near.expand(-1, 2, -1, -1)], full.hit_pixel[near.expand(-1, 2, -1, -1)])


# ----------------------------------------------------------------------------- precision, twin, API
def test_float32_matches_float64():
    g = room(64, 48)
    r32, r64 = ssr_dda_supercover(g.to(dtype=torch.float32), P(max_ray_distance=50.0)), \
        ssr_dda_supercover(g, P(max_ray_distance=50.0))
    agree = float((r32.termination == r64.termination).double().mean())
    assert agree >= 0.999, agree
    both = r32.hit & r64.hit
    assert float((r32.hit_pixel.double() - r64.hit_pixel).abs()[both.expand(-1, 2, -1, -1)].max()) < 1e-2


@pytest.mark.parametrize("kw,slat", [(dict(), False), (dict(max_steps=5), False), (dict(z_thickness=1.0), True),
                                     (dict(edge_fade_mode="circular", max_ray_distance=5.0), True)])
def test_teaching_twin_equals_vectorised(kw, slat):
    g = room(16, 12, slat=slat)
    p = P(**{"max_ray_distance": 30.0, **kw})
    a, b = ssr_dda_supercover(g, p), ssr_dda_supercover_basic(g, p)
    assert torch.equal(a.termination, b.termination) and torch.equal(a.hit, b.hit) and torch.equal(a.steps, b.steps)
    assert float((a.hit_pixel - b.hit_pixel).abs().max()) <= 1e-9
    assert torch.allclose(a.hit_view, b.hit_view, atol=1e-9) and torch.allclose(a.color, b.color, atol=1e-9)
    assert HIT in a.termination.unique().tolist()


def test_module_batch_debug_and_registry():
    g = room(24, 18)
    r = ssr_dda_supercover(g, debug=True)
    m = SupercoverDDASSR(debug=True)(g)
    assert torch.equal(r.color, m.color) and torch.equal(r.termination, m.termination)
    assert int(r.debug["visits"].sum()) == int(r.steps.sum()) and set(REQUIRES) <= set(g.channels)
    b = ssr_dda_supercover(GBuffer.cat([g, g]))
    assert torch.equal(b.hit_pixel[1:], r.hit_pixel) and torch.equal(b.steps[1:], r.steps)
    fn, cls, _ = ssr_method("dda_supercover")
    assert fn is ssr_dda_supercover and cls is SupercoverDDASSRParams


@pytest.mark.parametrize("kw,name", [
    (dict(max_steps=0), "max_steps"), (dict(z_thickness=-1.0), "z_thickness"), (dict(max_ray_distance=0.0),
                                                                                "max_ray_distance"),
    (dict(edge_fade_mode="square"), "edge_fade_mode"), (dict(fade_exponent=0.0), "fade_exponent"),
    (dict(z_thickness=math.nan), "z_thickness")])
def test_bad_params(kw, name):
    with pytest.raises(ValueError, match=name):
        P(**kw)


def test_bad_input():
    g = room(8, 6)
    with pytest.raises(TypeError, match="params"):
        ssr_dda_supercover(g, DDASSRParams())
    with pytest.raises(ValueError, match="color"):
        ssr_dda_supercover(g.select(["view_z", "normal", "mask"]))
    with pytest.raises(ValueError, match="pixel"):
        visit_map(g, P(), pixel=(8, 0))


@pytest.mark.slow
def test_float32_colour_equals_float64_on_cornell_box():
    """Regression: hits on an integer texel boundary (9.000005 in float32, 8.999999999999998 in
    float64) fetched another texel on 13 of 3072 pixels (max colour difference 0.8); the walk now runs in
    float64 and the texel is floored before any cast."""
    from ssbench.reference import gbuffer
    g = gbuffer("cornell_box", 64, 48, channels=("view_z", "normal", "mask", "color"))
    r64, r32 = ssr_dda_supercover(g.to(dtype=torch.float64)), ssr_dda_supercover(g.to(dtype=torch.float32))
    assert torch.equal(r32.termination, r64.termination) and int(r64.hit.sum()) > 100
    assert float((r64.color - r32.color.double()).abs().max()) < 1e-4


@pytest.mark.slow
def test_the_compiled_walk_gives_the_eager_bits_at_two_sizes_without_recompiling():
    """The cell walk steps through ``torch.compile`` (size-dynamic; eight steps per call, one with ``debug``): every
    output and the visit map equal eager, with a thin bar, a thick texel and a step budget that is not a multiple of
    eight; a second size compiles nothing."""
    from ssbench.passes.compiled import STEPS_PER_CALL
    from ssbench.passes.ssr.dda_supercover_walk import walk_steps
    from tests.passes.compiled_check import check_compiled_at_two_sizes
    settings = [P(max_ray_distance=30.0), P(max_ray_distance=30.0, z_thickness=1.0, max_steps=21)]
    assert settings[-1].max_steps % STEPS_PER_CALL and walk_steps.eager is not walk_steps
    for debug in (True, False):                                            # (each flag compiles its own kernel)
        check_compiled_at_two_sizes(lambda w, h: room(w, h, torch.float32, slat=True),
                                    lambda g, p: ssr_dda_supercover(g, p, debug=debug), settings, ((40, 30), (48, 36)))
