"""Linear SSR (SSR article §1) on analytic G-buffers: a mirror floor ``y = 0`` and walls ``z = zw`` facing the
camera, intersected with the pixel-centre rays in closed form (no Mitsuba)."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench import checks
from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes.ssr.common import (BEHIND_CAMERA, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS)
from ssbench.passes.ssr.linear import (REQUIRES, REQUIRES_BACKFACE, LinearSSR, LinearSSRParams, ssr_linear)
from ssbench.passes.teaching.ssr_linear_basic import ssr_linear_basic

SKY = (0.2, 0.4, 0.8)


def scene(w=32, h=24, eye=(0.0, 1.0, 0.0), target=(0.0, 0.7, -4.0), walls=((-5.0, 1.0, None),), floor=True,
          near=0.1, far=50.0, fovy=60.0, dtype=torch.float64):
    """G-buffer of a floor ``y = 0`` (open: ``back_z = −inf``) and walls ``(zw, thickness, ymax)``: slabs
    ``zw − thickness ≤ z ≤ zw``, ``0 ≤ y ≤ ymax`` (``None``: unbounded; no lower bound without a floor),
    front face normal +z, checker colour."""
    cam = Camera.from_look_at(eye, target, (0, 1, 0), fovy, w, h, near, far)
    d = cam.view_to_world_dir(cam.pixel_rays(torch.float64), dim=0)             # (3, H, W) world directions
    e = torch.tensor(eye, dtype=torch.float64).view(3, 1, 1)
    inf = torch.full(d.shape[1:], math.inf, dtype=torch.float64)
    best, nrm, back_t = inf.clone(), torch.zeros_like(d), inf.clone()
    col = torch.tensor(SKY, dtype=torch.float64).view(3, 1, 1).expand_as(d).clone()
    surfaces = [("floor", None, None, None)] if floor else []
    surfaces += [("wall", zw, th, ym) for zw, th, ym in walls]
    for kind, zw, th, ym in surfaces:
        if kind == "floor":
            t, n = -e[1] / d[1], (0.0, 1.0, 0.0)
        else:
            t, n = (zw - e[2]) / d[2], (0.0, 0.0, 1.0)
        p = e + t * d
        ok = (t > 0) & torch.isfinite(t) & (t < best) & ((p[1] >= -1e-9) | (not floor))
        if kind == "wall" and ym is not None:
            ok &= p[1] <= ym
        best = torch.where(ok, t, best)
        nrm = torch.where(ok, torch.tensor(n, dtype=torch.float64).view(3, 1, 1), nrm)
        if kind == "floor":
            back_t = torch.where(ok, inf, back_t)
            c = torch.tensor((0.5, 0.5, 0.5), dtype=torch.float64).view(3, 1, 1).expand_as(d)
        else:
            back_t = torch.where(ok, (zw - th - e[2]) / d[2], back_t)
            chk = ((torch.floor(p[0] * 2) + torch.floor(p[1] * 2)) % 2 == 0).to(torch.float64)
            c = torch.stack([0.9 * chk + 0.1, 0.2 * torch.ones_like(chk), 0.9 - 0.8 * chk])
        col = torch.where(ok, c, col)
    mask = torch.isfinite(best)
    world = e + torch.where(mask, best, 0.0) * d
    pos = cam.world_to_view(world, dim=0)
    far_pos = cam.uv_to_view(cam.uv_grid(torch.float64), torch.full((1, h, w), -far, dtype=torch.float64), dim=0)
    pos = torch.where(mask, pos, far_pos)
    back_world = e + torch.where(torch.isfinite(back_t), back_t, 0.0) * d
    back_z = torch.where(torch.isfinite(back_t), cam.world_to_view(back_world, dim=0)[2], -math.inf)
    g = GBuffer(cam, view_z=pos[2:3][None].to(dtype), position=pos[None].to(dtype),
                normal=cam.world_to_view_dir(nrm, dim=0)[None].to(dtype), mask=mask[None, None],
                back_z=back_z[None, None].to(dtype), color=col[None].to(dtype))
    return g


def wall_hit_pixel(g: GBuffer, zw: float):
    """Closed form: the mirror-floor reflection of each floor pixel's ray meets the wall plane ``z = zw`` at
    pixel ``(px, py)``; returns (floor mask, (2, H, W) pixels, (H, W) reflected-ray length to the wall)."""
    cam = g.camera
    P = cam.view_to_world(g.position[0].double(), dim=0)                        # (3, H, W) world hit points
    eye = torch.tensor(cam.eye, dtype=torch.float64).view(3, 1, 1)
    d = (P - eye) / (P - eye).norm(dim=0, keepdim=True)
    r = d * torch.tensor([1.0, -1.0, 1.0], dtype=torch.float64).view(3, 1, 1)  # reflect about y = 0
    s = (zw - P[2]) / r[2]
    q = P + s * r
    floor = g.mask[0, 0] & (g.normal[0, 1] > 0.5)
    return floor, cam.view_to_pixel(cam.world_to_view(q, dim=0), dim=0), s


def reachable(g: GBuffer, zw: float, s_max: float):
    """Floor pixels whose closed-form wall hit is on screen (1 px margin) within ``s_max`` along the ray."""
    floor, px, s = wall_hit_pixel(g, zw)
    return floor & (px[0] > 1) & (px[0] < g.width - 1) & (px[1] > 1) & (px[1] < g.height - 1) & (s < s_max)


# ----------------------------------------------------------------------------- closed form
def test_floor_reflection_hits_wall_at_closed_form_pixel():
    g = scene()
    p = LinearSSRParams(max_ray_distance=10.0, iterations=25, thickness=1.0, binary_search_iterations=8)
    r = ssr_linear(g, p)                                                  # steps of 0.4 units
    _, px, _ = wall_hit_pixel(g, -5.0)
    inside = reachable(g, -5.0, 9.0)
    assert int(inside.sum()) > 50
    assert bool(r.hit[0, 0][inside].all())
    err = (r.hit_pixel[0] - px).norm(dim=0)[inside]
    assert float(err.max()) < 1.0
    hv = g.camera.view_to_world(r.hit_view[0], dim=0)
    assert float((hv[2][inside] + 5.0).abs().max()) < 0.01                        # on (just behind) the wall
    # colour is the wall's checker at the hit texel, times the fades
    assert torch.allclose(r.color, r.raw_color * r.fade)
    assert bool((r.raw_color[0, :, inside] != torch.tensor(SKY, dtype=torch.float64).view(3, 1)).any(0).all())
    assert bool((r.termination[~g.mask] == NO_RAY).all()) and bool((r.steps[~g.mask] == 0).all())


def test_fine_steps_self_hit_the_floor():
    """Steps shorter than a floor texel's footprint: the first sample is behind its own (or the next) texel's
    depth and hits the floor it starts on. The article has no self-hit guard; pinned."""
    g = scene()
    r = ssr_linear(g, LinearSSRParams(max_ray_distance=10.0, iterations=200, thickness=0.2))
    inner = reachable(g, -5.0, 9.0)
    assert bool(r.hit[0, 0][inner].all())
    self_hit = inner & (r.steps[0, 0] == 1 + 4)                           # first sample + 4 bisection probes
    assert int(self_hit.sum()) >= int(inner.sum()) // 2
    own = g.camera.pixel_centers(torch.float64)
    assert float((r.hit_pixel[0] - own).norm(dim=0)[self_hit].max()) < 1.5


def test_defaults_and_backface_twin_agree():
    g = scene(16, 12)
    for p in (LinearSSRParams(), LinearSSRParams(jitter=1.0, seed=5, use_back_face_depth=True, iterations=20,
                                                 thickness=0.1, edge_fade_mode="circular"),
              LinearSSRParams(position_from="view_z", binary_search_iterations=0, iterations=7),
              LinearSSRParams(position_from="position", iterations=40, max_iterations=12)):
        a, b = ssr_linear(g, p), ssr_linear_basic(g, p)
        assert torch.equal(a.termination, b.termination) and torch.equal(a.hit, b.hit)
        assert torch.equal(a.steps, b.steps)
        for f in ("hit_pixel", "hit_view", "color", "raw_color", "fade"):
            assert torch.allclose(getattr(a, f), getattr(b, f), atol=1e-5, rtol=0), f
        assert bool(a.hit.any()) or p.max_iterations < p.iterations


# ----------------------------------------------------------------------------- hard cases
def facing_wall(zw, w=15, h=11, near=0.1, far=50.0):
    """Camera at the origin looking down −z at a wall ``z = zw``; odd size so the centre pixel's ray is −z."""
    return scene(w, h, eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), walls=((zw, 1.0, None),), floor=False,
                 near=near, far=far)


