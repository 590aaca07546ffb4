"""ssbench.metrics.ssr: per-pixel SSR classes on hand-built SSRResult / ReflectionReference stubs, metrics, pictures."""
import dataclasses
import math

import numpy as np
import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.metrics import ssr as M
from ssbench.passes.ssr.common import HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS, SSRResult, empty_result

H, W = 2, 14          # row 0: one test pixel per column; row 1: not reflective, its shape ids are lookup targets
ORIGIN = (0.0, 0.0, -1.0)
TRUE_HIT = (0.0, 0.0, -3.0)             # t = 2 along the ray (−z)
TRUE_PX = (5.5, 0.5)
SLAT, WALL = 3, 7                       # truth hits the slat; the wall is behind it


@dataclasses.dataclass(frozen=True)
class Truth:
    """Stub with the fields of ssbench.reference.ReflectionReference."""

    valid: torch.Tensor
    hit: torch.Tensor
    hit_world: torch.Tensor
    hit_view: torch.Tensor
    hit_pixel: torch.Tensor
    on_screen: torch.Tensor
    visible: torch.Tensor
    back_face: torch.Tensor
    hit_shape: torch.Tensor
    ray_length: torch.Tensor
    radiance: torch.Tensor
    seconds: float = 0.0


def _b(row0):
    t = torch.zeros(1, 1, H, W, dtype=torch.bool)
    t[0, 0, 0] = torch.tensor(row0, dtype=torch.bool)
    return t


# column: (valid, t.hit, on_screen, visible, back_face, pass hit, pass hit_pixel, pass hit_view, expected)
CASES = [
    (0, 0, 0, 0, 0, 0, (-1, -1), (0, 0, 0), M.NOT_REFLECTIVE),                  # 0 background
    (1, 1, 1, 1, 0, 1, (6.5, 0.5), (0, 0, -3.1), M.CORRECT),                    # 1 within 1 px
    (1, 1, 1, 1, 0, 0, (-1, -1), (0, 0, 0), M.MISSED),                          # 2 nothing found
    (1, 0, 0, 0, 0, 1, (3.5, 0.5), (0, 0, -4), M.FALSE_HIT),                    # 3 truth misses
    (1, 1, 1, 1, 0, 1, (0.5, 0.5), (0, 0, -2), M.FALSE_HIT),                    # 4 lands elsewhere, in front
    (1, 1, 1, 1, 0, 1, (0.5, 1.5), (0, 0, -5), M.PUNCH_THROUGH),                # 5 behind, on the wall
    (1, 1, 0, 1, 0, 1, (5.5, 0.5), (0, 0, -3), M.UNFIXABLE_HIT),                # 6 off-screen, pass hit anyway
    (1, 1, 1, 0, 0, 0, (-1, -1), (0, 0, 0), M.OCCLUDED_TARGET),                 # 7 hidden from the camera
    (1, 1, 1, 0, 1, 1, (2.5, 0.5), (0, 0, -6), M.UNFIXABLE_HIT),                # 8 back face, pass hit anyway
    (1, 0, 0, 0, 0, 0, (-1, -1), (0, 0, 0), M.TRUE_MISS),                      # 9 sky
    (1, 1, 1, 1, 0, 1, (1.5, 1.5), (0, 0, -5), M.MISPLACED_HIT),                # 10 behind, same shape: overshoot
    (1, 1, 1, 1, 0, 1, (math.nan, 0.5), (0, 0, -2), M.FALSE_HIT),               # 11 NaN hit pixel: far, not close
    (1, 1, 0, 1, 0, 0, (-1, -1), (0, 0, 0), M.OFF_SCREEN_TARGET),               # 12 off-screen, pass: nothing
    (1, 1, 1, 0, 1, 0, (-1, -1), (0, 0, 0), M.BACK_FACE_TARGET),                # 13 back face (and so hidden)
]


