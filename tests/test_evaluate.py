"""ssbench.evaluate.ao: one tidy row, with a stub pass and a stub ground truth (fast, no Mitsuba)."""
import dataclasses
import math
import sys
import types

import pytest
import torch

from ssbench import evaluate, reference
from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes import AO_METHODS, AOResult

H, W = 12, 16
GT = 0.7                 # stub ground truth on the left half (the right half and background: 1)


def _gbuffer(channels=("view_z", "position", "normal", "mask")) -> GBuffer:
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, W, H, 0.1, 100.0)
    z = torch.full((1, 1, H, W), -5.0)
    z[..., W // 2:] = -9.0                                                   # a depth step in the middle
    mask = torch.ones(1, 1, H, W, dtype=torch.bool)
    mask[..., :2, :] = False                                                 # two rows of background
    z[~mask] = -100.0
    pos = cam.uv_to_view(cam.uv_grid()[None], z)
    normal = torch.zeros(1, 3, H, W)
    normal[:, 2] = 1.0
    normal[~mask.expand(1, 3, H, W)] = 0.0
    full = dict(view_z=z, position=pos, normal=normal, mask=mask)
    return GBuffer(cam, **{k: v for k, v in full.items() if k in channels})


def _gt_map(value=GT) -> torch.Tensor:
    g = _gbuffer()
    ao = torch.ones(1, 1, H, W)
    ao[..., : W // 2] = value
    ao[~g.mask] = 1.0
    return ao


@dataclasses.dataclass(frozen=True)
class StubParams:
    radius: float = 0.5
    strength: float = 2.0                         # occlusion = strength × GT occlusion
    num_samples: int = 8

    def __post_init__(self):
        if not self.radius > 0:
            raise ValueError(f"radius: must be > 0, got {self.radius}")


class Calls:
    def __init__(self):
        self.passes, self.gt, self.oracle, self.gbuffer = [], [], [], []


@pytest.fixture
def stub(monkeypatch):
    """Register a stub AO method and stub the reference (G-buffer, ground truth, oracle)."""
    calls = Calls()
    mod = types.ModuleType("ssbench_stub_ao")

    def stub_ao(gbuffer, params, *, generator=None, debug=False):
        calls.passes.append((gbuffer.channels, params, generator))
        noise = 0.01 * torch.rand(1, 1, H, W, generator=generator)
        ao = (1 - params.strength * (1 - _gt_map())).clamp(0, 1) - noise * gbuffer.mask
        return AOResult(ao.clamp(0, 1))

    stub_ao.__module__ = mod.__name__
    mod.stub_ao, mod.StubParams, mod.REQUIRES, mod.FLAVOUR = stub_ao, StubParams, ("view_z", "mask"), "obscurance"
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setitem(AO_METHODS, "stub", "ssbench_stub_ao:stub_ao:StubParams")

    def fake_gbuffer(scene, width=None, height=None, channels=None, **kw):
        calls.gbuffer.append((width, height, tuple(channels)))
        return _gbuffer()

    def fake_ao(scene, gbuffer, radius, rays=256, weighting="cosine", seed=0, *, use_cache=True):
        calls.gt.append((weighting, radius, rays, seed))
        return reference.AOReference(_gt_map(), torch.full((1, 1, H, W), 0.01), weighting, radius, rays)

    def fake_oracle(gbuffer, radius, rays=256, weighting="cosine", seed=0, *, use_cache=True):
        calls.oracle.append((weighting, radius, rays, seed))
        return reference.AOReference(_gt_map(0.8), torch.zeros(1, 1, H, W), weighting, radius, rays)

    monkeypatch.setattr(reference, "gbuffer", fake_gbuffer)
    monkeypatch.setattr(reference, "ambient_occlusion", fake_ao)
    monkeypatch.setattr(reference, "screen_space_oracle", fake_oracle)
    return calls, mod


def test_row_holds_settings_timings_and_metrics(stub):
    calls, _ = stub
    row = evaluate.ao("crease", "stub", width=W, height=H, rays=32, seed=3, repeats=2)
    assert row["scene"] == "crease" and row["method"] == "stub"
    assert row["params"] == {"radius": 0.5, "strength": 2.0, "num_samples": 8}
    assert (row["width"], row["height"], row["rays"], row["seed"]) == (W, H, 32, 3)
    assert row["radius"] == 0.5 and row["radius_param"] == "radius" and row["weighting"] == "obscurance"
    assert row["threads"] == torch.get_num_threads() and row["repeats"] == 2
    assert len(row["seconds_runs"]) == 2 and row["seconds"] > 0
    assert len(calls.passes) == 3                                            # one warm-up + 2 timed runs
    # the pass sees only its REQUIRES channels; every run gets a fresh generator seeded with `seed`
    assert {c[0] for c in calls.passes} == {("view_z", "mask")}
    assert all(c[2].initial_seed() == 3 for c in calls.passes)
    assert calls.gbuffer == [(W, H, ("view_z", "mask", "position", "normal"))]
    # ground truth: the pass's flavour and cosine; the oracle in the flavour
    assert sorted(c[0] for c in calls.gt) == ["cosine", "obscurance"]
    assert calls.oracle == [("obscurance", 0.5, 32, 3)]
    for t in ("cos", "flavour", "oracle"):
        for m in evaluate.TARGET_METRICS:
            assert isinstance(row[f"{m}_{t}"], float), (m, t)
    for k in ("banding", "banding_target", "tile", "tile_energy", "noise", "info_loss_rmse", "info_loss_mae", "info_loss_bias", "estimator_rmse",
              "estimator_mae", "gt_stderr_cos", "coverage", "nonfinite", "oracle"):
        assert k in row, k
    assert row["oracle"] is True and row["nonfinite"] == 0
    assert row["coverage"] == pytest.approx((H - 2) / H)


def test_metric_values_in_closed_form(stub):
    row = evaluate.ao("crease", "stub", {"num_samples": 4}, width=W, height=H, repeats=1)
    # stub: occlusion = 2 × GT occlusion (0.3 → 0.6) on the left, minus tiny noise; GT 1 on the right
    assert row["over_darkening_cos"] == pytest.approx(2.0, rel=0.05)
    assert row["bias_cos"] == pytest.approx(-0.3 / 2, abs=0.01)
    assert row["mae_flavour"] == pytest.approx(0.3 / 2, abs=0.01)
    assert row["flat_bias_cos"] == pytest.approx(0.005, abs=0.005)            # right half: only the noise
    assert row["info_loss_mae"] == pytest.approx(0.1 / 2, abs=1e-6)           # oracle 0.8 vs GT 0.7 on half
    assert row["info_loss_bias"] == pytest.approx(0.05, abs=1e-6)
    assert row["estimator_rmse"] == row["rmse_oracle"]
    assert row["gt_stderr_cos"] == pytest.approx(0.01)
    assert row["psnr_cos"] > 0 and 0 < row["ssim_cos"] < 1 and 0 < row["flip_cos"] < 1
    assert row["halo_band_cos"] > 0 and math.isfinite(row["halo_ratio_cos"])


def test_params_dataclass_dict_and_errors(stub):
    row = evaluate.ao("crease", "stub", StubParams(strength=1.0), width=W, height=H, repeats=1)
    assert row["params"]["strength"] == 1.0
    assert row["over_darkening_cos"] == pytest.approx(1.0, rel=0.05)
    with pytest.raises(ValueError, match="'bogus'"):
        evaluate.ao("crease", "stub", {"bogus": 1, "strength": 1.0}, width=W, height=H)
    with pytest.raises(TypeError, match="params"):
        evaluate.ao("crease", "stub", [("strength", 1.0)], width=W, height=H)
    with pytest.raises(ValueError, match="radius"):                          # the dataclass's own validation
        evaluate.ao("crease", "stub", {"radius": -1.0}, width=W, height=H)
    with pytest.raises(ValueError, match="repeats"):
        evaluate.ao("crease", "stub", width=W, height=H, repeats=0)
    with pytest.raises(ValueError, match="weighting"):
        evaluate.ao("crease", "stub", width=W, height=H, weighting="ambient")
    with pytest.raises(KeyError, match="method"):
        evaluate.ao("crease", "no_such_method", width=W, height=H)


def test_radius_sets_pass_and_ground_truth(stub):
    calls, _ = stub
    row = evaluate.ao("crease", "stub", width=W, height=H, radius=2.0, repeats=1)
    assert row["params"]["radius"] == 2.0 and row["radius"] == 2.0
    assert calls.passes[-1][1].radius == 2.0
    assert {c[1] for c in calls.gt} == {2.0} and calls.oracle[-1][1] == 2.0
    with pytest.raises(ValueError, match="conflicts"):
        evaluate.ao("crease", "stub", {"radius": 1.0}, width=W, height=H, radius=2.0)
    with pytest.raises(ValueError, match="radius"):
        evaluate.ao("crease", "stub", width=W, height=H, radius=0)


def test_radius_param_lookup(stub):
    @dataclasses.dataclass(frozen=True)
    class KernelParams:
        kernel_radius: float = 8.0

    @dataclasses.dataclass(frozen=True)
    class NoRadius:
        strength: float = 1.0

    assert evaluate.radius_param(KernelParams) == "kernel_radius"
    assert evaluate.radius_param(NoRadius) is None
    assert evaluate.radius_param(NoRadius, types.SimpleNamespace(RADIUS_PARAM="strength")) == "strength"
    _, mod = stub
    mod.StubParams = NoRadius
    with pytest.raises(ValueError, match="no radius parameter"):
        evaluate.ao("crease", "stub", width=W, height=H, repeats=1)


def test_default_flavour_is_cosine_and_gt_is_traced_once(stub, monkeypatch):
    calls, mod = stub
    monkeypatch.delattr(mod, "FLAVOUR")
    row = evaluate.ao("crease", "stub", width=W, height=H, repeats=1)
    assert row["weighting"] == "cosine"
    assert [c[0] for c in calls.gt] == ["cosine"]
    assert row["rmse_cos"] == row["rmse_flavour"]
    calls.gt.clear()
    row = evaluate.ao("crease", "stub", width=W, height=H, repeats=1, weighting="uniform")
    assert sorted(c[0] for c in calls.gt) == ["cosine", "uniform"] and row["weighting"] == "uniform"


def test_shared_references_memo(stub):
    calls, _ = stub
    memo = {}
    g = _gbuffer()
    for _ in range(2):
        evaluate.ao("crease", "stub", width=W, height=H, repeats=1, references=memo, gbuffer=g)
    assert len(calls.gt) == 2 and len(calls.oracle) == 1 and calls.gbuffer == []


def test_gbuffer_must_hold_the_channels(stub):
    with pytest.raises(ValueError, match="position"):
        evaluate.ao("crease", "stub", repeats=1, gbuffer=_gbuffer(("view_z", "mask", "normal")))


def test_missing_oracle_gives_nan(stub, monkeypatch):
    def broken(*a, **k):
        raise NotImplementedError("no oracle here")
    monkeypatch.setattr(reference, "screen_space_oracle", broken)
    row = evaluate.ao("crease", "stub", width=W, height=H, repeats=1)
    assert row["oracle"] is False and "no oracle here" in row["oracle_error"]
    assert math.isnan(row["rmse_oracle"]) and math.isnan(row["info_loss_rmse"])
    assert math.isfinite(row["rmse_cos"])
    row = evaluate.ao("crease", "stub", width=W, height=H, repeats=1, oracle=False, flip=False)
    assert row["oracle"] is False and math.isnan(row["flip_cos"])


def test_blur_scores_the_blurred_map(stub):
    import kornia
    calls, _ = stub
    seen = []

    def box(ao, gbuffer):
        seen.append(gbuffer.channels)
        return kornia.filters.box_blur(ao, 5)

    row = evaluate.ao("crease", "stub", width=W, height=H, repeats=2, blur=box)
    assert row["blur"] == "box" and row["blur_seconds"] > 0 and len(seen) == 3
    assert row["noise"] < row["noise_raw"]
    with pytest.raises(TypeError, match="blur"):
        evaluate.ao("crease", "stub", width=W, height=H, blur=3)


def test_run_ao_returns_the_images(stub):
    ev = evaluate.run_ao("crease", "stub", width=W, height=H, repeats=1)
    assert ev.ao.shape == (1, 1, H, W) and torch.equal(ev.ao, ev.ao_raw)
    assert set(ev.references) == {"cos", "flavour", "oracle"}
    assert ev.row["rmse_cos"] == pytest.approx(float((ev.ao - ev.references["cos"].ao)[ev.gbuffer.mask]
                                                     .square().mean().sqrt()), rel=1e-6)


def test_wrong_output_shape_is_an_error(stub):
    _, mod = stub

    def bad(gbuffer, params, *, generator=None, debug=False):
        return AOResult(torch.ones(1, 1, H, W - 1))
    bad.__module__ = mod.__name__
    mod.stub_ao = bad
    with pytest.raises(ValueError, match="shape"):
        evaluate.ao("crease", "stub", width=W, height=H, repeats=1)


@pytest.mark.slow
@pytest.mark.mitsuba
@pytest.mark.parametrize("method", ["hbao", "gtao", "ssao", "crytek"])
def test_real_pass_against_real_reference(method, tmp_path, monkeypatch):
    """End to end on a tiny image: the real pass, G-buffer and ray-traced ground truth."""
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))
    from ssbench.passes import ao_method
    try:
        ao_method(method)
    except (ImportError, AttributeError) as e:
        pytest.skip(f"{method} not importable yet: {e}")
    row = evaluate.ao("crease", method, width=32, height=24, rays=16, repeats=1)
    assert row["nonfinite"] == 0 and 0 <= row["mae_cos"] <= 1
    assert math.isfinite(row["rmse_oracle"]) and math.isfinite(row["info_loss_rmse"])


