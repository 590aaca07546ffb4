"""The Dr.Jit references evaluate what they return in as few kernels as their algorithm needs.

Dr.Jit arrays are lazy: converting one output to torch evaluates only that output, and the next conversion runs
the whole computation behind it again (the AO truth traced its ray loop twice, once for the AO and once for its
standard error). These tests count the JIT kernels a call launches over the image (Dr.Jit's kernel history) and,
where a value left lazy is traced again inside later kernels, the ray-trace sites in each kernel's IR: counts, not
times, so they hold on any machine.
"""
import pytest

from ssbench.reference import WEIGHTINGS, ambient_occlusion, backend, gbuffer, reflections, screen_space_oracle
from ssbench.reference.glossy import GLOSSY_CHANNELS, glossy_reflections
from ssbench.reference.multibounce import multibounce_ao

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
W, H = 32, 24
CH = ("position", "normal", "mask", "view_z", "shape_id", "back_z", "second_z")


def _trace_sites(fn) -> list[int]:
    """One entry per JIT kernel of the image's size that ``fn()`` launches (after a first call that compiles
    them): the ray-tracing call sites in its LLVM IR (Dr.Jit marks each one), a static count."""
    backend.mitsuba()
    import drjit as dr
    fn()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()                                            # clears it
        fn()
        history = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    return [k["ir"].getvalue().count("-------- Ray trace") for k in history
            if k.get("type") == dr.KernelType.JIT and k.get("size") == W * H]


def _kernels(fn) -> int:
    """JIT kernels of the image's size that ``fn()`` launches."""
    return len(_trace_sites(fn))


@pytest.fixture(scope="module")
def g():
    return gbuffer("reflective_floor", W, H, channels=CH)


@pytest.mark.parametrize("weighting", WEIGHTINGS)
def test_ao_truth_and_oracle_trace_their_rays_once(g, weighting):
    assert _kernels(lambda: ambient_occlusion("reflective_floor", g, 0.5, 8, weighting, use_cache=False)) == 1
    assert _kernels(lambda: screen_space_oracle(g, 0.5, 8, weighting, use_cache=False)) == 1


def test_reflections_trace_each_sample_once(g):
    """One kernel for the mirror rays, one per radiance sample, one for the hit records (it was 3 per sample and
    one per hit record)."""
    assert _kernels(lambda: reflections("reflective_floor", g, spp=3, use_cache=False)) == 3 + 2


def test_gbuffer_renders_its_channels_in_one_kernel():
    assert _kernels(lambda: gbuffer("reflective_floor", W, H, channels=CH, use_cache=False)) == 1


def test_multibounce_converts_its_primaries_once(g):
    assert _kernels(lambda: multibounce_ao("reflective_floor", g, 0.5, 8, use_cache=False)) == 2


def test_glossy_traces_its_primary_rays_once():
    """The pixel-centre rays are traced in one kernel before the directions; each direction's kernel then holds
    only its own tracing: the scene's path integrator (as in a radiance sample of :func:`reflections`), the
    lobe ray's hit record and the camera's visibility test (it re-traced the primaries in every one)."""
    g = gbuffer("reflective_floor", W, H, channels=GLOSSY_CHANNELS + ("position", "normal", "view_z"))
    path = _trace_sites(lambda: reflections("reflective_floor", g, spp=2, use_cache=False))[1]
    sites = _trace_sites(lambda: glossy_reflections("reflective_floor", g, rays=3, use_cache=False))
    assert sites == [1] + [path + 2] * 3
