"""ssbench.passes.ao.slice_samples: the texel position buffer and the slice samples GTAO and VBAO read."""
from __future__ import annotations

import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes.ao import slice_samples as SS


def _cam(w: int = 11, h: int = 7) -> Camera:
    return Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 50.0, w, h, 0.1, 20.0)


def test_position_texture_is_the_view_position_of_each_texel_centre():
    cam = _cam()
    z = -(1.0 + torch.rand(2, 1, 7, 11, generator=torch.Generator().manual_seed(1), dtype=torch.float64) * 5)
    pos = SS.position_texture(cam, z)
    want = cam.uv_to_view(cam.uv_grid(torch.float64).unsqueeze(0), z, dim=1)     # (B, 3, H, W)
    assert pos.shape == (2, 3, 7, 11) and torch.equal(pos[:, 2:], z)
    torch.testing.assert_close(pos, want, rtol=1e-12, atol=1e-12)


def _offsets(dtype):
    g = torch.Generator().manual_seed(2)
    off_x = torch.randint(-14, 15, (2, 3, 4, 11), generator=g).to(dtype)
    off_y = torch.randint(-9, 10, (2, 3, 4, 11), generator=g).to(dtype)
    special = torch.tensor([math.nan, math.inf, -math.inf, 1e30, -1e30, -0.0, 0.0], dtype=dtype)
    off_x.view(-1)[:7], off_y.view(-1)[20:27] = special, special
    return off_x, off_y


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_slice_offsets_float_form_gives_the_bits_of_the_boolean_form(dtype, monkeypatch):
    cam = _cam()
    z = -(1.0 + torch.rand(2, 1, 7, 11, generator=torch.Generator().manual_seed(4), dtype=dtype) * 5)
    pos = SS.position_texture(cam, z)
    col = torch.arange(11, dtype=dtype).view(1, 1, 1, 11)
    row = torch.arange(2, 6, dtype=dtype).view(1, 1, 4, 1)
    P = tuple(torch.rand(2, 1, 4, 11, generator=torch.Generator().manual_seed(i), dtype=dtype) for i in range(3))
    off_x, off_y = _offsets(dtype)
    fast, on = SS.slice_offsets(cam, pos, col, row, off_x, off_y, P)
    from_depth, on_depth = SS.slice_offsets(cam, z, col, row, off_x, off_y, P)      # the compiled passes' texture
    assert torch.equal(on_depth, on) and all(torch.equal(a, b) for a, b in zip(from_depth, fast))
    monkeypatch.setattr(SS, "float_masks", lambda x: False)
    monkeypatch.setattr(SS, "inside_image", lambda x, y, w, h: (x >= 0) & (x < w) & (y >= 0) & (y < h))
    slow, on_bool = SS.slice_offsets(cam, pos, col, row, off_x, off_y, P)
    assert on.dtype == dtype and on_bool.dtype == torch.bool and torch.equal(on, on_bool.to(dtype))
    assert 0 < int(on_bool.sum()) < on_bool.numel()
    for a, b in zip(fast, slow):
        assert torch.equal(a, b)
    # a sample off the screen (or at a non-finite offset) reads the pixel's own texel
    own = [(pos[:, i:i + 1, 2:6] - P[i]).expand_as(a) for i, a in enumerate(slow)]
    for a, b in zip(slow, own):
        assert torch.equal(a[~on_bool], b[~on_bool])


def test_sample_texture_is_the_depth_alone_when_compiled_or_with_gradients():
    cam, z = _cam(), -torch.ones(1, 1, 7, 11)
    from ssbench.passes import compiled
    with torch.no_grad():
        assert SS.sample_texture(cam, z).shape == (1, 3, 7, 11)
        with compiled.compiling(True):
            assert SS.sample_texture(cam, z) is z
    assert torch.is_grad_enabled() and SS.sample_texture(cam, z) is z