@pytest.mark.parametrize("name", evaluate.BLUR_NAMES)
def test_named_blurs(stub, name):
    row = evaluate.ao("crease", "stub", width=W, height=H, repeats=1, blur=name)
    assert row["blur"] == name and row["noise"] < row["noise_raw"]


def test_unknown_blur_name(stub):
    calls, _ = stub
    with pytest.raises(ValueError, match="blur: unknown blur 'gauss'; known: box"):
        evaluate.ao("crease", "stub", width=W, height=H, blur="gauss")
    assert not calls.passes and not calls.gbuffer                          # checked before any work


def test_no_warmup(stub):
    calls, _ = stub
    row = evaluate.ao("crease", "stub", width=W, height=H, repeats=1, warmup=False)
    assert len(calls.passes) == 1 and row["warmup"] is False


# ------------------------------------------------------------------------------------------ SSR rows
from ssbench.metrics import ssr as SSRM  # noqa: E402
from ssbench.passes import SSR_METHODS  # noqa: E402
from ssbench.passes.ssr.common import HIT, MAX_DISTANCE, NO_RAY, OUT_OF_STEPS, SSRResult  # noqa: E402

SH, SW = 10, 16          # rows 0-1 background; left half: truth hits visibly (3 px up); right half: sky


@dataclasses.dataclass(frozen=True)
class StubSSRParams:
    thickness: float = 0.1
    use_back_face_depth: bool = False
    miss_rows: int = 2                      # the pass misses the last `miss_rows` rows of the left half
    fade: float = 0.5

    def __post_init__(self):
        if not self.thickness > 0:
            raise ValueError(f"thickness: must be > 0, got {self.thickness}")


