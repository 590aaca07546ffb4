"""The compiled switch: each AO pass's per-band kernel through ``torch.compile`` gives the eager bits (GTAO and VBAO:
stated exceptions), the switch's precedence (context manager over ``SSBENCH_COMPILE``) holds, and first calls are
counted as compile time."""
import dataclasses

import pytest
import torch

from ssbench.passes import compiled as C


def test_the_context_manager_overrides_the_environment(monkeypatch):
    monkeypatch.setenv(C.ENV, "1")
    assert C.enabled()
    with C.compiling(False):
        assert not C.enabled()
        with C.compiling(True):
            assert C.enabled()
        assert not C.enabled()
    monkeypatch.setenv(C.ENV, "0")
    assert not C.enabled()
    monkeypatch.setenv(C.ENV, "maybe")                                  # a typo is an error, not "off"
    with pytest.raises(ValueError, match=f"^{C.ENV}: .*'maybe'"):
        C.enabled()
    with C.compiling(False):                                            # the context manager still decides
        assert not C.enabled()
    with pytest.raises(TypeError, match="^on:"):
        with C.compiling("yes"):
            pass


def test_a_kernel_runs_eager_when_off_and_compiled_once_per_signature_when_on():
    @C.kernel
    def double(x):
        return x * 2

    x = torch.arange(4.0)
    before = C.compile_seconds()
    with C.compiling(False):
        assert torch.equal(double(x), x * 2) and C.compile_seconds() == before     # eager: nothing compiled
    with C.compiling(True):
        assert torch.equal(double(x), x * 2)
        first = C.compile_seconds()
        assert first > before
        assert torch.equal(double(x + 1), (x + 1) * 2) and C.compile_seconds() == first   # same signature
        assert torch.equal(double(torch.arange(5.0)), torch.arange(5.0) * 2) and C.compile_seconds() > first
    assert double.eager(x).tolist() == [0.0, 2.0, 4.0, 6.0]


def _variant_settings() -> tuple:
    return (torch._dynamo.config.recompile_limit, torch._dynamo.config.accumulated_recompile_limit,
            torch._dynamo.config.fail_on_recompile_limit_hit, torch.fx.experimental._config.use_duck_shape)


def test_a_compiled_call_runs_with_room_for_its_variants_and_restores_the_settings_after_it():
    seen = []
    record = torch._dynamo.disable(lambda: seen.append(_variant_settings()))    # runs when the compiled call runs

    @C.kernel
    def probe(x, fail):
        record()
        if fail:
            raise ValueError("fail: as asked")
        return x + 1

    before = _variant_settings()
    assert before[0] < C.KERNEL_VARIANTS                                  # dynamo's default (8) would run eager past it
    with C.compiling(True):
        assert probe(torch.zeros(3), False).tolist() == [1.0, 1.0, 1.0]
        assert probe(torch.zeros(3), False).tolist() == [1.0, 1.0, 1.0]     # a later call, already compiled
        with pytest.raises(ValueError, match="^fail: as asked"):
            probe(torch.zeros(3), True)
    assert seen[:2] == [(C.KERNEL_VARIANTS, 16 * C.KERNEL_VARIANTS, True, False)] * 2
    assert _variant_settings() == before                                 # restored, after the error too


def test_a_kept_mask_is_bool_eager_and_float_inside_a_compiled_kernel():
    @C.kernel
    def hold(x):                                 # what the kernel stores: the kept mask itself, and a selection by it
        m = C.kept_mask(x > 0)
        return m, torch.where(C.is_set(m), x, -x)

    x = torch.tensor([-2.0, 0.0, 3.0, float("nan")])
    with C.compiling(False):
        m, y = hold(x)
        assert m.dtype == torch.bool and m.tolist() == [False, False, True, False]
    with C.compiling(True):
        mc, yc = hold(x)
    assert mc.dtype == torch.float32 and mc.tolist() == [0.0, 0.0, 1.0, 0.0]
    assert torch.equal(C.is_set(mc), m)
    torch.testing.assert_close(yc, y, rtol=0, atol=0, equal_nan=True)     # the same selections


