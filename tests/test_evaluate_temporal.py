"""Frames of an AO method on a static scene: the noise advances as the method does it, the camera jitters."""
import pytest
import torch

from ssbench.evaluate import ao_frames
from ssbench.evaluate._temporal import halton
from ssbench.passes.ao.gtao import GTAOParams
from ssbench.passes.ao.gtao_parts import noise_buffer

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
KW = dict(width=48, height=36, radius=1.0, frames=4)


def test_frozen_noise_and_no_jitter_do_not_flicker_and_each_source_adds():
    frozen = ao_frames("sphere_on_plane", "ssao", jitter=False, advance_noise=False, **KW)
    assert frozen.flicker == 0.0 and frozen.offsets == ((0.0, 0.0),) * 4
    assert torch.equal(frozen.ao[0], frozen.ao[3])
    noise = ao_frames("sphere_on_plane", "ssao", jitter=False, **KW)
    jitter = ao_frames("sphere_on_plane", "ssao", advance_noise=False, **KW)
    assert noise.flicker > 0 and jitter.flicker > 0
    assert jitter.offsets[0] == (halton(1, 2) - 0.5, halton(1, 3) - 0.5) == pytest.approx((0.0, -1 / 6))
    assert not torch.equal(jitter.mask[0], jitter.mask[1]) or not torch.equal(jitter.ao[0], jitter.ao[1])


def test_gtao_advances_its_hilbert_noise_by_the_frame_index():
    a, b = (noise_buffer(GTAOParams(frame=f), 1, 8, 8) for f in (0, 1))
    assert not torch.equal(a, b)
    assert torch.equal(noise_buffer(GTAOParams(frame=64), 1, 8, 8), a)   # XeGTAO: 288 (frame mod 64)
    run = ao_frames("sphere_on_plane", "gtao", jitter=False, **KW)
    assert run.flicker > 0 and run.params.frame == 0
    with pytest.raises(ValueError, match="frame"):
        GTAOParams(frame=-1)


def test_arguments_are_checked():
    with pytest.raises(ValueError, match="frames"):
        ao_frames("sphere_on_plane", "ssao", frames=1)
    with pytest.raises(ValueError, match="seed"):
        ao_frames("sphere_on_plane", "ssao", seed=-1)


def test_accumulation_cuts_flicker():
    """A still scene with advancing noise and sub-pixel jitter: the temporal resolve (reprojection, rejection,
    clamp, blend) flickers less than the raw frames over the AO methods, and makes none much worse (VBAO, whose
    raw flicker is low and comes mostly from the jitter at edges, can come out slightly above its raw flicker:
    the report's time section shows it)."""
    from ssbench.passes import AO_METHODS
    from ssbench.passes.temporal import AccumulationParams
    raw, acc = [], []
    for method in AO_METHODS:
        run = ao_frames("stairs", method, accumulation=AccumulationParams(), **{**KW, "frames": 8})
        raw.append(run.flicker)
        acc.append(run.flicker_accumulated)
        assert run.flicker_accumulated < 1.25 * run.flicker, (method, run.flicker, run.flicker_accumulated)
        assert run.accumulated.shape == run.ao.shape and bool(run.history_valid[1:].any())
        assert not bool(run.history_valid[0].any())                       # frame 0 has no history
    assert sum(acc) < 0.8 * sum(raw), (raw, acc)
    for name in ("ssao", "hbao"):                                            # noise-driven flicker: roughly halved
        i = list(AO_METHODS).index(name)
        assert acc[i] < 0.75 * raw[i], (name, raw[i], acc[i])


def test_ghosting_responds_to_a_resolve_that_keeps_stale_history():
    """The calibration of ghosting: on an orbiting camera, loosening the resolve (no clamp, a 10× depth
    tolerance, half the blend weight) must raise the error it adds over the raw frames."""
    from ssbench.passes.temporal import AccumulationParams
    kw = {**KW, "frames": 8, "radius": 0.5, "orbit_deg": 2.0, "truth_rays": 32}
    tight = ao_frames("stairs", "ssao", accumulation=AccumulationParams(), **kw)
    loose = ao_frames("stairs", "ssao", accumulation=AccumulationParams(alpha=0.05, clamp="none",
                                                                         depth_tolerance=10.0), **kw)
    assert loose.ghosting > tight.ghosting + 0.001, (tight.ghosting, loose.ghosting)
    assert tight.cameras[0].eye != tight.cameras[1].eye
    with pytest.raises(ValueError, match="truth_rays"):
        ao_frames("stairs", "ssao", truth_rays=8, **KW)