@dataclasses.dataclass(frozen=True)
class StubTruth:
    valid: torch.Tensor
    hit: torch.Tensor
    hit_view: torch.Tensor
    hit_pixel: torch.Tensor
    on_screen: torch.Tensor
    visible: torch.Tensor
    back_face: torch.Tensor
    hit_shape: torch.Tensor
    radiance: torch.Tensor
    seconds: float = 0.25


def _ssr_full_gbuffer() -> GBuffer:
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, SW, SH, 0.1, 100.0)
    mask = torch.ones(1, 1, SH, SW, dtype=torch.bool)
    mask[..., :2, :] = False
    z = torch.where(mask, -5.0, -100.0)
    n = torch.where(mask, torch.tensor([0.0, 1.0, 0.0]).view(1, 3, 1, 1), 0.0)
    return GBuffer(cam, view_z=z, position=cam.uv_to_view(cam.uv_grid()[None], z), normal=n, mask=mask,
                   shape_id=torch.where(mask, 0, -1).int(), color=torch.full((1, 3, SH, SW), 0.4),
                   back_z=torch.where(mask, -5.5, -math.inf), albedo=torch.zeros(1, 3, SH, SW),
                   roughness=torch.zeros(1, 1, SH, SW), metallic=torch.ones(1, 1, SH, SW))


