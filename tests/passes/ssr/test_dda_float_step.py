"""The DDA's step with 0/1 float flags against its int32 form, bit for bit: on every step of marches through the
analytic room (strided footprints cut short at the segment's end, rays leaving the screen, hits, back faces, the second
depth layer), on a step whose footprint share is NaN, and the pass's outputs with either form."""
from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from ssbench.passes.ssr import dda_march
from ssbench.passes.ssr.common import HIT, MAX_DISTANCE, OFF_SCREEN
from ssbench.passes.ssr.dda import DDASSRParams, ssr_dda
from ssbench.passes.ssr.dda_float_step import float_dda_step
from tests.passes.ssr_scenes import room, with_second_layer

PARAMS = (DDASSRParams(), DDASSRParams(pixel_stride=3.5, jitter=1.0, max_ray_distance=6.0),
          DDASSRParams(use_back_face_depth=True, use_second_layer=True, pixel_stride=2.0, z_thickness=0.05),
          DDASSRParams(refinement="remarch", pixel_stride=4.0, max_steps=12))


def bits(x: torch.Tensor) -> torch.Tensor:
    """The integers of a float tensor's bits (−0 ≠ +0, NaN payloads count); other tensors as they are."""
    if not x.is_floating_point():
        return x
    return x.contiguous().view(torch.int32 if x.dtype == torch.float32 else torch.int64)


def as_floats(state, ray):
    """The int32 form's state and ray with their flags, counts, codes and batch index in the samples' dtype."""
    f = state.prevZ.dtype
    return (state._replace(alive32=state.alive32.to(f), steps=state.steps.to(f), term=state.term.to(f)),
            ray._replace(clipped32=ray.clipped32.to(f), b_index=ray.b_index.to(f)))


def assert_same_step(old: tuple, new: tuple) -> None:
    (s0, done0, t0, live0), (s1, done1, t1, live1) = old, new
    for name in s0._fields[:-3]:                                                 # the samples' fields
        assert torch.equal(bits(getattr(s0, name)), bits(getattr(s1, name))), name
    for name in ("alive32", "steps", "term"):
        assert torch.equal(getattr(s0, name).double(), getattr(s1, name).double()), name
    assert torch.equal(done0, done1 != 0) and torch.equal(live0, live1 != 0) and torch.equal(t0.long(), t1.long())


def scene(dtype: torch.dtype):
    """The room with a thin bar, its second depth layer and back faces 0.3 behind every surface."""
    g = with_second_layer(room(40, 30, dtype=dtype, slat=True))
    return dataclasses.replace(g, back_z=torch.where(g.mask, g.view_z - 0.3, -math.inf))


class Stop(Exception):
    """Raised to end a march at its first step."""


def run(g, p, **kwargs):
    """The DDA on ``g`` with parameters ``p``, its jitter seeded."""
    return ssr_dda(g, p, generator=torch.Generator().manual_seed(2), **kwargs)


def first_step(monkeypatch, g) -> tuple:
    """The arguments of the int32 march's first step (the march ended there)."""
    captured = []

    def first(*args, **kwargs):
        captured.append(args)
        raise Stop
    monkeypatch.setattr(dda_march, "float_flags", lambda *_: False)
    monkeypatch.setattr(dda_march, "dda_step", first)
    with pytest.raises(Stop):
        run(g, PARAMS[0])
    monkeypatch.undo()
    return captured[0][:5]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_float_step_equals_int32_step_on_every_step(monkeypatch, dtype):
    int_step, seen = dda_march.dda_step, {"steps": 0, HIT: 0, OFF_SCREEN: 0, MAX_DISTANCE: 0}

    def both(state, ray, tex, size, z_thickness, go=None):
        old = int_step(state, ray, tex, size, z_thickness, go)
        assert_same_step(old, float_dda_step(*as_floats(state, ray), tex, size, z_thickness))
        seen["steps"] += 1
        for code in (HIT, OFF_SCREEN, MAX_DISTANCE):
            seen[code] += int((old[1] & (old[0].term == code)).sum())
        return old
    monkeypatch.setattr(dda_march, "float_flags", lambda *_: False)             # the int32 march drives
    monkeypatch.setattr(dda_march, "dda_step", both)
    for p in PARAMS:
        run(scene(dtype), p)
    assert seen["steps"] > 40 and min(seen.values()) > 0                       # every ending happened


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_pass_outputs_equal_with_int32_flags(monkeypatch, dtype):
    for p in PARAMS:
        a = run(scene(dtype), p, debug=True)
        monkeypatch.setattr(dda_march, "float_flags", lambda *_: False)
        b = run(scene(dtype), p, debug=True)
        monkeypatch.undo()
        for name in ("color", "hit", "hit_pixel", "hit_view", "steps", "termination", "fade", "raw_color"):
            assert torch.equal(bits(getattr(a, name)), bits(getattr(b, name))), name
        assert all(torch.equal(bits(v), bits(b.debug[k])) for k, v in a.debug.items() if isinstance(v, torch.Tensor))
        assert bool(a.hit.any())


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_float_step_keeps_a_nan_footprint_share_out(monkeypatch, dtype):
    """``f = (stop − u) / stride + ½`` is NaN where ``stop`` and ``stride`` are infinite: not a partial footprint,
    ``back = 0`` and ``half = ½`` in both forms."""
    state, ray, tex, size, z_thickness = first_step(monkeypatch, room(24, 18, dtype=dtype))
    rows = torch.arange(state.Px.numel()) % 5 == 0
    ray = ray._replace(stride=torch.where(rows, math.inf, ray.stride), stop=torch.where(rows, math.inf, ray.stop))
    old = dda_march.dda_step(state, ray, tex, size, z_thickness)
    assert_same_step(old, float_dda_step(*as_floats(state, ray), tex, size, z_thickness))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_float_step_reads_a_texel_for_nan_samples(monkeypatch, dtype):
    """A NaN sample (degenerate input) is off screen and reads some texel in range, never an index out of range."""
    state, ray, tex, size, z_thickness = first_step(monkeypatch, room(24, 18, dtype=dtype))
    rows = torch.arange(state.Px.numel())
    state = state._replace(Px=torch.where(rows % 4 == 0, math.nan, state.Px),
                           Py=torch.where(rows % 4 == 1, math.nan, state.Py))
    new, done, t, live = float_dda_step(*as_floats(state, ray), tex, size, z_thickness)
    bad = (rows % 4 == 0) | (rows % 4 == 1)
    assert bool((t >= 0).all()) and bool((t < tex[0].numel()).all())
    assert bool((live[bad] == 0).all()) and bool((done[bad] == 1).all()) and bool((new.term[bad] == OFF_SCREEN).all())