def test_a_dynamic_kernel_counts_one_compilation_for_every_size_and_number():
    @C.kernel(dynamic=True)
    def scaled(x, s):
        return x * s

    with C.compiling(True):
        assert torch.equal(scaled(torch.arange(6.0), 2.0), torch.arange(6.0) * 2)
        first = C.compile_seconds()
        assert torch.equal(scaled(torch.arange(9.0), 3.0), torch.arange(9.0) * 3)   # another size, another number
        assert C.compile_seconds() == first
    assert C._signature((torch.zeros(3), 1.0), {}, dynamic=True) == C._signature((torch.zeros(5), 2.0), {}, dynamic=True)
    assert C._signature((torch.zeros(3),), {}) != C._signature((torch.zeros(5),), {})
    assert C._signature((torch.zeros(3), True), {}, dynamic=True) != C._signature((torch.zeros(3), False), {}, dynamic=True)

    from ssbench.camera import Camera
    cam = lambda w, h, fovy=60.0: Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), fovy, w, h, 0.1, 9.0)  # noqa
    dynamic = lambda *a: C._signature(a, {}, dynamic=True)                                             # noqa: E731
    assert dynamic(cam(8, 6)) == dynamic(cam(40, 20)) != dynamic(cam(8, 6, 45.0))   # a camera's size is a number
    assert C._signature((cam(8, 6),), {}) != C._signature((cam(40, 20),), {})


@pytest.mark.slow
def test_compiled_ssr_marchers_follow_every_changed_setting_as_a_sweep_does():
    """A sweep runs one marcher compiled over many settings in one process, and a size-dynamic kernel takes the
    numbers as symbols: after the defaults compiled, each numeric setting changed in turn (:func:`_changed`) must
    give the eager result. torch 2.13 kept the first value of a float that fills a tensor (``clip_ray_length``'s
    limit), so the linear march and glossy SSR (which marches it) traced the default ``max_ray_distance`` for any
    other."""
    from ssbench.passes import SSR_METHODS, ssr_method
    from tests.passes.ssr_scenes import room
    g = room(48, 36, torch.float32)
    g = dataclasses.replace(g, roughness=torch.full_like(g.roughness, 0.3))
    checked = 0
    for method in SSR_METHODS:
        fn, params_cls, _ = ssr_method(method)
        p0 = params_cls()
        changed = [c for c in (_changed(p0, f.name) for f in dataclasses.fields(p0)) if c is not None]
        for p in [p0] + changed:
            with C.compiling(False):
                eager = fn(g, p, generator=torch.Generator().manual_seed(0))
            with C.compiling(True):
                comp = fn(g, p, generator=torch.Generator().manual_seed(0))
            assert torch.equal(eager.hit, comp.hit), (method, p)
            assert torch.allclose(eager.color, comp.color, rtol=0, atol=1e-5), (method, p)
            checked += p is not p0
    assert checked >= 3 * len(SSR_METHODS)


