"""Hi-Z SSR (FidelityFX SSSR / HDRP traversal): pyramid, closed form, teaching twin, the anchors' pinned bugs."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.gbuffer import GBuffer
from ssbench.passes.ssr.common import BEHIND_SURFACE, HIT, OFF_SCREEN, OUT_OF_STEPS, reflection_rays
from ssbench.passes.ssr.dda import DDASSRParams, ssr_dda
from ssbench.passes.ssr.hiz import HiZSSR, HiZSSRParams, ssr_hiz
from ssbench.passes.ssr.hiz_pyramid import depth_pyramid, reversed_depth
from ssbench.passes.teaching.ssr_hiz_basic import build_pyramid, ssr_hiz_basic, trace_pixel, validate_hit
from tests.passes.ssr_scenes import FLOOR, WALL, analytic, one_ray, room

F64 = torch.float64


# ----------------------------------------------------------------------------- the pyramid
@pytest.mark.parametrize("h,w", [(7, 13), (8, 8), (1, 5), (11, 17)])
def test_pyramid_cells_are_the_max_of_their_texels(h, w):
    rz = torch.rand(2, 1, h, w, generator=torch.Generator().manual_seed(h * w), dtype=F64)
    p = depth_pyramid(rz)
    assert tuple(p.levels[-1].shape[-2:]) == (1, 1)
    for m, level in enumerate(p.levels):
        s = 2 ** m
        assert level.shape[-2:] == (math.ceil(h / s), math.ceil(w / s))
        for cy in range(level.shape[-2]):
            for cx in range(level.shape[-1]):                 # a cell covers texels [c·2^m, (c+1)·2^m), clipped
                block = rz[:, 0, cy * s:(cy + 1) * s, cx * s:(cx + 1) * s]
                assert torch.equal(level[:, 0, cy, cx], block.amax((1, 2)))
                b, mm = torch.tensor([1]), torch.tensor([m])
                assert float(p.cell(b, mm, torch.tensor([cx]), torch.tensor([cy]))) == float(level[1, 0, cy, cx])
    twin = build_pyramid(rz[0, 0].tolist())
    assert all(torch.equal(torch.tensor(t, dtype=F64), lv[0, 0]) for t, lv in zip(twin, p.levels))


def test_reversed_depth():
    z = torch.tensor([[[[-0.1, -1.0, -1e6, -50.0]]]], dtype=F64)
    rz = reversed_depth(z, z != -50.0, 0.1)
    assert rz.flatten().tolist() == [1.0, 0.1, 1e-7, 0.0]     # near plane 1, background 0
    with pytest.raises(ValueError, match="view_z"):
        reversed_depth(z[0], z[0] < 0, 0.1)


# ----------------------------------------------------------------------------- closed form
def test_mirror_floor_hits_wall_closed_form():
    g = room()
    cam, W, H = g.camera, g.width, g.height
    r = ssr_hiz(g, HiZSSRParams(max_ray_distance=50.0, depth_buffer_thickness=0.5))
    target, ok = analytic(g, [FLOOR, WALL])
    pix = cam.view_to_pixel(target)
    floor = ok & (g.shape_id == 0)
    inside = floor & (pix[:, :1] > 1) & (pix[:, :1] < W - 1) & (pix[:, 1:] > 1) & (pix[:, 1:] < H - 1)
    outside = floor & ((pix[:, :1] < -1) | (pix[:, :1] > W + 1) | (pix[:, 1:] < -1) | (pix[:, 1:] > H + 1))
    assert int(inside.sum()) > 600 and int(outside.sum()) > 10
    assert bool(r.hit[inside].all())
    err = (r.hit_pixel - pix).norm(dim=1, keepdim=True)[inside]
    assert float(err.max()) < 1.0, float(err.max())
    assert bool((r.termination[outside] == OFF_SCREEN).all())
    off_line = torch.cross(r.hit_view - g.position, reflection_rays(g.position, g.normal), dim=1).norm(dim=1, keepdim=True)
    assert float(off_line[r.hit].max()) < 1e-9                 # the hit point lies on the mirror ray
    assert torch.allclose(cam.view_to_pixel(r.hit_view)[r.hit.expand(-1, 2, -1, -1)],
                          r.hit_pixel[r.hit.expand(-1, 2, -1, -1)], atol=1e-6)
    assert torch.allclose(r.color, r.raw_color * r.fade)


def test_fewer_reads_than_the_dda_for_the_same_hits():
    """Reads grow like the log of the ray's length in pixels, the DDA's linearly."""
    g = room(96, 72)
    h = ssr_hiz(g, HiZSSRParams(max_ray_distance=50.0, depth_buffer_thickness=0.5), debug=True)
    d = ssr_dda(g, DDASSRParams(max_ray_distance=50.0, refinement="none"))
    both = h.hit & d.hit
    assert int(both.sum()) > 2500
    assert float(h.steps[both].double().mean()) < 0.5 * float(d.steps[both].double().mean())
    long = both & (d.steps >= 48)
    assert int(long.sum()) > 500 and float(h.steps[long].double().mean()) < 0.3 * float(d.steps[long].double().mean())
    levels = h.debug["reads_per_level"]
    assert int(levels.sum()) == int(h.steps.sum()) and int(levels[1:].sum()) > 0   # it climbs
    assert int(h.debug["visits"].sum()) == int(levels[0])


# ----------------------------------------------------------------------------- teaching twin
@pytest.mark.parametrize("size,kw", [
    ((16, 12), dict()), ((16, 12), dict(depth_buffer_thickness=0.5)), ((17, 11), dict(trace_behind=True)),
    ((16, 12), dict(thickness_mode="relative", depth_buffer_thickness=0.05, reject_backfaces=False)),
    ((16, 12), dict(max_traversal_intersections=5, max_mip=1)), ((13, 9), dict(max_ray_distance=3.0))])
def test_teaching_twin_equals_vectorised(size, kw):
    for g in (room(*size), room(*size, slat=True)):
        p = HiZSSRParams(**{"max_ray_distance": 30.0, **kw})
        a, b = ssr_hiz(g, p), ssr_hiz_basic(g, p)
        assert torch.equal(a.termination, b.termination) and torch.equal(a.steps, b.steps)
        assert float((a.hit_pixel - b.hit_pixel).abs().max()) <= 1e-9
        assert torch.allclose(a.hit_view, b.hit_view, atol=1e-9) and torch.allclose(a.color, b.color, atol=1e-9)


def test_trace_pixel_climbs_and_descends():
    g = room(32, 24)
    p = HiZSSRParams(max_ray_distance=50.0, depth_buffer_thickness=0.5)
    r = ssr_hiz(g, p, debug=True)
    steps = torch.where(r.hit, r.steps, 0)[0, 0]
    j, i = divmod(int(steps.argmax()), g.width)                # the hit that took the most reads
    assert bool(r.hit[0, 0, j, i]) and int(g.shape_id[0, 0, j, i]) == 0   # a floor pixel
    t = trace_pixel(g, p, (i, j))
    assert t["termination"] == HIT and t["steps"] == int(r.steps[0, 0, j, i]) == len(t["path"])
    assert t["position"][:2] == pytest.approx(r.hit_pixel[0, :, j, i].tolist(), abs=1e-9)
    assert list(t["p1"]) == pytest.approx(r.debug["ray_end"][0, :, j, i].tolist(), abs=1e-9)
    mips = [step[0] for step in t["path"]]
    assert max(mips) >= 2 and mips[-1] == 0 and any(step[4] for step in t["path"])   # skipped tiles, then level 0
    with pytest.raises(ValueError, match="pixel"):
        trace_pixel(g, p, (32, 0))                             # outside the image


# ----------------------------------------------------------------------------- the anchors' bugs, pinned
def test_running_out_of_iterations_is_never_a_hit():
    """FidelityFX's ``valid_hit = i <= max_traversal_intersections`` is true on every exit of its loop."""
    g = room()
    r = ssr_hiz(g, HiZSSRParams(max_ray_distance=50.0, depth_buffer_thickness=0.5, max_traversal_intersections=4))
    spent = r.termination == OUT_OF_STEPS
    assert int(spent.sum()) > 100
    assert not bool(r.hit[spent].any()) and bool((r.color.abs().sum(1, keepdim=True)[spent] == 0).all())
    assert bool((r.steps[spent] == 4).all())