def finite(r):
    return all(bool(torch.isfinite(getattr(r, f)).all()) for f in ("color", "hit_pixel", "hit_view", "fade"))


def test_ray_toward_camera_is_clipped_at_near_plane():
    g = facing_wall(-3.0)
    r = ssr_linear(g, LinearSSRParams(max_ray_distance=20.0))           # would cross the near plane
    assert finite(r) and not bool(r.hit.any())
    assert int(r.termination[0, 0, 5, 7]) == BEHIND_CAMERA
    assert set(r.termination.unique().tolist()) <= {BEHIND_CAMERA, OFF_SCREEN}
    r = ssr_linear(g, LinearSSRParams(max_ray_distance=1.0))            # ends before the near plane
    assert int(r.termination[0, 0, 5, 7]) == MAX_DISTANCE


def test_origin_at_near_plane():
    for zw in (-0.1, -0.105, -0.109):                                   # within 0.01 of near = 0.1
        r = ssr_linear(facing_wall(zw), LinearSSRParams())
        assert finite(r) and not bool(r.hit.any())
        assert int(r.termination[0, 0, 5, 7]) == BEHIND_CAMERA
        assert set(r.termination.unique().tolist()) <= {BEHIND_CAMERA, OFF_SCREEN}


def test_very_short_ray_pins_self_hit():
    """|ΔP| < 0.01 px: toward the camera no hit; away from it the sample is behind its own texel's depth and
    hits its own surface (the article has no self-hit guard)."""
    p = LinearSSRParams(max_ray_distance=1e-3, iterations=4)
    r = ssr_linear(facing_wall(-3.0), p)
    assert finite(r) and bool((r.termination == MAX_DISTANCE).all())
    g = scene(16, 12)
    r = ssr_linear(g, p)
    floor = g.mask & (g.normal[:, 1:2] > 0.5)
    assert finite(r) and bool(r.hit[floor].all())
    own = g.camera.pixel_centers(torch.float64)[None]
    assert float((r.hit_pixel - own).abs().amax(1, keepdim=True)[floor].max()) < 0.5   # its own texel


