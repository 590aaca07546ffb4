"""Frames of an AO method on a static scene: the noise advances as the method does it, the camera jitters."""
import math

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


def test_a_moving_object_leaves_a_trail_the_clamp_and_its_motion_vectors_shorten():
    """The ball of ``sphere_on_plane`` slides 0.15 per frame under a still camera: its contact shadow moves over
    the static floor (history the depth test trusts) and its own pixels move. Near the ball, the resolve's added
    error must fall with the clamp and, at each clamp setting, with the ball's motion vectors (which also keep
    more history: the ball's pixels reproject onto the ball)."""
    from ssbench.passes.temporal import AccumulationParams
    from ssbench.scenes.motion import Motion
    m = Motion("ball", (0.15, 0.0, 0.0))
    kw = {**KW, "width": 96, "height": 72, "frames": 8, "radius": 0.5, "truth_rays": 32, "moving": m}
    runs = {(clamp, mv): ao_frames("sphere_on_plane", "gtao", accumulation=AccumulationParams(clamp=clamp),
                                    motion_vectors=mv, **kw)
            for clamp in ("minmax", "none") for mv in (True, False)}
    g = {k: r.ghosting_moving for k, r in runs.items()}
    assert g[("none", True)] > 1.5 * g[("minmax", True)] > 0, g
    assert g[("none", False)] > g[("none", True)] and g[("minmax", False)] > g[("minmax", True)], g
    kept = {mv: float(runs[("minmax", mv)].history_valid[1:].float().mean()) for mv in (True, False)}
    assert kept[True] > kept[False] + 0.01, kept
    still = ao_frames("sphere_on_plane", "gtao", accumulation=AccumulationParams(), truth_rays=2, **KW)
    assert math.isnan(still.ghosting_moving) and not math.isnan(still.ghosting)   # no moving object: NaN
    with pytest.raises(ValueError, match="shape"):
        ao_frames("sphere_on_plane", "gtao", moving=Motion("nothing", (0.1, 0, 0)), **KW)
    with pytest.raises(TypeError, match="moving"):
        ao_frames("sphere_on_plane", "gtao", moving=("ball", (0.1, 0, 0)), **KW)