def test_rays_toward_the_camera_keep_their_screen_direction():
    """FidelityFX projects ``o + d`` unclipped: from a surface 0.5 in front of the eye, toward the camera, that
    point is behind the eye (``w ≤ 0``) and its projection flips the ray's screen direction."""
    R = (0.3, 0.2, 0.93)
    g = one_ray(R, z=-0.5)
    cam = g.camera
    r = ssr_hiz(g, HiZSSRParams(), debug=True)
    y, x = (g.mask[0, 0]).nonzero()[0].tolist()
    o = g.view_z.new_tensor(cam.uv_to_view(cam.uv_grid(F64)[None], g.view_z)[0, :, y, x].tolist())
    d = reflection_rays(cam.uv_to_view(cam.uv_grid(F64)[None], g.view_z), g.normal)[0, :, y, x]
    P0 = torch.tensor([x + 0.5, y + 0.5], dtype=F64)
    true_dir = cam.view_to_pixel(o + 1e-3 * d, dim=-1) - P0   # the ray's first millimetre on screen
    naive = cam.view_to_pixel(o + d, dim=-1) - P0             # FidelityFX's ProjectDirection(o + d)
    assert float(o[2] + d[2]) > 0 and float(naive @ true_dir) < 0   # behind the eye, flipped
    ours = r.debug["ray_end"][0, :, y, x] - P0
    assert float(ours @ true_dir) > 0.99 * float(ours.norm() * true_dir.norm())
    assert int(r.termination[0, 0, y, x]) in (OFF_SCREEN, 5)   # leaves the screen or reaches the near plane