def _scene(shape_ids: bool = True, with_position: bool = True):
    col = lambda i: [c[i] for c in CASES]                                   # noqa: E731
    valid, thit, on, vis, back, phit = (_b(col(i)) for i in range(6))
    tpx = torch.full((1, 2, H, W), -1.0)
    tview = torch.zeros(1, 3, H, W)
    for j in range(W):
        if CASES[j][1]:
            tpx[0, :, 0, j] = torch.tensor(TRUE_PX)
            tview[0, :, 0, j] = torch.tensor(TRUE_HIT)
    shape = torch.full((1, 1, H, W), -1, dtype=torch.int32)
    shape[thit] = SLAT
    rad = torch.where(valid, 0.5, 0.0).expand(1, 3, H, W).contiguous()
    truth = Truth(valid=valid, hit=thit, hit_world=tview.clone(), hit_view=tview, hit_pixel=tpx, on_screen=on & thit,
                  visible=vis & thit, back_face=back & thit, hit_shape=shape,
                  ray_length=torch.where(thit, 2.0, math.inf), radiance=rad)
    ppx = torch.full((1, 2, H, W), -1.0)
    pview = torch.zeros(1, 3, H, W)
    for j, c in enumerate(CASES):
        ppx[0, :, 0, j] = torch.tensor(c[6], dtype=torch.float32)
        pview[0, :, 0, j] = torch.tensor(c[7], dtype=torch.float32)
    term = torch.where(phit, HIT, MAX_DISTANCE).to(torch.int8)
    term[~valid] = NO_RAY
    raw = torch.where(phit, 0.5, 0.0).expand(1, 3, H, W).contiguous()
    result = SSRResult(color=raw * 0.5, hit=phit, hit_pixel=ppx, hit_view=pview,
                       steps=torch.where(valid, 4, 0).to(torch.int32), termination=term,
                       fade=torch.full((1, 1, H, W), 0.5), raw_color=raw, debug={})
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, W, H, 0.1, 100.0)
    pos = torch.tensor(ORIGIN).view(1, 3, 1, 1).expand(1, 3, H, W).contiguous()
    sid = torch.full((1, 1, H, W), 1, dtype=torch.int32)
    sid[0, 0, 1, 0], sid[0, 0, 1, 1] = WALL, SLAT
    g = GBuffer(cam, position=pos if with_position else None, view_z=pos[:, 2:3].clone(),
                shape_id=sid if shape_ids else None)
    return result, truth, g


def _expected():
    out = torch.zeros(1, 1, H, W, dtype=torch.int8)
    out[0, 0, 0] = torch.tensor([c[8] for c in CASES], dtype=torch.int8)
    return out


def test_every_class_on_a_hand_built_row():
    result, truth, g = _scene()
    classes, names = M.classify(result, truth, g)
    assert classes.dtype == torch.int8 and classes.shape == (1, 1, H, W)
    assert torch.equal(classes, _expected()), classes[0, 0, 0].tolist()
    assert names == M.CLASS_NAMES and len(set(names.values())) == 11
    assert {int(c) for c in classes.flatten()} == set(M.CLASS_NAMES)        # every class occurs


def test_punch_through_without_shape_ids_is_any_hit_behind():
    result, truth, g = _scene(shape_ids=False)
    classes, _ = M.classify(result, truth, g)
    assert classes[0, 0, 0, 5] == M.PUNCH_THROUGH and classes[0, 0, 0, 10] == M.PUNCH_THROUGH
    assert classes[0, 0, 0, 4] == M.FALSE_HIT                               # in front of the true hit


def test_origins_from_view_z_when_position_is_missing():
    result, truth, g = _scene(with_position=False)
    # uv_to_view puts each origin on its pixel's eye ray; the true/pass hits are on the axis, still ordered
    classes, _ = M.classify(result, truth, g)
    assert classes[0, 0, 0, 5] == M.PUNCH_THROUGH and classes[0, 0, 0, 4] == M.FALSE_HIT


