"""The Dr.Jit references evaluate what they return in as few kernels as their algorithm needs.

Dr.Jit arrays are lazy: converting one output to torch evaluates only that output, and the next conversion runs
the whole computation behind it again (the AO truth traced its ray loop twice, once for the AO and once for its
standard error). These tests count the JIT kernels a call launches over the image (Dr.Jit's kernel history), a
count, not a time, so they hold on any machine.
"""
import pytest

from ssbench.reference import WEIGHTINGS, ambient_occlusion, backend, gbuffer, reflections, screen_space_oracle
from ssbench.reference.multibounce import multibounce_ao

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
W, H = 32, 24
CH = ("position", "normal", "mask", "view_z", "shape_id", "back_z", "second_z")


def _kernels(fn) -> int:
    """JIT kernels of the image's size that ``fn()`` launches (after a first call that compiles them)."""
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
    return sum(1 for k in history if k.get("type") == dr.KernelType.JIT and k.get("size") == W * H)


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