def test_relative_thickness_grows_with_depth():
    """HDRP's thickness is relative, ``(1 + t)·linZ``: 0.01 is a centimetre at z = −1 and a metre at z = −100."""
    p_rel = HiZSSRParams(thickness_mode="relative", depth_buffer_thickness=0.01, reject_backfaces=False)
    p_abs = HiZSSRParams(depth_buffer_thickness=0.01, reject_backfaces=False)
    for surface, ok_rel in ((-1.0, False), (-100.0, True)):
        ray = surface - 0.5                                    # half a unit behind the surface
        assert validate_hit(surface, None, (0, 0, 1), ray, (0, 0, -1), p_rel) is ok_rel
        assert validate_hit(surface, None, (0, 0, 1), ray, (0, 0, -1), p_abs) is False


def test_thin_bar_stops_the_ray_unless_it_traces_behind():
    """FidelityFX ends a ray at the first texel it passes behind; HDRP-style ``trace_behind`` crosses it."""
    g = room(slat=True)
    stop = ssr_hiz(g, HiZSSRParams(max_ray_distance=50.0, depth_buffer_thickness=0.05))
    go = ssr_hiz(g, HiZSSRParams(max_ray_distance=50.0, depth_buffer_thickness=0.05, trace_behind=True))
    stopped = stop.termination == BEHIND_SURFACE
    assert int(stopped.sum()) > 20 and not bool((go.termination == BEHIND_SURFACE).any())
    assert int((stopped & go.hit).sum()) >= 10                 # crossed behind the bar, then hit something
    assert bool(go.hit[stop.hit].all()) and torch.equal(go.hit_pixel[:, :, stop.hit[0, 0]],
                                                        stop.hit_pixel[:, :, stop.hit[0, 0]])   # same walk until then
    assert bool((go.steps >= stop.steps).all())


