"""Hemisphere SSAO against three.js ``SSAOShader`` itself, run in headless Chromium (WebGL2, SwiftShader) on the
same G-buffer, kernel and noise: equal on every valid pixel, with a control that must fail (no row flip) and the
measured effect of each difference by design."""
import dataclasses

import pytest
import torch

from ssbench.passes.ao.ssao import HemisphereSSAOParams, hemisphere_ssao
from ssbench.peer import available
from ssbench.reference import gbuffer
from ssbench.scenes import catalog

pytestmark = [pytest.mark.slow, pytest.mark.skipif(available() is not None, reason=str(available())),
              pytest.mark.usefixtures("three_installed")]
SCENES = ("crease", "cornell_box", "stairs", "furnished_room")


@pytest.fixture(scope="module")
def gbuffers():
    return {name: gbuffer(catalog.get(name), 96, 72) for name in SCENES}


def shares(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor) -> tuple[float, float]:
    d = (a - b).abs()[mask]
    return float((d < 1e-6).float().mean()), float(d.mean())


@pytest.mark.parametrize("scene", SCENES)
@pytest.mark.parametrize("article_noise", [False, True], ids=["shipped_r", "article_xyz"])
def test_shader_equals_the_pass_on_every_valid_pixel(gbuffers, scene, article_noise):
    from ssbench.peer.ssao import three_ssao
    g = gbuffers[scene]
    for k in (16, 32):
        shader, ours = three_ssao(g, HemisphereSSAOParams(kernel_size=k), article_noise=article_noise)
        equal, mean = shares(shader, ours, g.mask)
        assert equal == 1.0 and mean == 0.0, (scene, k, equal, mean)
        assert torch.equal(shader[~g.mask], torch.ones_like(shader[~g.mask]))        # background: vec4(1.0)


def test_control_without_the_row_flip_fails(gbuffers):
    from ssbench.peer.ssao import three_ssao
    for scene in SCENES:
        g = gbuffers[scene]
        shader, ours = three_ssao(g, HemisphereSSAOParams(), flip_rows=False)
        equal, mean = shares(shader, ours, g.mask)
        assert equal < 0.7 and mean > 0.05, (scene, equal, mean)


def test_the_noise_read_is_a_difference_that_matters(gbuffers):
    """three.js's vec3(noise.r) against the article's .xyz: the shipped shader is *not* the article's pass."""
    from ssbench.peer.ssao import three_ssao
    for scene in ("cornell_box", "stairs"):
        g = gbuffers[scene]
        shader, _ = three_ssao(g, HemisphereSSAOParams())
        article = hemisphere_ssao(g, dataclasses.replace(HemisphereSSAOParams(), noise_channels="xyz")).ao
        equal, mean = shares(shader, article, g.mask)
        assert equal < 0.9 and mean > 0.005, (scene, equal, mean)


def test_settings_the_shader_cannot_express_are_refused(gbuffers):
    from ssbench.peer.ssao import three_ssao
    for bad, name in ((HemisphereSSAOParams(noise_size=8), "noise_size"), (HemisphereSSAOParams(strength=2.0),
                      "strength"), (HemisphereSSAOParams(position_from="view_z"), "position_from")):
        with pytest.raises(ValueError, match=name):
            three_ssao(gbuffers["crease"], bad)