def test_no_gbuffer_needed_unless_a_wrong_hit_must_be_ordered():
    result, truth, g = _scene()
    with pytest.raises(ValueError, match="gbuffer"):
        M.classify(result, truth, None)
    ok = dataclasses.replace(result, hit=result.hit & False)                 # no hits at all: no ordering needed
    classes, _ = M.classify(ok, truth, None)
    assert int((classes == M.MISSED).sum()) == 6                           # the six visible targets


def test_k_px_boundary_and_validation():
    result, truth, g = _scene()
    d = float(torch.tensor([6.5 - 5.5, 0.0]).norm())                        # column 1 is 1 px off
    assert M.classify(result, truth, g, k_px=d)[0][0, 0, 0, 1] == M.CORRECT
    assert M.classify(result, truth, g, k_px=0.99)[0][0, 0, 0, 1] in (M.FALSE_HIT, M.PUNCH_THROUGH)
    for bad in (0, -1.0, math.nan, math.inf, True, "1"):
        with pytest.raises(ValueError, match="k_px"):
            M.classify(result, truth, g, k_px=bad)


def test_a_hit_on_an_unfixable_target_is_an_error_even_when_it_matches():
    result, truth, g = _scene()
    # column 6: the pass hit exactly the (off-screen) truth pixel: a screen-space pass cannot have seen it there
    assert torch.equal(result.hit_pixel[0, :, 0, 6], torch.tensor(TRUE_PX))
    assert M.classify(result, truth, g)[0][0, 0, 0, 6] == M.UNFIXABLE_HIT
    # back face wins over occluded
    vis = truth.visible.clone()
    vis[0, 0, 0, 13] = True
    classes, _ = M.classify(result, dataclasses.replace(truth, visible=vis), g)
    assert classes[0, 0, 0, 13] == M.BACK_FACE_TARGET


def test_false_hit_is_the_wrong_surface_and_misplaced_the_right_one():
    result, truth, g = _scene()
    classes, _ = M.classify(result, truth, g)
    assert classes[0, 0, 0, 4] == M.FALSE_HIT                               # lands on shape 1, truth on the slat
    assert classes[0, 0, 0, 10] == M.MISPLACED_HIT                          # the slat, 4 px off
    assert classes[0, 0, 0, 11] == M.FALSE_HIT                              # a NaN pixel shows no shape
    no_ids = M.classify(result, truth, dataclasses.replace(g, shape_id=None))[0]
    assert not bool((no_ids == M.MISPLACED_HIT).any())                     # unknown shapes: no right-surface claim


def test_reflective_mask_and_gbuffer_mask_limit_the_pixels():
    result, truth, g = _scene()
    refl = torch.ones(1, 1, H, W, dtype=torch.bool)
    refl[0, 0, 0, 1:4] = False
    classes, _ = M.classify(result, truth, g, reflective=refl)
    assert (classes[0, 0, 0, :4] == M.NOT_REFLECTIVE).all()
    assert torch.equal(classes[0, 0, 0, 4:], _expected()[0, 0, 0, 4:])
    masked = dataclasses.replace(g, mask=~refl)
    classes, _ = M.classify(result, truth, masked)
    assert (classes[0, 0, 0, 4:] == M.NOT_REFLECTIVE).all()
    with pytest.raises(TypeError, match="reflective"):
        M.classify(result, truth, g, reflective=refl.float())


def test_bad_inputs_name_the_argument():
    result, truth, g = _scene()
    with pytest.raises(ValueError, match="truth.hit_pixel"):
        M.classify(result, dataclasses.replace(truth, hit_pixel=truth.hit_pixel[..., :5]), g)
    with pytest.raises(TypeError, match="result.hit_view"):
        M.classify(dataclasses.replace(result, hit_view=None), truth, g)
    with pytest.raises(ValueError, match="truth.visible"):
        M.classify(result, dataclasses.replace(truth, visible=truth.visible.expand(1, 2, H, W)), g)