def test_grazing_floor():
    g = scene(32, 24, eye=(0.0, 0.05, 0.0), target=(0.0, 0.05, -1.0), walls=((-30.0, 1.0, None),), far=100.0)
    r = ssr_linear(g, LinearSSRParams(max_ray_distance=40.0, iterations=100, thickness=0.5))
    floor = g.mask & (g.normal[:, 1:2] > 0.5)
    near = g.view_z > -g.camera.near                       # nearer than the near plane: clipped on a GPU, no ray
    assert finite(r) and bool((floor & ~near).any())
    assert set(r.termination[floor & ~near].unique().tolist()) <= {HIT, MAX_DISTANCE, OFF_SCREEN}
    assert bool((r.termination[floor & near] == NO_RAY).all())
    assert bool(r.hit[floor].any())


def test_target_off_screen():
    g = scene(16, 12, eye=(0.0, 1.0, 0.0), target=(0.0, 0.0, -1.0), walls=())  # frustum top 15° below horizon
    r = ssr_linear(g, LinearSSRParams(max_ray_distance=40.0, iterations=40))    # reflections rise ≥ 15°
    assert finite(r) and bool(g.mask.any()) and bool((r.termination[g.mask] == OFF_SCREEN).all())
    assert bool((r.termination[~g.mask] == NO_RAY).all()) and not bool(r.hit.any())