# ----------------------------------------------------------------------------- contract
def test_batch_dtype_and_module():
    g = room(24, 18)
    p = HiZSSRParams(max_ray_distance=30.0, depth_buffer_thickness=0.3)
    a = ssr_hiz(g, p)
    b = ssr_hiz(GBuffer.cat([g, g]), p)
    assert torch.equal(b.termination[1:], a.termination) and torch.equal(b.hit_pixel[1:], a.hit_pixel)
    f = ssr_hiz(g.to(torch.float32), p)
    assert float((f.hit == a.hit).double().mean()) > 0.98
    assert torch.equal(HiZSSR(p)(g).termination, a.termination)
    assert all(bool(torch.isfinite(t).all()) for t in (a.color, a.hit_view, a.hit_pixel, f.color))


def test_index_arithmetic_in_int32_gives_the_int64_bits(monkeypatch):
    """The march indexes the pyramid in int32 while its cells fit (a meta tensor stands for a pyramid of 2³¹
    cells, which takes int64); int64 indices give every output and debug count of the int32 ones."""
    import ssbench.passes.ssr.hiz as hiz_module
    from ssbench.passes.ssr.hiz_march import index_dtype
    from ssbench.passes.ssr.hiz_step import PyramidLayers
    assert index_dtype(PyramidLayers(torch.empty(2 ** 31 - 1, device="meta"), 7, 0)) == torch.int32
    assert index_dtype(PyramidLayers(torch.empty(2 ** 31, device="meta"), 7, 0)) == torch.int64
    g = GBuffer.cat([room(24, 18), room(24, 18, slat=True)])
    for p in (HiZSSRParams(max_ray_distance=30.0), HiZSSRParams(max_ray_distance=30.0, trace_behind=True, max_mip=2)):
        a = ssr_hiz(g, p, debug=True)
        monkeypatch.setattr(hiz_module, "index_dtype", lambda layers: torch.int64)
        b = ssr_hiz(g, p, debug=True)
        monkeypatch.undo()
        for name in ("termination", "steps", "hit_pixel", "hit_view", "color"):
            assert torch.equal(getattr(a, name), getattr(b, name)), name
        assert all(torch.equal(a.debug[k], b.debug[k]) for k in ("visits", "reads_per_level"))
        assert int(a.debug["reads_per_level"][1:].sum()) > 0                  # it climbs: levels ≥ 1 are read


@pytest.mark.parametrize("kw,name", [
    (dict(max_traversal_intersections=0), "max_traversal_intersections"),
    (dict(depth_buffer_thickness=-1.0), "depth_buffer_thickness"), (dict(max_ray_distance=math.inf), "max_ray_distance"),
    (dict(max_mip=-1), "max_mip"), (dict(thickness_mode="hdrp"), "thickness_mode"),
    (dict(trace_behind=1), "trace_behind"), (dict(fade_distance=0.0), "fade_distance")])
def test_bad_params(kw, name):
    with pytest.raises(ValueError, match=name):
        HiZSSRParams(**kw)


def test_bad_gbuffer():
    g = room(8, 6)
    with pytest.raises(ValueError, match="back_z"):
        ssr_hiz(g, HiZSSRParams(use_back_face_depth=True))
    with pytest.raises(TypeError, match="params"):
        ssr_hiz(g, DDASSRParams())


def test_back_face_depth_is_a_per_texel_thickness():
    """As for the DDA: slabs down to ``back_z`` equal the constant thickness of their depth; the twin agrees."""
    import dataclasses
    g = room(32, 24, slat=True)
    g = dataclasses.replace(g, back_z=torch.where(g.mask, g.view_z - 0.3, -math.inf))
    layered = ssr_hiz(g, HiZSSRParams(max_ray_distance=30.0, use_back_face_depth=True, depth_buffer_thickness=0.0))
    constant = ssr_hiz(g, HiZSSRParams(max_ray_distance=30.0, depth_buffer_thickness=0.3))
    assert torch.equal(layered.termination, constant.termination) and torch.equal(layered.hit_pixel, constant.hit_pixel)
    assert int(layered.hit.sum()) > 100
    twin = ssr_hiz_basic(g, HiZSSRParams(max_ray_distance=30.0, use_back_face_depth=True, depth_buffer_thickness=0.0))
    assert torch.equal(twin.termination, layered.termination)