def _stub_truth(g: GBuffer) -> StubTruth:
    mask = g.mask
    left = torch.zeros_like(mask)
    left[..., : SW // 2] = True
    hit = mask & left
    px = g.camera.pixel_centers()[None] + torch.tensor([0.0, -3.0]).view(1, 2, 1, 1)
    return StubTruth(valid=mask.clone(), hit=hit, hit_view=torch.where(hit, g.position - 1.0, 0.0),
                     hit_pixel=torch.where(hit, px, -1.0), on_screen=hit.clone(), visible=hit.clone(),
                     back_face=torch.zeros_like(hit), hit_shape=torch.where(hit, 1, -1).int(),
                     radiance=torch.where(mask, 0.4, 0.0).expand(1, 3, SH, SW).contiguous())


class SSRCalls:
    def __init__(self):
        self.passes, self.gbuffer, self.truth = [], [], []


@pytest.fixture
def stub_ssr(monkeypatch):
    """Register a stub SSR method ('stub') and stub the reference (G-buffer channels, reflections)."""
    calls = SSRCalls()
    mod = types.ModuleType("ssbench_stub_ssr")

    def stub(gbuffer, params, *, generator=None, debug=False):
        calls.passes.append((gbuffer.channels, params, generator, debug))
        truth = _stub_truth(_ssr_full_gbuffer())
        hit = truth.hit.clone()
        if params.miss_rows:
            hit[..., SH - params.miss_rows:, :] = False
        term = torch.where(hit, HIT, MAX_DISTANCE).to(torch.int8)
        term[..., SH - 1, SW // 2:] = OUT_OF_STEPS
        term[~gbuffer.mask] = NO_RAY
        raw = torch.where(hit, gbuffer.color, 0.0)
        fade = torch.full((1, 1, SH, SW), params.fade)
        extra = {"visits": torch.ones(1, 1, SH, SW, dtype=torch.int32)} if debug else {}
        return SSRResult(color=raw * fade, hit=hit, hit_pixel=torch.where(hit, truth.hit_pixel, -1.0),
                         hit_view=torch.where(hit, truth.hit_view, 0.0),
                         steps=torch.where(gbuffer.mask, 7, 0).int(), termination=term, fade=fade,
                         raw_color=raw, debug=extra)

    stub.__module__ = mod.__name__
    mod.stub, mod.StubSSRParams = stub, StubSSRParams
    mod.REQUIRES = ("view_z", "normal", "mask", "color")
    mod.REQUIRES_BACKFACE = mod.REQUIRES + ("back_z",)
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setitem(SSR_METHODS, "stub", f"{mod.__name__}:stub:StubSSRParams")

    def fake_gbuffer(scene, width=None, height=None, channels=None, spp=64, seed=0, **kw):
        calls.gbuffer.append((width, height, tuple(channels), spp, seed))
        return _ssr_full_gbuffer().select(tuple(channels))

    def fake_reflections(scene, gbuffer, *, spp=16, seed=0, use_cache=True):
        calls.truth.append((gbuffer.channels, spp, seed))
        return _stub_truth(_ssr_full_gbuffer())

    monkeypatch.setattr(reference, "gbuffer", fake_gbuffer)
    monkeypatch.setattr(reference, "reflections", fake_reflections, raising=False)
    return calls, mod


def test_ssr_row_settings_classes_and_metrics(stub_ssr):
    calls, _ = stub_ssr
    row = evaluate.ssr("reflective_floor", "stub", width=SW, height=SH, seed=2, repeats=2, spp=4)
    assert row["scene"] == "reflective_floor" and row["method"] == "stub"
    assert row["params"] == {"thickness": 0.1, "use_back_face_depth": False, "miss_rows": 2, "fade": 0.5}
    assert (row["width"], row["height"], row["seed"], row["spp"], row["k_px"]) == (SW, SH, 2, 4, 1.5)
    assert len(calls.passes) == 3 and len(row["seconds_runs"]) == 2 and row["seconds"] > 0
    assert {c[0] for c in calls.passes} == {("view_z", "normal", "mask", "color")}   # only REQUIRES
    assert all(c[2].initial_seed() == 2 and c[3] is False for c in calls.passes)
    assert calls.gbuffer == [(SW, SH, ("view_z", "normal", "mask", "color", "position", "shape_id"), 4, 2)]
    assert [c[1:] for c in calls.truth] == [(4, 2)]
    assert row["channels"] == ["view_z", "normal", "mask", "color"] and row["back_face_depth"] is False
    # closed form: 8 reflective rows x 16; left half: truth hits, pass misses the last 2 rows; right half: sky
    n = 8 * SW
    assert row["reflective_pixels"] == n and row["coverage"] == pytest.approx(n / (SH * SW))
    assert row["frac_correct"] == pytest.approx(6 * 8 / n) and row["frac_missed"] == pytest.approx(2 * 8 / n)
    assert row["frac_true_miss"] == pytest.approx(0.5) and row["frac_false_hit"] == 0.0
    assert row["frac_unfixable"] == 0.0 and row["frac_off_screen_target_pass_hit"] == 0.0
    assert row["frac_misplaced_hit"] == 0.0 and row["frac_unfixable_hit"] == 0.0 and row["frac_wrong_output"] == 0.0
    assert row["hit_rate"] == pytest.approx(48 / n) and row["truth_hit_rate"] == pytest.approx(0.5)
    assert row["hit_err_n"] == 48 and row["hit_err_px_max"] == 0.0 and row["hit_err_correct_view_mean"] == 0.0
    # colour: raw 0.4 where hit (radiance 0.4 on every reflective pixel, 0 for misses), faded × 0.5
    assert row["mae_raw"] == pytest.approx(0.4 * (n - 48) / n, rel=1e-5)
    assert row["mae_faded"] == pytest.approx((0.4 * (n - 48) + 0.2 * 48) / n, rel=1e-5)
    assert row["psnr_raw"] > row["psnr_faded"] and 0 < row["flip_raw"] < row["flip_faded"]
    assert row["mae_raw_truth_hit"] == pytest.approx(0.4 * 16 / 64, rel=1e-5)      # left half only: no sky
    assert row["mae_faded_truth_hit"] == pytest.approx((0.4 * 16 + 0.2 * 48) / 64, rel=1e-5)
    assert row["term_hit"] == pytest.approx(48 / n) and row["term_out_of_steps"] == pytest.approx(8 / n)
    assert row["steps_mean"] == 7.0 and row["steps_max"] == 7 and row["nonfinite"] == 0
    assert row["gt_seconds"] == 0.25 and row["threads"] == torch.get_num_threads()


def test_ssr_back_face_depth_adds_its_channels(stub_ssr):
    calls, _ = stub_ssr
    row = evaluate.ssr("fence", "stub", {"use_back_face_depth": True}, width=SW, height=SH, repeats=1)
    assert row["back_face_depth"] is True and row["channels"][-1] == "back_z"
    assert "back_z" in calls.gbuffer[-1][2] and "back_z" in calls.passes[-1][0]


def test_ssr_pass_channels_prefers_the_module_function():
    mod = types.SimpleNamespace(REQUIRES=("view_z",), required_channels=lambda p: ("view_z", "position"))
    assert evaluate.pass_channels(mod, StubSSRParams()) == ("view_z", "position")
    mod = types.SimpleNamespace(REQUIRES=("view_z", "color"))
    assert evaluate.pass_channels(mod, StubSSRParams(use_back_face_depth=True)) == ("view_z", "color", "back_z")


def test_ssr_params_and_argument_errors(stub_ssr):
    calls, _ = stub_ssr
    with pytest.raises(ValueError, match="'bogus'"):
        evaluate.ssr("fence", "stub", {"bogus": 1}, width=SW, height=SH)
    with pytest.raises(ValueError, match="thickness"):
        evaluate.ssr("fence", "stub", {"thickness": 0.0}, width=SW, height=SH)
    for kw, name in (({"repeats": 0}, "repeats"), ({"seed": -1}, "seed"), ({"spp": 0}, "spp"),
                     ({"k_px": 0}, "k_px"), ({"reflective": "some"}, "reflective")):
        with pytest.raises(ValueError, match=name):
            evaluate.ssr("fence", "stub", width=SW, height=SH, **kw)
    with pytest.raises(KeyError, match="method"):
        evaluate.ssr("fence", "no_such_method", width=SW, height=SH)
    assert not calls.passes and not calls.gbuffer                            # checked before any work


def test_ssr_reuses_gbuffer_and_truth_and_collects_visits(stub_ssr):
    calls, _ = stub_ssr
    g = _ssr_full_gbuffer()
    truth = _stub_truth(g)
    ev = evaluate.run_ssr("fence", "stub", gbuffer=g, truth=truth, repeats=1, warmup=False, debug=True,
                          flip=False)
    assert not calls.gbuffer and not calls.truth
    assert [c[3] for c in calls.passes] == [False, True]                    # the timed run, then the debug run
    assert ev.debug["visits"].shape == (1, 1, SH, SW) and ev.classes.shape == (1, 1, SH, SW)
    assert ev.truth is truth and math.isnan(ev.row["flip_raw"]) and ev.row["warmup"] is False
    with pytest.raises(ValueError, match="shape_id"):
        evaluate.ssr("fence", "stub", gbuffer=g.select(("view_z", "normal", "mask", "color", "position")),
                     truth=truth, repeats=1)


def test_ssr_marched_pixels_only(stub_ssr):
    _, mod = stub_ssr
    row = evaluate.ssr("fence", "stub", width=SW, height=SH, repeats=1, reflective="marched", flip=False)
    assert row["reflective"] == "marched" and row["reflective_pixels"] == 8 * SW      # NO_RAY only off mask


def test_ssr_wrong_output_shape_is_an_error(stub_ssr):
    _, mod = stub_ssr

    def bad(gbuffer, params, *, generator=None, debug=False):
        r = SSRResult(*(torch.zeros(1, c, SH, SW - 1) for c in (3, 1, 2, 3, 1, 1, 1, 3)))
        return dataclasses.replace(r, hit=r.hit.bool())
    bad.__module__ = mod.__name__
    mod.stub = bad
    with pytest.raises(ValueError, match="shape"):
        evaluate.ssr("fence", "stub", width=SW, height=SH, repeats=1)


@pytest.mark.slow
@pytest.mark.mitsuba
@pytest.mark.parametrize("method", ["linear", "dda", "dda_supercover"])
def test_real_ssr_pass_against_real_reflections(method, tmp_path, monkeypatch):
    """End to end on a tiny image: the real pass, G-buffer and exact reflections."""
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))
    from ssbench.passes import ssr_method
    try:
        ssr_method(method)
    except (ImportError, AttributeError) as e:
        pytest.skip(f"{method} not importable yet: {e}")
    row = evaluate.ssr("reflective_floor", method, width=40, height=30, spp=2, repeats=1, flip=False)
    assert row["nonfinite"] == 0 and row["reflective_pixels"] > 0
    total = sum(row[f"frac_{k}"] for k in SSRM.CLASS_NAMES.values() if k != "not_reflective")
    assert total == pytest.approx(1.0)