def test_thin_slat_punch_through_and_back_face_depth():
    slat, thick = scene(walls=((-5.0, 0.02, None),)), scene(walls=((-5.0, 2.0, None),))
    sel = reachable(slat, -5.0, 5.5)

    def hits(g, **kw):                   # hit fraction over sel; hits must lie inside [back − T, front]
        p = LinearSSRParams(**{"max_ray_distance": 6.0, "iterations": 6, "thickness": 0.05,
                               "binary_search_iterations": 0, **kw})
        r = ssr_linear(g, p)                                          # steps of 1 unit
        z = g.camera.view_to_world(r.hit_view[0], dim=0)[2][sel & r.hit[0, 0]]
        assert bool((z <= -5.0 + 1e-9).all())
        return float(r.hit[0, 0][sel].double().mean())

    assert hits(slat) < 0.2                                           # punch-through: the slat is thinner than a step
    assert hits(slat, thickness=1.5) == 1.0                           # a fixed thickness ≥ the depth step catches it
    assert hits(thick) < 0.2                                          # a thick slab is missed with T = 0.05 ...
    assert hits(thick, use_back_face_depth=True) == 1.0               # ... and hit with its back-face depth
    assert hits(slat, use_back_face_depth=True) < 0.2                 # the gap behind the thin slat is not a hit
    inf_back = GBuffer(slat.camera, **{**slat.as_dict(), "back_z": torch.full_like(slat.back_z, -math.inf)})
    assert hits(inf_back, use_back_face_depth=True) == 1.0            # back_z = −inf: infinitely thick


def test_out_of_steps_is_never_a_hit():
    g = scene()
    p = LinearSSRParams(max_ray_distance=10.0, iterations=25, max_iterations=5)   # marches 2 of 10 units
    r = ssr_linear(g, p)
    floor, _, s = wall_hit_pixel(g, -5.0)
    far_ = floor & (s > 2.0)
    t = r.termination[0, 0][far_]
    assert set(t.unique().tolist()) <= {OUT_OF_STEPS, OFF_SCREEN} and not bool(r.hit[0, 0][far_].any())
    assert float((t == OUT_OF_STEPS).double().mean()) > 0.9
    assert bool((r.steps[r.termination == OUT_OF_STEPS] == 5).all())
    full = ssr_linear(g, LinearSSRParams(**{**p.__dict__, "max_iterations": 300}))
    assert bool(full.hit[0, 0][reachable(g, -5.0, 9.0) & far_].all())


def test_visits_and_trace():
    g = scene(16, 12)
    r = ssr_linear(g, LinearSSRParams(), debug=True, trace_pixel=(8, 10))
    v = r.debug["visits"]
    assert v.shape == (1, 1, 12, 16) and v.dtype == torch.int32
    assert int(v.sum()) == int(r.steps.sum()) - int((r.termination == OFF_SCREEN).sum())
    tr = r.debug["trace"][0]
    assert tr["view"].shape[0] == int(r.steps[0, 0, 10, 8]) == tr["pixel"].shape[0]
    if bool(r.hit[0, 0, 10, 8]):
        last = tr["view"][tr["hit"]][-1]
        assert torch.allclose(last, r.hit_view[0, :, 10, 8])