def test_fp64_inputs_and_an_all_miss_result():
    result, truth, g = _scene()
    r64 = dataclasses.replace(result, hit_pixel=result.hit_pixel.double(), hit_view=result.hit_view.double())
    assert torch.equal(M.classify(r64, truth, g.to(dtype=torch.float64))[0], _expected())
    empty = empty_result(torch.zeros(1, 3, H, W))
    classes, _ = M.classify(empty, truth, g)
    exp = _expected()
    exp[(exp == M.CORRECT) | (exp == M.FALSE_HIT) | (exp == M.PUNCH_THROUGH) | (exp == M.MISPLACED_HIT)] = M.MISSED
    exp[0, 0, 0, 3] = M.TRUE_MISS                                          # truth misses, pass misses
    exp[0, 0, 0, 6], exp[0, 0, 0, 8] = M.OFF_SCREEN_TARGET, M.BACK_FACE_TARGET   # no hit: no error there
    assert torch.equal(classes, exp)


def test_truth_classes_is_a_perfect_pass():
    _, truth, _ = _scene()
    tc = M.truth_classes(truth)
    exp = _expected()
    exp[(exp == M.MISSED) | (exp == M.FALSE_HIT) | (exp == M.PUNCH_THROUGH) | (exp == M.MISPLACED_HIT)] = M.CORRECT
    exp[0, 0, 0, 3] = M.TRUE_MISS
    exp[0, 0, 0, 6], exp[0, 0, 0, 8] = M.OFF_SCREEN_TARGET, M.BACK_FACE_TARGET
    assert torch.equal(tc, exp)


def test_class_fractions_and_counts():
    result, truth, g = _scene()
    classes, _ = M.classify(result, truth, g)
    f = M.class_fractions(classes, M.truth_classes(truth))
    n = 13                                                                  # reflective pixels
    assert f["reflective_pixels"] == n and f["reflective"] == pytest.approx(n / (H * W))
    assert f["correct"] == pytest.approx(1 / n) and f["false_hit"] == pytest.approx(3 / n)
    assert f["misplaced_hit"] == pytest.approx(1 / n) and f["unfixable_hit"] == pytest.approx(2 / n)
    assert f["punch_through"] == pytest.approx(1 / n) and f["true_miss"] == pytest.approx(1 / n)
    assert sum(f[k] for k in M.CLASS_NAMES.values() if k != "not_reflective") == pytest.approx(1.0)
    assert f["unfixable"] == pytest.approx(5 / n)                           # 6, 7, 8, 12, 13
    assert f["wrong_output"] == pytest.approx(7 / n)                        # 3 false + misplaced + punch + 2
    assert f["off_screen_target_pass_hit"] == pytest.approx(1 / n)          # the pass still hit there
    assert f["back_face_target_pass_hit"] == pytest.approx(1 / n) and f["occluded_target_pass_hit"] == 0.0
    assert "off_screen_target_pass_hit" not in M.class_fractions(classes)
    counts = M.class_counts(classes)
    assert counts["not_reflective"] == 1 + W and sum(counts.values()) == H * W
    empty = M.class_fractions(torch.zeros(1, 1, 2, 2, dtype=torch.int8))
    assert math.isnan(empty["correct"]) and empty["reflective"] == 0.0
    with pytest.raises(TypeError, match="classes"):
        M.class_fractions(classes.float())


def test_termination_fractions():
    result, truth, g = _scene()
    valid = truth.valid
    t = M.termination_fractions(result.termination, valid)
    assert t["hit"] == pytest.approx(8 / 13) and t["max_distance"] == pytest.approx(5 / 13)
    assert t["no_ray"] == 0.0 and t["out_of_steps"] == 0.0
    term = result.termination.clone()
    term[0, 0, 0, 2] = OUT_OF_STEPS
    term[0, 0, 0, 7] = OFF_SCREEN
    t = M.termination_fractions(term, valid)
    assert t["out_of_steps"] == pytest.approx(1 / 13) and t["off_screen"] == pytest.approx(1 / 13)