@pytest.mark.slow
def test_ssr_specular_mask_counts_only_mirror_pixels():
    from ssbench.evaluate import ssr
    from ssbench.reference import gbuffer
    g = gbuffer("reflective_floor", 64, 48, channels=["metallic", "roughness", "mask"])
    want = int((g.mask & ((g.metallic >= 0.5) | (g.roughness <= 0.5))).sum())
    row = ssr("reflective_floor", "linear", width=64, height=48, repeats=1, reflective="specular", spp=2)
    assert row["reflective_pixels"] == want and 0 < want < 64 * 48
    with pytest.raises(ValueError, match="reflective"):
        ssr("reflective_floor", "linear", width=64, height=48, repeats=1, reflective="shiny")


def test_tile_energy_is_measured_at_the_pass_noise_tile_and_banding_against_the_truth():
    """An 8-px noise tile is scored at 8 (a tile-4 score would miss its 1/8-cycle harmonics); without an oracle,
    banding is scored against the flavour ground truth with its standard error."""
    from ssbench import metrics
    from ssbench.evaluate import run_ao
    ev = run_ao("sphere_on_plane", "ssao", {"noise_size": 8, "kernel_size": 8}, width=64, height=48, rays=64, radius=1.5,
                flip=False, repeats=1, oracle=False)
    assert ev.row["tile"] == 8
    pred = ev.result.ao.float()
    assert ev.row["tile_energy"] == pytest.approx(float(metrics.tile_energy(pred, ev.gbuffer.mask, tile=8)))
    assert ev.row["tile_energy"] > float(metrics.tile_energy(pred, ev.gbuffer.mask, tile=4))
    ref = ev.references["flavour"]
    assert ev.row["banding_target"] == "flavour" and ev.row["banding"] > 0
    assert ev.row["banding"] == pytest.approx(float(metrics.banding(pred, ref.ao, ev.gbuffer.view_z, ev.gbuffer.mask,
                                                                    target_stderr=ref.stderr)))
