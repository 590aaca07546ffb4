"""The linear march's step with 0/1 float flags against its int32 form, bit for bit, on working sets built to hit
every branch: hits, misses, rays leaving the screen (NaN and infinite projections too), rays already stopped (hit or
off screen) whose samples hold signed zeros, back faces; and the pass's outputs with either form."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.passes.ssr import linear_march
from ssbench.passes.ssr.linear import LinearSSRParams, ssr_linear
from ssbench.passes.ssr.linear_float_step import float_march_step
from ssbench.passes.ssr.linear_march import march_step

H, W = 6, 8


def bits(x: torch.Tensor) -> torch.Tensor:
    """The integers of a float tensor's bits (so that −0 ≠ +0 and NaN payloads count)."""
    return x.contiguous().view(torch.int32 if x.dtype == torch.float32 else torch.int64)


def working_set(dtype: torch.dtype, n: int = 4000, seed: int = 0) -> tuple:
    """``(qx, qy, qz, dx, dy, dz, base, live, hit, steps)`` with int32 flags: random rays around a depth buffer of two
    images, a tenth of them stopped (half of those on a hit), signed zeros and non-finite samples sprinkled in."""
    g = torch.Generator().manual_seed(seed)
    q = torch.randn(3, n, generator=g, dtype=torch.float64) * torch.tensor([[1.5], [1.0], [0.5]], dtype=torch.float64)
    q[2] -= 2.0
    d = torch.randn(3, n, generator=g, dtype=torch.float64) * 0.2
    q, d = q.to(dtype), d.to(dtype)
    k = torch.arange(n)
    q[0, k % 37 == 0], d[0, k % 37 == 0] = -0.0, -0.0          # Q.x + deltaStep.x = −0
    q[1, k % 41 == 0], d[1, k % 41 == 0] = 0.0, -0.0
    d[2, k % 43 == 0] = 0.0
    q[0, k % 53 == 0] = math.nan                                 # a NaN projection: off screen
    q[1, k % 59 == 0] = math.inf
    q[2, k % 61 == 0] = 0.0                                      # on the camera plane
    live = (torch.rand(n, generator=g) > 0.1).to(torch.int32)
    hit = ((live == 0) & (torch.rand(n, generator=g) > 0.5)).to(torch.int32)
    steps = torch.randint(0, 30, (n,), generator=g, dtype=torch.int32)
    base = (torch.rand(n, generator=g) > 0.5).to(torch.int32) * (H * W)
    return (*q, *d, base, live, hit, steps)


def depth(dtype: torch.dtype, seed: int = 1) -> tuple[torch.Tensor, torch.Tensor]:
    """``(front, back)``: flat scene z of two images (NaN off a mask) and back faces behind them."""
    g = torch.Generator().manual_seed(seed)
    front = (-2.0 - torch.rand(2 * H * W, generator=g, dtype=torch.float64)).to(dtype)
    front[torch.rand(2 * H * W, generator=g) < 0.2] = math.nan
    return front, front - 0.3


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("with_back", [False, True])
def test_float_step_equals_int32_step(dtype, with_back):
    front, back = depth(dtype)
    back = back if with_back else None
    rays = working_set(dtype)
    floats = rays[:6] + tuple(r.to(dtype) for r in rays[6:])
    for _ in range(3):                                           # three steps: stopped rays ride along
        ri, ti, oni, hi = march_step((1.2, 1.7), (H, W), 0.4, front, back, rays)
        rf, tf, onf, hf = float_march_step((1.2, 1.7), (H, W), 0.4, front, back, floats)
        for a, b in zip(ri[:6], rf[:6]):                         # Q (and deltaStep): the same bits
            assert torch.equal(bits(a), bits(b))
        for a, b in zip(ri[7:], rf[7:]):                         # live, hit, steps: the same numbers
            assert torch.equal(a.to(torch.float64), b.to(torch.float64))
        assert torch.equal(oni, onf != 0) and torch.equal(hi, hf != 0)
        assert torch.equal(ti[oni].long(), tf[oni].long())       # the texel of every on-screen sample
        rays, floats = ri, rf
    assert int(rays[8].sum()) > 0 and int((rays[7] == 0).sum()) > 400       # hits and stops happened


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_pass_outputs_equal_with_int32_flags(monkeypatch, dtype):
    """The whole pass (debug buffers, a traced pixel, back faces, jitter) with float flags and with int32 ones."""
    from tests.passes.ssr.test_linear import scene
    g = scene(w=40, h=30, walls=((-3.0, 0.5, None), (-6.0, 1.0, 1.5)), dtype=dtype)
    for params in (LinearSSRParams(), LinearSSRParams(iterations=9, thickness=0.1, jitter=1.0),
                   LinearSSRParams(use_back_face_depth=True, binary_search_iterations=0)):
        kw = dict(generator=torch.Generator().manual_seed(3), debug=True, trace_pixel=(20, 25))
        a = ssr_linear(g, params, **kw)
        monkeypatch.setattr(linear_march, "float_flags", lambda *_: False)
        kw["generator"] = torch.Generator().manual_seed(3)
        b = ssr_linear(g, params, **kw)
        monkeypatch.undo()
        for name in ("color", "hit", "hit_pixel", "hit_view", "steps", "termination", "fade", "raw_color"):
            x, y = getattr(a, name), getattr(b, name)
            assert torch.equal(bits(x) if x.is_floating_point() else x, bits(y) if y.is_floating_point() else y), name
        assert torch.equal(a.debug["visits"], b.debug["visits"])
        ta, tb = a.debug["trace"][0], b.debug["trace"][0]
        assert ta["hit"].numel() >= 2 and all(torch.equal(ta[k], tb[k]) for k in ta)