def test_hit_error_over_pairs():
    result, truth, g = _scene()
    classes, _ = M.classify(result, truth, g)
    e = M.hit_error(result, truth, classes == M.CORRECT)
    assert e["n"] == 1 and e["px_mean"] == pytest.approx(1.0) and e["view_mean"] == pytest.approx(0.1, abs=1e-6)
    pairs = torch.isin(classes, torch.tensor((M.CORRECT, M.FALSE_HIT, M.MISPLACED_HIT, M.PUNCH_THROUGH),
                                             dtype=classes.dtype))
    e = M.hit_error(result, truth, pairs)
    assert e["n"] == 4                                   # columns 1, 4, 5, 10 (3: truth misses; 11: NaN pixel)
    px = [1.0, 5.0, math.hypot(5, 1), math.hypot(4, 1)]
    assert e["px_mean"] == pytest.approx(sum(px) / 4) and e["px_max"] == pytest.approx(max(px))
    assert e["view_max"] == pytest.approx(2.0)
    px_map, view_map = M.hit_error_maps(result, truth)
    assert math.isnan(float(px_map[0, 0, 0, 2])) and float(view_map[0, 0, 0, 5]) == pytest.approx(2.0)
    none = M.hit_error(result, truth, torch.zeros(1, 1, H, W, dtype=torch.bool))
    assert none["n"] == 0 and math.isnan(none["px_mean"])


def test_color_error_faded_vs_raw():
    result, truth, g = _scene()
    c = M.color_error(result, truth)
    # raw colour 0.5 on the 8 hit pixels (radiance 0.5), 0 on the 5 misses; faded colour halves it
    assert c["mae_raw"] == pytest.approx(5 * 0.5 / 13, rel=1e-5)
    assert c["mae_faded"] == pytest.approx((5 * 0.5 + 8 * 0.25) / 13, rel=1e-5)
    assert c["psnr_raw"] > c["psnr_faded"] and 0 <= c["flip_raw"] <= c["flip_faded"] <= 1
    assert math.isnan(M.color_error(result, truth, flip=False)["flip_raw"])
    with pytest.raises(TypeError, match="truth.radiance"):
        M.color_error(result, dataclasses.replace(truth, radiance=None))
    err = M.color_error_map(result.raw_color, truth.radiance)
    assert err.shape == (1, 1, H, W) and float(err[0, 0, 0, 2]) == pytest.approx(0.5)


def test_class_rgb_and_legend():
    result, truth, g = _scene()
    classes, _ = M.classify(result, truth, g)
    rgb = M.class_rgb(classes)
    assert rgb.shape == (H, W, 3) and rgb.dtype == np.uint8
    for j, c in enumerate(CASES):
        assert tuple(rgb[0, j]) == tuple(int(v * 255 + 0.5) for v in M.CLASS_COLORS[c[8]]), j
    assert len({tuple(v) for v in M.CLASS_COLORS.values()}) == len(M.CLASS_COLORS)
    entries = M.legend_entries()
    assert [e["key"] for e in entries] == list(M.CLASS_NAMES.values())
    assert all(e["color"].startswith("#") and len(e["color"]) == 7 and e["description"] for e in entries)
    assert len(M.legend_handles([M.CORRECT, M.MISSED])) == 2
    with pytest.raises(ValueError, match="codes"):
        M.legend_entries([42])


def test_hard_cases_give_finite_outputs():
    """Degenerate pass output (NaN/Inf hit buffers) never produces NaN classes or crashes."""
    result, truth, g = _scene()
    bad = dataclasses.replace(result, hit_view=torch.full_like(result.hit_view, math.inf),
                              hit_pixel=torch.full_like(result.hit_pixel, math.nan))
    classes, _ = M.classify(bad, truth, g)
    assert ((classes >= 0) & (classes <= max(M.CLASS_NAMES))).all()
    assert (classes[result.hit & truth.hit & truth.on_screen & truth.visible & ~truth.back_face]
            == M.FALSE_HIT).all()
