"""DDA SSR (SSR article §2.2): synthetic analytic G-buffers (ray/plane intersections, no Mitsuba)."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes.ssr.common import (BEHIND_CAMERA, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS,
                                       reflection_rays)
from ssbench.passes.ssr.dda import DDASSR, REQUIRES, DDASSRParams, ssr_dda
from ssbench.passes.ssr.visits import crossed_pixels, visit_map
from ssbench.passes.teaching.ssr_dda_basic import ssr_dda_basic
from tests.passes.ssr_scenes import FLOOR, WALL, analytic, one_ray, raycast, room

F64 = torch.float64


def at(t: torch.Tensor, x: int, y: int) -> int:
    return int(t[0, 0, y, x])


# ----------------------------------------------------------------------------- projection and closed form
@pytest.mark.parametrize("refinement", ["none", "binary", "remarch"])
def test_mirror_floor_hits_wall_closed_form(refinement):
    g = room()
    cam, W, H = g.camera, g.width, g.height
    r = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, refinement=refinement))
    target, ok = analytic(g, [FLOOR, WALL])
    pix = cam.view_to_pixel(target)
    floor = ok & (g.shape_id == 0)
    inside = floor & (pix[:, :1] > 1) & (pix[:, :1] < W - 1) & (pix[:, 1:] > 1) & (pix[:, 1:] < H - 1)
    outside = floor & ((pix[:, :1] < -1) | (pix[:, :1] > W + 1) | (pix[:, 1:] < -1) | (pix[:, 1:] > H + 1))
    assert int(inside.sum()) > 600 and int(outside.sum()) > 10
    assert bool(r.hit[inside].all())
    err = (r.hit_pixel - pix).norm(dim=1, keepdim=True)[inside]
    assert float(err.max()) < 1.0, float(err.max())                       # found within a pixel (stride 1)
    assert bool((r.termination[outside] == OFF_SCREEN).all())
    # the hit point lies on the ray, projects to hit_pixel, and carries the colour of its texel
    o = g.position
    R = reflection_rays(o, g.normal)
    off_line = torch.cross(r.hit_view - o, R, dim=1).norm(dim=1, keepdim=True)
    assert float(off_line[r.hit].max()) < 1e-9
    assert torch.allclose(cam.view_to_pixel(r.hit_view)[r.hit.expand(-1, 2, -1, -1)],
                          r.hit_pixel[r.hit.expand(-1, 2, -1, -1)], atol=1e-6)
    col, row = r.hit_pixel[:, 0].floor().long(), r.hit_pixel[:, 1].floor().long()
    hit = r.hit[0, 0]
    assert torch.equal(r.raw_color[0][:, hit], g.color[0][:, row[0][hit], col[0][hit]])
    assert torch.allclose(r.color, r.raw_color * r.fade) and bool((r.fade[~r.hit] == 0).all())


def test_refinement_sharpens_strided_hits():
    g = room()
    target, ok = analytic(g, [FLOOR, WALL])
    pix = g.camera.view_to_pixel(target)
    errs = {}
    for refinement in ("none", "binary", "remarch"):
        p = DDASSRParams(max_ray_distance=50.0, pixel_stride=4.0, pixel_stride_z_cutoff=math.inf,
                         refinement=refinement, binary_search_iterations=4)
        r = ssr_dda(g, p)
        good = r.hit & ok & (g.shape_id == 0)
        errs[refinement] = float((r.hit_pixel - pix).norm(dim=1, keepdim=True)[good].mean())
    assert errs["binary"] < 0.7 * errs["none"] and errs["remarch"] < 0.7 * errs["none"], errs


# ----------------------------------------------------------------------------- DDA visits (SSR article Fig. 11)
def test_crossed_pixels_is_exact():
    g = torch.Generator().manual_seed(3)
    for _ in range(20):
        p0, p1 = (torch.rand(2, 2, generator=g, dtype=F64) * torch.tensor([30.0, 20.0], dtype=F64)).tolist()
        crossed = crossed_pixels(p0, p1, 20, 30)
        t = torch.linspace(0, 1, 20001, dtype=F64)[:, None]
        pts = torch.tensor(p0, dtype=F64) * (1 - t) + torch.tensor(p1, dtype=F64) * t
        dense = torch.zeros(20, 30, dtype=torch.bool)
        dense[pts[:, 1].floor().long().clamp(0, 19), pts[:, 0].floor().long().clamp(0, 29)] = True
        assert bool((dense <= crossed).all())
        for y, x in crossed.nonzero().tolist():                         # every crossed square meets the segment
            lo, hi = 0.0, 1.0                                             # Liang–Barsky clip against the square
            for a, d, b0, b1 in ((p0[0], p1[0] - p0[0], x, x + 1), (p0[1], p1[1] - p0[1], y, y + 1)):
                if abs(d) < 1e-15:
                    assert b0 <= a <= b1
                    continue
                ta, tb = sorted(((b0 - a) / d, (b1 - a) / d))
                lo, hi = max(lo, ta), min(hi, tb)
            assert lo <= hi + 1e-12


@pytest.mark.parametrize("deg", [0.0, 17.0, 45.0, 63.0, 80.0, 90.0, 135.0, 200.0, 271.0, 333.0])
def test_dda_samples_every_major_line_once(deg):
    """Stride 1: one fetch per pixel line along the major axis, each inside the pixels the segment crosses."""
    a = math.radians(deg)
    g = one_ray((math.cos(a), math.sin(a), 0.0), w=49, h=41)              # a lateral ray: depth stays −5
    m = visit_map(g, DDASSRParams(max_ray_distance=1.8), pixel=(24, 20))
    visits, crossed, (x0, y0), (x1, y1) = m["visits"], m["crossed"], m["p0"], m["p1"]
    assert m["termination"] == MAX_DISTANCE and int(visits.max()) == 1
    assert bool((visits.bool() <= crossed).all()) and visits[20, 24] == 0        # the origin is never sampled
    major = 0 if abs(x1 - x0) >= abs(y1 - y0) else 1
    lines = visits.nonzero()[:, 1 - major]                                # (row, col) → the major coordinate
    start, stop = (x0, x1) if major == 0 else (y0, y1)
    n = math.ceil(abs(stop - start) - 0.5)         # samples at start ± 1, ± 2, … whose footprint (±½) starts
    #                                                before P1; the last one is shortened to end at P1
    assert visits.sum() == n == lines.unique().numel() >= 12              # one visit per line, no line skipped
    step = 1 if stop > start else -1
    assert sorted(lines.tolist()) == sorted(math.floor(start) + step * i for i in range(1, n + 1))
    # what the DDA skips are corner cuts: crossed pixels in a line that already has its one sample
    skipped = crossed & ~visits.bool()
    skipped[20, 24] = False
    assert set(skipped.nonzero()[:, 1 - major].tolist()) <= set(lines.tolist()) | {math.floor(stop)}


def test_degenerate_line_toward_the_eye():
    g = one_ray((0.0, 0.0, 1.0))                                          # straight back at the eye: |ΔP| ≈ 0
    m = visit_map(g, DDASSRParams(), pixel=(16, 12))
    assert abs(m["p1"][0] - m["p0"][0] - 0.01) < 1e-9 and abs(m["p1"][1] - m["p0"][1] - 0.01) < 1e-9  # nudged
    assert int(m["visits"].sum()) == 0 and int(m["crossed"].sum()) == 1
    assert m["termination"] == BEHIND_CAMERA                              # clipped at the near plane


def test_stride_is_in_pixels():
    g = room(64, 48)
    steps, rs = {}, {}
    for stride in (1.0, 2.0, 4.0):
        rs[stride] = r = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, pixel_stride=stride,
                                                  pixel_stride_z_cutoff=math.inf, refinement="none"))
        o = g.camera.pixel_centers(F64)[None]
        # every step moves exactly `stride` pixels along the major axis, but a last one shortened at the image edge
        moved = (r.hit_pixel - o).abs().amax(1, keepdim=True)
        full = r.steps.to(F64) * stride
        exact = r.hit & ((moved - full).abs() <= 1e-6)
        edge = torch.minimum(r.hit_pixel, torch.tensor([64.0, 48.0], dtype=F64).view(1, 2, 1, 1) - r.hit_pixel)
        last = r.hit & (moved > full - 0.5 * stride) & (moved < full - 0.25 * stride) & \
            (edge.amin(1, keepdim=True) < 0.5 * stride)                   # centre of [P − ½dP, edge]
        assert bool((exact | last)[r.hit].all()) and int(exact.sum()) > 10 * int(last.sum())
        steps[stride] = r.steps
    far = rs[1.0].hit & rs[2.0].hit & rs[4.0].hit & (steps[1.0] >= 16) & (g.shape_id == 0)   # floor → wall
    assert int(far.sum()) > 100
    assert bool(((steps[1.0][far] - 2 * steps[2.0][far]).abs() <= 1).all())
    assert bool(((steps[2.0][far] - 2 * steps[4.0][far]).abs() <= 1).all())


# ----------------------------------------------------------------------------- hard cases
def finite(r) -> bool:
    return all(bool(torch.isfinite(t).all()) for t in (r.color, r.hit_pixel, r.hit_view, r.fade, r.raw_color))


def test_toward_camera_crosses_near_plane():
    g = one_ray(normal=(0.0, 0.0, 1.0), z=-3.0, near=1.0, pixel=(17, 12))    # one pixel right of the centre
    r = ssr_dda(g, DDASSRParams(max_ray_distance=10.0))
    assert finite(r) and at(r.termination, 17, 12) == BEHIND_CAMERA and at(r.steps, 17, 12) >= 2
    assert int(r.termination.ne(NO_RAY).sum()) == 1                       # background: no ray


def test_origin_at_the_near_plane():
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 45.0, 16, 12, 0.1, 100.0)
    n = torch.zeros(1, 3, 12, 16, dtype=F64)
    n[:, 2] = 1.0
    g = GBuffer(cam, view_z=torch.full((1, 1, 12, 16), -0.105, dtype=F64), normal=n,
                mask=torch.ones(1, 1, 12, 16, dtype=torch.bool), color=torch.ones(1, 3, 12, 16, dtype=F64))
    r = ssr_dda(g)
    assert finite(r) and bool((r.termination == BEHIND_CAMERA).all())      # 0.005 of ray, then the near plane


@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_grazing_and_degenerate_no_nan(dtype):
    g = one_ray(normal=(0.0, 1.0, 0.0), pixel=(16, 12))                   # N ⟂ I = −z: R = I, straight on
    r = ssr_dda(g.to(dtype=dtype), DDASSRParams())
    assert finite(r) and at(r.termination, 16, 12) == MAX_DISTANCE
    cam = Camera.from_look_at((0, 0.02, 0), (0, 0.02, -1), (0, 1, 0), 60.0, 32, 24, 0.01, 100.0)
    low = raycast(cam, [(*FLOOR, None)], dtype)                           # a floor seen edge-on
    r = ssr_dda(low, DDASSRParams(max_ray_distance=100.0))
    assert finite(r) and bool((r.termination[~low.mask] == NO_RAY).all())
    assert set(r.termination[low.mask].unique().tolist()) <= {HIT, OFF_SCREEN, MAX_DISTANCE, OUT_OF_STEPS}


def test_target_off_screen():
    g = one_ray((1.0, 0.2, 0.0))
    r = ssr_dda(g, DDASSRParams(max_ray_distance=50.0))
    assert at(r.termination, 16, 12) == OFF_SCREEN and not bool(r.hit.any()) and finite(r)


def test_thin_slat_punch_through_is_pinned():
    """A one-pixel bar (row 26) in front of a wall, seen in the floor from row 44: strides 1–3 land a sample on
    row 26 (44 − 26 = 18 is a multiple of 1, 2, 3) and hit the bar; stride 4 samples rows 40, 36, …, 28, 24,
    steps over the bar and hits the wall behind it; jitter shifts the phase per pixel and hits it sometimes."""
    g = room(64, 64, slat=True)
    bar = g.shape_id == 2
    assert bar[0, 0].any(1).nonzero().flatten().tolist() == [26]
    target, ok = analytic(g, [FLOOR, ((0.0, 0.0, -6.0), (0.0, 0.0, 1.0)), WALL])
    world = g.camera.view_to_world(target)
    aim = ok & (g.shape_id == 0) & ((world[:, 2:] + 4.0).abs() < 1e-9) & (world[:, 1:2] > 0.9) & (world[:, 1:2] < 1.05)
    pix = g.camera.view_to_pixel(target)
    aim &= (pix[:, :1] > 1) & (pix[:, :1] < 63)
    assert aim[0, 0].any(1).nonzero().flatten().tolist() == [44] and int(aim.sum()) >= 50
    for stride, jitter, on_bar in ((1.0, 0, 1.0), (2.0, 0, 1.0), (3.0, 0, 1.0), (4.0, 0, 0.0), (4.0, 1, None)):
        p = DDASSRParams(max_ray_distance=50.0, pixel_stride=stride, pixel_stride_z_cutoff=math.inf, jitter=jitter)
        r = ssr_dda(g, p)
        assert bool(r.hit[aim].all())
        z = g.camera.view_to_world(r.hit_view)[:, 2:][aim]
        bar_hits = float(((z + 4.0).abs() < 0.2).double().mean())
        assert bar_hits + float(((z + 6.0).abs() < 0.3).double().mean()) == 1.0   # the bar or the wall behind
        if on_bar is None:
            assert 0.0 < bar_hits < 1.0, bar_hits
        else:
            assert bar_hits == on_bar, (stride, bar_hits)


def test_out_of_steps_is_never_a_hit():
    g = room()
    full = ssr_dda(g, DDASSRParams(max_ray_distance=50.0))
    short = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, max_steps=3))
    far = full.hit & (full.steps > 3)
    assert int(far.sum()) > 100
    assert bool((short.termination[far] == OUT_OF_STEPS).all()) and not bool(short.hit[far].any())
    assert bool((short.color[far.expand(-1, 3, -1, -1)] == 0).all())
    near = full.hit & (full.steps <= 3)
    assert torch.equal(short.hit_pixel[near.expand(-1, 2, -1, -1)], full.hit_pixel[near.expand(-1, 2, -1, -1)])


@pytest.mark.parametrize("refinement", ["none", "binary"])
def test_fit_stride_reaches_long_rays_within_budget(refinement):
    """max_steps = 8: long floor → wall rays run out at stride 1, the fitted stride reaches their target."""
    g, K = room(), 8
    full = ssr_dda(g, DDASSRParams(max_ray_distance=50.0))
    short = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, max_steps=K))
    fit = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, max_steps=K, fit_stride_to_steps=True, refinement=refinement))
    target, ok = analytic(g, [FLOOR, WALL])
    pix = g.camera.view_to_pixel(target)
    inside = ok & (g.shape_id == 0) & (pix[:, :1] > 1) & (pix[:, :1] < g.width - 1) & (pix[:, 1:] > 1) & \
        (pix[:, 1:] < g.height - 1)
    far = inside & full.hit & (full.steps > K)
    assert int(far.sum()) > 300 and bool((short.termination[far] == OUT_OF_STEPS).all())
    assert bool(fit.hit[far].all())
    err = (fit.hit_pixel - pix).norm(dim=1, keepdim=True)[far]
    assert float(err.max()) < (0.5 if refinement == "binary" else 4.0), float(err.max())
    if refinement == "none":
        assert int(fit.steps.max()) <= K                                  # DDA samples only: within the budget


def test_fit_stride_changes_nothing_when_the_budget_suffices():
    g = room()
    for kw in (dict(), dict(pixel_stride=2.0, jitter=1.0)):
        a = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, max_steps=4096, **kw))
        b = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, max_steps=4096, fit_stride_to_steps=True, **kw))
        assert torch.equal(a.termination, b.termination) and torch.equal(a.hit_pixel, b.hit_pixel)
        assert torch.equal(a.steps, b.steps)


# ----------------------------------------------------------------------------- precision, seeds, API
def test_float32_matches_float64():
    g = room(64, 48)
    for p in (DDASSRParams(max_ray_distance=50.0), DDASSRParams(pixel_stride=3.0, jitter=1.0)):
        r32, r64 = ssr_dda(g.to(dtype=torch.float32), p), ssr_dda(g, p)
        agree = (r32.termination == r64.termination).double().mean()
        assert float(agree) >= 0.999, float(agree)
        both = r32.hit & r64.hit
        assert float((r32.hit_pixel.double() - r64.hit_pixel).abs()[both.expand(-1, 2, -1, -1)].max()) < 1e-2


def test_seed_determinism_with_jitter():
    g = room(32, 24)
    p = DDASSRParams(max_ray_distance=50.0, pixel_stride=3.0, jitter=1.0, seed=7)
    a, b = ssr_dda(g, p), ssr_dda(g, p)
    assert torch.equal(a.hit_pixel, b.hit_pixel) and torch.equal(a.termination, b.termination)
    c = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, pixel_stride=3.0, jitter=1.0, seed=8))
    assert not torch.equal(a.hit_pixel, c.hit_pixel)
    d = ssr_dda(g, p, generator=torch.Generator().manual_seed(7))
    assert torch.equal(a.hit_pixel, d.hit_pixel)


def test_module_batch_and_debug():
    g = room(24, 18)
    p = DDASSRParams(max_ray_distance=50.0, pixel_stride=2.0)
    r = ssr_dda(g, p, debug=True)
    m = DDASSR(p, debug=True)(g)
    assert torch.equal(r.color, m.color) and torch.equal(r.termination, m.termination)
    assert int(r.debug["visits"].sum()) == int(r.steps.sum())              # every fetch is one step
    assert r.debug["ray_end"].shape == (1, 2, 18, 24) and set(REQUIRES) <= set(g.channels)
    b = ssr_dda(GBuffer.cat([g, g]), p)
    assert torch.equal(b.hit_pixel[1:], r.hit_pixel) and torch.equal(b.steps[1:], r.steps)


@pytest.mark.parametrize("kw", [dict(), dict(pixel_stride=3.0, jitter=1.0),
                                dict(pixel_stride=3.0, jitter=0.5, refinement="remarch", edge_fade_mode="circular"),
                                dict(pixel_stride=2.5, refinement="none", max_steps=5, pixel_stride_z_cutoff=10.0),
                                dict(fit_stride_to_steps=True, max_steps=4),
                                dict(fit_stride_to_steps=True, max_steps=6, jitter=1.0, refinement="remarch"),
                                dict(fit_stride_to_steps=True, max_steps=3, pixel_stride=2.0,
                                     pixel_stride_z_cutoff=5.0, refinement="none")])
def test_teaching_twin_equals_vectorised(kw):
    g = room(16, 12)
    p = DDASSRParams(max_ray_distance=30.0, **kw)
    a, b = ssr_dda(g, p), ssr_dda_basic(g, p)
    assert torch.equal(a.termination, b.termination) and torch.equal(a.hit, b.hit) and torch.equal(a.steps, b.steps)
    assert float((a.hit_pixel - b.hit_pixel).abs().max()) <= 1e-5
    assert torch.allclose(a.hit_view, b.hit_view, atol=1e-9) and torch.allclose(a.color, b.color, atol=1e-9)
    assert {HIT, OFF_SCREEN} <= set(a.termination.unique().tolist())


@pytest.mark.parametrize("kw,name", [
    (dict(max_steps=0), "max_steps"), (dict(pixel_stride=0.5), "pixel_stride"), (dict(z_thickness=-1.0), "z_thickness"),
    (dict(max_ray_distance=0.0), "max_ray_distance"), (dict(pixel_stride_z_cutoff=0.0), "pixel_stride_z_cutoff"),
    (dict(jitter=math.nan), "jitter"), (dict(binary_search_iterations=-1), "binary_search_iterations"),
    (dict(refinement="secant"), "refinement"), (dict(fade_exponent=0.0), "fade_exponent"), (dict(seed=-1), "seed"),
    (dict(edge_fade_mode="square"), "edge_fade_mode"), (dict(fit_stride_to_steps=1), "fit_stride_to_steps"),
    (dict(fit_stride_to_steps="auto"), "fit_stride_to_steps")])
def test_bad_params(kw, name):
    with pytest.raises(ValueError, match=name):
        ssr_dda(room(8, 6), DDASSRParams(**kw))


def test_bad_gbuffer():
    g = room(8, 6)
    with pytest.raises(ValueError, match="color"):
        ssr_dda(g.select(["view_z", "normal", "mask"]))
    with pytest.raises(ValueError, match="view_z"):
        ssr_dda(GBuffer(g.camera, view_z=g.view_z * math.nan, normal=g.normal, mask=g.mask, color=g.color))
    with pytest.raises(ValueError, match="normal"):
        ssr_dda(GBuffer(g.camera, view_z=g.view_z, normal=g.normal * 2, mask=g.mask, color=g.color))
    with pytest.raises(ValueError, match="pixel"):
        visit_map(g, pixel=(8, 0))
    with pytest.raises(TypeError, match="params"):
        ssr_dda(g, params={"pixel_stride": 2})


@pytest.mark.parametrize("stride", [1.0, 3.0, 8.0])
def test_last_footprint_reaches_the_image_edge(stride):
    """A surface only in the top row: the sample whose centre leaves the image still has footprint on screen.

    From row 20.5 straight up, strides 3 and 8 put the last on-screen centres at rows 2.5 and 4.5, their footprints
    end at rows 1 and 0.5; the next centre (−0.5, −3.5) is off screen. Regression: that sample was dropped
    (``OFF_SCREEN``), so row 0 was never tested; now it is tested over ``[P − ½dP, edge]`` at that part's centre.
    """
    g = one_ray((0.0, 1.0, 0.0), pixel=(16, 20))                          # lateral: the ray stays at z = −5
    g.view_z[0, 0, 0, 16], g.mask[0, 0, 0, 16], g.normal[0, 2, 0, 16] = -4.95, True, 1.0   # 0.05 in front
    for fn in (ssr_dda, ssr_dda_basic):
        r = fn(g, DDASSRParams(max_ray_distance=50.0, pixel_stride=stride, pixel_stride_z_cutoff=math.inf))
        assert at(r.termination, 16, 20) == HIT and finite(r)
        assert r.hit_pixel[0, :, 20, 16].floor().tolist() == [16.0, 0.0]


@pytest.mark.parametrize("method", ["dda", "dda_supercover", "hiz", "three_ssr"])
def test_marching_in_chunks_of_rays_changes_no_bit(method, monkeypatch):
    """The marchers that march chunks of rays at a time (a bounded working set: the DDA's MARCH_CHUNK, the
    supercover's and Hi-Z's RAY_CHUNK through :func:`~ssbench.passes.ssr.dda_state.march_in_chunks`, three.js SSR's
    RAY_CHUNK), each chunk setting up its own rays (the pixel centres of its rays, not of the image): chunks of 7
    rays give the same outputs, debug buffers included, as one chunk for every ray; with jitter and two images too."""
    import dataclasses

    import ssbench.passes.ssr.dda as D
    import ssbench.passes.ssr.dda_state as DS
    import ssbench.passes.ssr.hiz as Z
    import ssbench.passes.ssr.three_ssr as T
    from ssbench.passes import ssr_method
    from tests.passes.ssr_scenes import room
    g = room(40, 30, slat=True)
    g = dataclasses.replace(g, **{f.name: torch.cat([v, v.flip(-1)]) for f in dataclasses.fields(g)
                                  if isinstance(v := getattr(g, f.name), torch.Tensor)})     # two images
    fn, params_cls, _ = ssr_method(method)
    module, name = {"dda": (D, "MARCH_CHUNK"), "dda_supercover": (DS, "RAY_CHUNK"), "hiz": (Z, "RAY_CHUNK"),
                    "three_ssr": (T, "RAY_CHUNK")}[method]
    params = params_cls(jitter=0.5) if method == "dda" else params_cls()

    def run(chunk):
        monkeypatch.setattr(module, name, chunk)
        return fn(g, params, debug=True)
    whole, chunked = run(1 << 40), run(7)
    assert int(whole.hit.sum()) > 0
    for f in dataclasses.fields(whole):
        v = getattr(whole, f.name)
        if isinstance(v, torch.Tensor):
            assert torch.equal(v, getattr(chunked, f.name)), f.name
    assert whole.debug and whole.debug.keys() == chunked.debug.keys()
    for k, v in whole.debug.items():
        assert torch.equal(v, chunked.debug[k]), k


def _slabs(g, depth):
    """``g`` with ``back_z`` a slab ``depth`` behind every surface (−inf on the background)."""
    import dataclasses
    return dataclasses.replace(g, back_z=torch.where(g.mask, g.view_z - depth, -math.inf))


@pytest.mark.parametrize("kw", [dict(), dict(pixel_stride=3.0, jitter=1.0, refinement="remarch")])
def test_back_face_depth_is_a_per_texel_thickness(kw):
    """Layered depth: a slab down to ``back_z`` with no extra thickness is the constant thickness of that depth,
    exactly; a thinner slab misses where the constant model hits, and the twin agrees."""
    g = _slabs(room(32, 24, slat=True), 0.3)
    layered = ssr_dda(g, DDASSRParams(max_ray_distance=30.0, use_back_face_depth=True, z_thickness=0.0, **kw))
    constant = ssr_dda(g, DDASSRParams(max_ray_distance=30.0, z_thickness=0.3, **kw))
    assert torch.equal(layered.termination, constant.termination) and torch.equal(layered.hit_pixel, constant.hit_pixel)
    thin = ssr_dda(_slabs(g, 0.01), DDASSRParams(max_ray_distance=30.0, use_back_face_depth=True, z_thickness=0.0,
                                                 **kw))
    assert int((constant.hit & ~thin.hit).sum()) > 0
    twin = ssr_dda_basic(g, DDASSRParams(max_ray_distance=30.0, use_back_face_depth=True, z_thickness=0.0, **kw))
    assert torch.equal(twin.termination, layered.termination)
    with pytest.raises(ValueError, match="back_z"):
        ssr_dda(room(8, 6), DDASSRParams(use_back_face_depth=True))


def test_second_layer_sees_behind_the_bar():
    """G3D's two-layer trace: with ``second_z`` a ray passing behind the thin bar hits the wall the bar hides;
    with one layer it cannot (that wall is not in the depth buffer). The twin agrees."""
    from tests.passes.ssr_scenes import with_second_layer
    W, H = 96, 72                                           # the bar is two pixels tall
    g = with_second_layer(room(W, H, slat=True))
    bar = (g.shape_id == 2)[0, 0]
    one = ssr_dda(g, DDASSRParams(max_ray_distance=30.0, z_thickness=0.05))
    two = ssr_dda(g, DDASSRParams(max_ray_distance=30.0, z_thickness=0.05, use_second_layer=True))

    def hidden_hits(r):                                     # hits on a bar texel, at the wall's depth
        px = r.hit_pixel[0].floor().long().clamp_min(0)
        on_bar = r.hit[0, 0] & bar[px[1].clamp(max=H - 1), px[0].clamp(max=W - 1)]
        behind = r.hit_view[0, 2] < g.view_z[0, 0][px[1].clamp(max=H - 1), px[0].clamp(max=W - 1)] - 1.0
        return int((on_bar & behind).sum())                 # a unit farther than the bar: the wall it hides
    assert hidden_hits(one) == 0 and hidden_hits(two) > 5
    twin = ssr_dda_basic(g, DDASSRParams(max_ray_distance=30.0, z_thickness=0.05, use_second_layer=True))
    assert torch.equal(twin.termination, two.termination)
    with pytest.raises(ValueError, match="second_z"):
        ssr_dda(room(8, 6), DDASSRParams(use_second_layer=True))


@pytest.mark.slow
def test_the_compiled_dda_steps_give_the_eager_bits_at_two_sizes_without_recompiling():
    """The DDA steps through ``torch.compile`` (size-dynamic; eight steps per call, one with ``debug``): every output
    and the visit map equal eager, with strides and the binary search, the 1-pixel re-march, the second depth
    layer, jitter and a step budget that is not a multiple of eight; a second size compiles nothing."""
    from ssbench.passes.compiled import STEPS_PER_CALL
    from ssbench.passes.ssr.dda_march import dda_steps
    from tests.passes.compiled_check import check_compiled_at_two_sizes
    from tests.passes.ssr_scenes import room, with_second_layer
    settings = [DDASSRParams(pixel_stride=3.0), DDASSRParams(pixel_stride=2.0, refinement="remarch", jitter=1.0),
                DDASSRParams(use_second_layer=True, z_thickness=0.05, max_steps=21)]
    assert settings[-1].max_steps % STEPS_PER_CALL and dda_steps.eager is not dda_steps
    for debug, which in ((True, settings), (False, settings[1:])):        # (each flag set compiles its own kernel)
        check_compiled_at_two_sizes(lambda w, h: with_second_layer(room(w, h, torch.float32, slat=True)),
                                    lambda g, p: ssr_dda(g, p, debug=debug), which, ((40, 30), (48, 36)))
