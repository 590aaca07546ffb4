"""three.js ``GTAOShader`` itself, run in headless Chromium, against ``three_gtao`` (its torch transliteration):
equal to float rounding on every valid pixel, a control that must fail, and the measured distance to ``gtao``
(Jimenez et al.'s screen-space slices, a different method by design)."""
import pytest

from ssbench.passes.ao.gtao import GTAOParams, gtao
from ssbench.passes.ao.three_gtao import ThreeGTAOParams, three_gtao
from ssbench.peer import available
from ssbench.reference import gbuffer
from ssbench.scenes import catalog

pytestmark = [pytest.mark.slow, pytest.mark.skipif(available() is not None, reason=str(available())),
              pytest.mark.usefixtures("three_installed")]
SCENES = ("crease", "cornell_box", "stairs", "furnished_room")
SETTINGS = [ThreeGTAOParams(radius=0.5), ThreeGTAOParams(radius=0.5, samples=32, distance_fall_off=0.0),
            ThreeGTAOParams(radius=1.0, thickness=0.3, distance_exponent=2.0, scale=1.5)]
#: float32 rounding (acos, normalize, the GPU's matrix products): the largest |Δ| seen was 3.3e-5
TOL = 1e-4


@pytest.fixture(scope="module")
def gbuffers():
    return {name: gbuffer(catalog.get(name), 96, 72) for name in SCENES}


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("setting", range(len(SETTINGS)))
def test_shader_equals_the_pass_on_every_valid_pixel(gbuffers, scene, setting):
    from ssbench.peer.gtao import three_gtao_shader
    g = gbuffers[scene]
    shader, ours = three_gtao_shader(g, SETTINGS[setting])
    d = (shader - ours).abs()[g.mask]
    assert float(d.max()) < TOL, (scene, float(d.max()))
    assert float((ours[g.mask] < 0.99).float().mean()) > 0.02            # the comparison covers occluded pixels


def test_control_without_the_row_flip_fails(gbuffers):
    from ssbench.peer.gtao import three_gtao_shader
    for scene in ("cornell_box", "stairs", "furnished_room"):
        g = gbuffers[scene]
        shader, ours = three_gtao_shader(g, SETTINGS[0], flip_rows=False)
        d = (shader - ours).abs()[g.mask]
        assert float((d < TOL).float().mean()) < 0.9 and float(d.mean()) > 0.01, scene


def test_the_article_gtao_is_a_different_method(gbuffers):
    g = gbuffers["cornell_box"]
    a = three_gtao(g, ThreeGTAOParams(radius=0.5)).ao[g.mask]
    b = gtao(g, GTAOParams(radius=0.5)).ao[g.mask]
    assert float((a - b).abs().mean()) > 0.01