def test_second_layer_sees_behind_the_bar():
    """As for the DDA: behind the bar, a ray in front of the second layer goes on (even in FidelityFX mode) and hits
    the wall the bar hides; the twin agrees."""
    from tests.passes.ssr_scenes import with_second_layer
    W, H = 96, 72                                           # the bar is two pixels tall
    g = with_second_layer(room(W, H, slat=True))
    bar = (g.shape_id == 2)[0, 0]
    p = dict(max_ray_distance=30.0, depth_buffer_thickness=0.05)
    one, two = ssr_hiz(g, HiZSSRParams(**p)), ssr_hiz(g, HiZSSRParams(use_second_layer=True, **p))

    def hidden_hits(r):
        px = r.hit_pixel[0].floor().long().clamp_min(0)
        on_bar = r.hit[0, 0] & bar[px[1].clamp(max=H - 1), px[0].clamp(max=W - 1)]
        behind = r.hit_view[0, 2] < g.view_z[0, 0][px[1].clamp(max=H - 1), px[0].clamp(max=W - 1)] - 1.0
        return int((on_bar & behind).sum())                 # a unit farther than the bar: the wall it hides
    assert hidden_hits(one) == 0 and hidden_hits(two) > 5
    assert int((two.termination == BEHIND_SURFACE).sum()) < int((one.termination == BEHIND_SURFACE).sum())
    twin = ssr_hiz_basic(g, HiZSSRParams(use_second_layer=True, **p))
    assert torch.equal(twin.termination, two.termination) and torch.equal(twin.steps, two.steps)
    with pytest.raises(ValueError, match="second_z"):
        ssr_hiz(room(8, 6), HiZSSRParams(use_second_layer=True))


def test_the_compiled_hiz_iterations_give_the_eager_bits_at_two_sizes_without_recompiling():
    """The traversal's iterations through ``torch.compile`` (size-dynamic; every ray judged, where eager judges only
    the candidates; eight iterations per call, one with ``debug``): every output, the visit map and the reads per
    level equal eager (FidelityFX mode, tracing behind with a budget that is not a multiple of eight, the second
    layer, relative thickness, layered depth); a second image size reuses the compiled kernel."""
    import dataclasses
    from ssbench.passes.compiled import STEPS_PER_CALL
    from ssbench.passes.ssr.hiz_step import hiz_iterations
    from tests.passes.compiled_check import check_compiled_at_two_sizes
    from tests.passes.ssr_scenes import with_second_layer
    settings = [HiZSSRParams(max_ray_distance=30.0),
                HiZSSRParams(max_ray_distance=30.0, trace_behind=True, max_mip=2, max_traversal_intersections=37),
                HiZSSRParams(max_ray_distance=30.0, use_second_layer=True, thickness_mode="relative",
                             depth_buffer_thickness=0.05),
                HiZSSRParams(max_ray_distance=30.0, use_back_face_depth=True, depth_buffer_thickness=0.0,
                             reject_backfaces=False)]

    def layered(w, h):
        g = with_second_layer(room(w, h, torch.float32, slat=True))
        return dataclasses.replace(g, back_z=torch.where(g.mask, g.view_z - 0.3, -math.inf))
    assert settings[1].max_traversal_intersections % STEPS_PER_CALL and hiz_iterations.eager is not hiz_iterations
    for debug, which in ((True, settings), (False, settings[1:3])):       # (each flag set compiles its own kernel)
        check_compiled_at_two_sizes(layered, lambda g, p: ssr_hiz(g, p, debug=debug), which, ((32, 24), (40, 30)))