# ----------------------------------------------------------------------------- numerics, API, errors
def test_fp32_matches_fp64_termination():
    p = LinearSSRParams(max_ray_distance=10.0, iterations=60, thickness=0.3)
    g64 = scene(64, 48, walls=((-5.0, 1.0, None), (-3.0, 0.3, 0.4)))
    a, b = ssr_linear(g64, p), ssr_linear(g64.to(dtype=torch.float32), p)
    assert float((a.termination == b.termination).double().mean()) >= 0.999
    assert bool(a.hit.any()) and b.color.dtype == torch.float32


def test_seeded_jitter_is_reproducible_and_module_matches():
    g, p = scene(16, 12), LinearSSRParams(jitter=1.0, seed=3, iterations=10)
    a, b = ssr_linear(g, p), LinearSSR(p)(g)
    for f in ("color", "hit_pixel", "hit_view", "steps", "termination", "fade"):
        assert torch.equal(getattr(a, f), getattr(b, f)), f
    c = ssr_linear(g, LinearSSRParams(jitter=1.0, seed=4, iterations=10))
    assert not torch.equal(a.hit_view, c.hit_view)
    gen = torch.Generator().manual_seed(3)
    assert torch.equal(ssr_linear(g, p, generator=gen).hit_view, a.hit_view)


def test_requires():
    assert REQUIRES == ("view_z", "normal", "mask", "color") and REQUIRES_BACKFACE[-1] == "back_z"


@pytest.mark.parametrize("kw,name", [({"iterations": 0}, "iterations"), ({"thickness": 0.0}, "thickness"),
                                     ({"thickness": -1.0}, "thickness"),
                                     ({"max_ray_distance": 0.0}, "max_ray_distance"),
                                     ({"max_ray_distance": math.inf}, "max_ray_distance"), ({"jitter": 2.0}, "jitter"),
                                     ({"edge_fade_mode": "box"}, "edge_fade_mode"), ({"seed": -1}, "seed"),
                                     ({"binary_search_iterations": -1}, "binary_search_iterations"),
                                     ({"position_from": "x"}, "position_from")])
def test_bad_params(kw, name):
    with pytest.raises(ValueError, match=name):
        LinearSSRParams(**kw)


def test_bad_gbuffer():
    g = scene(8, 6)
    with pytest.raises(ValueError, match="color"):
        ssr_linear(g.select(["view_z", "normal", "mask"]))
    with pytest.raises(ValueError, match="back_z"):
        ssr_linear(g.select(list(REQUIRES)), LinearSSRParams(use_back_face_depth=True))
    with checks.checks_disabled():
        bad = GBuffer(g.camera, **{**g.as_dict(), "normal": g.normal[:, :2]})
    with pytest.raises(ValueError, match="normal"):
        ssr_linear(bad)
    with checks.checks_disabled():
        bad = GBuffer(g.camera, **{**g.as_dict(), "view_z": -g.view_z})
    with pytest.raises(ValueError, match="view_z"):
        ssr_linear(bad)
    with pytest.raises(TypeError, match="params"):
        ssr_linear(g, {"iterations": 3})


