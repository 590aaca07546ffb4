"""Point-counting SSAO (hemisphere, Crytek) converges to the volume flavour it declares, not to a directional one."""
import pytest

from ssbench.evaluate import run_ao
from ssbench.passes import ao_method

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]


@pytest.mark.parametrize("method,flavour", [("ssao", "volume_hemisphere"), ("crytek", "volume_sphere")])
def test_scored_against_its_own_flavour_near_the_crease(method, flavour):
    fn = ao_method(method)[0]
    ev = run_ao("crease", method, {"kernel_size": 64}, width=160, height=120, rays=256, repeats=1, flip=False,
                warmup=False)
    assert ev.row["weighting"] == flavour
    full, orc, cos = (ev.references[k].ao for k in ("flavour", "oracle", "cos"))
    # near the crease (the directional truth sees the wall), where the depth buffer holds all the geometry
    near = ev.gbuffer.mask & (cos < 0.97) & ((orc - full).abs() < 0.02)
    assert near.sum() > 300
    err = ev.ao - full
    assert abs(float(err[near].mean())) <= 0.05, fn.__name__
    # the directional truth is a different quantity: scored against it the same output is far off
    assert abs(float((ev.ao - cos)[near].mean())) > 2 * abs(float(err[near].mean()))