def _changed(p, name: str):
    """``p`` with its numeric field ``name`` changed: a positive float scaled by 0.55 (1.6 where that is out of
    range), an integer halved (3 more where that is out of range); None for other fields, the seed, or when no
    change is allowed."""
    v = getattr(p, name)
    if type(v) is float and v > 0:
        candidates = (v * 0.55, v * 1.6)
    elif type(v) is int and name != "seed":
        candidates = (v // 2, v + 3)
    else:
        return None
    for c in candidates:
        try:
            return dataclasses.replace(p, **{name: c})
        except ValueError:
            pass
    return None


def test_a_static_kernel_compiles_every_signature_past_dynamos_default_of_eight():
    """Dynamo keeps 8 compilations per function and then runs it eager without a word: a sweep's ninth parameter
    set would have timed eager code as compiled."""
    from torch._dynamo.utils import counters

    @C.kernel
    def shifted(x, k):
        return x * k + 1

    with C.compiling(True):
        graphs = counters["stats"]["unique_graphs"]
        for k in range(12):                                          # 12 values of a baked-in number: 12 signatures
            assert torch.equal(shifted(torch.arange(4.0), float(k)), torch.arange(4.0) * k + 1)
        assert counters["stats"]["unique_graphs"] - graphs == 12     # each one compiled, none run eager


@pytest.mark.slow
@pytest.mark.parametrize("method, settings", [("crytek", {}), ("ssao", {}), ("gtao", {"quality": "low"}), ("vbao", {}),
                                              ("sao", {"radius": 4.0}), ("hbao", {}), ("three_gtao", {"radius": 0.5}),
                                              ("ssao", {"position_from": "view_z", "noise_channels": "r"})])
def test_compiled_ao_passes_equal_eager(method, settings):
    from ssbench.passes import ao_method
    from tests.passes.ssr_scenes import room
    g = dataclasses.replace(room(24, 18, torch.float32, slat=True), color=None)
    fn, params_cls, _ = ao_method(method)
    p = params_cls(**settings)
    with C.compiling(False):
        eager = fn(g, p, generator=torch.Generator().manual_seed(1), debug=True)
    before = C.compile_seconds()
    with C.compiling(True):
        comp = fn(g, p, generator=torch.Generator().manual_seed(1), debug=True)
    assert C.compile_seconds() > before                                 # its kernel did go through torch.compile
    assert 0 < float(eager.ao.mean()) < 1
    if method == "vbao":    # the same ulp in acos moves a sample across a sector edge now and then: one bit of one
        d = (eager.ao - comp.ao).abs()                                  # slice, 1/(N·S), in few pixels
        assert float(d.max()) <= 1.0 / (p.sector_count * p.slices) + 1e-6 and float((d > 0).float().mean()) < 0.02
        assert float((eager.debug["bits"] == comp.debug["bits"]).float().mean()) > 0.98    # the same sectors
    elif method == "sao":   # a tap whose ssR·cos lands within an ulp of an integer can truncate to the next pixel
        d = (eager.ao - comp.ao).abs()                                  # (inductor contracts to FMA): rare pixels
        assert float((d > 0).float().mean()) < 0.01 and float(d.max()) < 0.05
        assert float((eager.debug["mip_level"] != comp.debug["mip_level"]).float().mean()) < 0.01
    elif method == "hbao":  # the march unrolled (no early exit): the same AO; only atan of the horizon (a debug
        assert torch.equal(eager.ao, comp.ao)                           # buffer) may differ by an ulp in inductor
        for k, v in eager.debug.items():
            assert torch.equal(v, comp.debug[k]) if k != "horizons" else float((v - comp.debug[k]).abs().max()) <= 1e-6
    elif method == "three_gtao":   # inductor's vectorised acos and sqrt differ from ATen's by an ulp now and then
        assert float((eager.ao - comp.ao).abs().max()) <= 1e-6          # measured <= 2.4e-7 at 1920x1080
    elif method != "gtao":
        assert torch.equal(eager.ao, comp.ao)
        for k, v in eager.debug.items():
            assert not isinstance(v, torch.Tensor) or torch.equal(v, comp.debug[k]), k
    else:   # inductor's vectorised cos/acos differ from ATen's by an ulp; acos near ±1 magnifies that in the
        # normal angle (~1e-4 rad in float32), which the slice integral then smooths out again
        assert float((eager.ao - comp.ao).abs().max()) <= 1e-5            # measured <= 4.5e-6 at 1920x1080
        assert float((eager.debug["slice_visibility"] - comp.debug["slice_visibility"]).abs().max()) <= 1e-5
        assert float((eager.debug["normal_angle"] - comp.debug["normal_angle"]).abs().max()) <= 1e-3