@pytest.mark.slow
def test_the_compiled_march_gives_the_eager_bits_at_two_sizes_without_recompiling():
    """The march steps through ``torch.compile`` (size-dynamic; eight per call, one with debug buffers): every
    output, the visit map and a traced pixel's samples equal eager, with back faces and jitter too, and a step
    budget that is not a multiple of eight; a second image size reuses the compiled steps."""
    import dataclasses

    from torch._dynamo.utils import counters

    from ssbench.passes import compiled as C
    from ssbench.passes.compiled import STEPS_PER_CALL
    from ssbench.passes.ssr.linear_march import march_steps
    settings = [LinearSSRParams(thickness=0.3), LinearSSRParams(use_back_face_depth=True, thickness=0.3),
                LinearSSRParams(jitter=1.0, iterations=21)]
    assert settings[-1].iterations % STEPS_PER_CALL
    for w, h in ((32, 24), (40, 30)):
        g = scene(w, h, walls=((-5.0, 0.4, 1.2), (-7.0, 1.0, None)), dtype=torch.float32)
        for p in settings:
            with C.compiling(False):
                eager = ssr_linear(g, p, debug=True, trace_pixel=(w // 2, h - 2))
            with C.compiling(True):
                comp = ssr_linear(g, p, debug=True, trace_pixel=(w // 2, h - 2))
            assert bool(eager.hit.any()) and bool((eager.termination == OFF_SCREEN).any())
            for f in dataclasses.fields(eager):
                if f.name != "debug":
                    assert torch.equal(getattr(eager, f.name), getattr(comp, f.name)), f.name
            assert torch.equal(eager.debug["visits"], comp.debug["visits"])
            for k, v in eager.debug["trace"][0].items():
                assert torch.equal(v, comp.debug["trace"][0][k]), k
        for p in settings[1:]:                        # no debug buffers: eight steps per compiled call
            with C.compiling(False):
                eager = ssr_linear(g, p)
            with C.compiling(True):
                comp = ssr_linear(g, p)
            for f in dataclasses.fields(eager):
                if f.name != "debug":
                    assert torch.equal(getattr(eager, f.name), getattr(comp, f.name)), f.name
        if w == 32:
            seconds, graphs = C.compile_seconds(), counters["stats"]["unique_graphs"]
    assert graphs >= 1 and counters["stats"]["unique_graphs"] == graphs          # the second size: nothing new
    assert C.compile_seconds() == seconds
    assert march_steps.eager is not march_steps



@pytest.mark.slow
def test_the_compiled_ray_set_up_gives_the_eager_bits_for_every_position_source_and_a_batch():
    """The set-up's kernels (``ray_origin`` before the reflection, ``ray_steps`` after it) compiled: the same rays,
    bit for bit, for each ``position_from``, with jitter, on a batch of two images; a second image size and other
    settings (numbers) compile nothing new, a new field of view does."""
    from torch._dynamo.utils import counters

    from ssbench.passes import compiled as C
    from ssbench.passes.ssr.linear_rays import linear_rays, ray_origin, ray_steps
    assert ray_origin.eager is not ray_origin and ray_steps.eager is not ray_steps
    fields = ("ray", "base", "origin", "delta", "start", "clipped", "ray_length", "jitter")

    def batch(w, h, fovy=60.0):
        g = scene(w, h, walls=((-5.0, 0.4, 1.2),), fovy=fovy, dtype=torch.float32)
        two = {n: torch.cat([getattr(g, n), getattr(g, n).flip(-1)]) for n in g.channels}   # a mirrored second image
        return GBuffer(g.camera, **two)

    def compare(g, p):
        with C.compiling(False):
            eager = linear_rays(g, p, torch.Generator().manual_seed(3))
        with C.compiling(True):
            comp = linear_rays(g, p, torch.Generator().manual_seed(3))
        assert eager.ray.numel() > 0
        for f in fields:
            a, b = getattr(eager, f), getattr(comp, f)
            assert (a is None and b is None) or torch.equal(a, b), f
        assert torch.equal(eager.test.scene_z, comp.test.scene_z)

    settings = [LinearSSRParams(position_from=s, jitter=j) for s in ("depth", "view_z", "position") for j in (0.0, 0.5)]
    for p in settings:
        compare(batch(24, 18), p)
    seconds, graphs = C.compile_seconds(), counters["stats"]["unique_graphs"]
    for p in (LinearSSRParams(iterations=9, max_ray_distance=7.0, jitter=0.25), LinearSSRParams(position_from="view_z")):
        compare(batch(28, 16), p)
    assert counters["stats"]["unique_graphs"] == graphs and C.compile_seconds() == seconds   # nothing new
    compare(batch(28, 16, fovy=45.0), settings[0])
    assert counters["stats"]["unique_graphs"] > graphs and C.compile_seconds() > seconds     # a new camera compiles
