"""SSR fades (SSR article §1.4 screen edge, §1.5 distance): closed-form values."""
from __future__ import annotations

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes.ssr.fade import distance_fade, edge_fade

W, H = 16, 12


def at(*uv):
    """(1, 2, N) pixel coordinates of uv points (v up)."""
    t = torch.tensor(uv, dtype=torch.float64)
    return torch.stack([t[:, 0] * W, (1 - t[:, 1]) * H])[None]


def test_circular_closed_form():
    f = edge_fade(at((0.5, 0.5), (0.75, 0.5), (0.5, 0.25), (0.0, 0.5), (0.5, 1.0), (1.0, 1.0), (0.6, 0.7)),
                  W, H, mode="circular").flatten()
    r2 = 0.1 ** 2 + 0.2 ** 2
    expect = torch.tensor([1.0, 0.75, 0.75, 0.0, 0.0, 0.0, 1 - 4 * r2], dtype=torch.float64)
    assert torch.allclose(f, expect, atol=1e-12)


@pytest.mark.parametrize("ed,ee", [(16.0, 1.0), (8.0, 1.0), (8.0, 2.0), (50.0, 1.0), (15.0, 0.25)])
def test_vignette_closed_form(ed, ee):
    f = edge_fade(at((0.5, 0.5), (0.25, 0.5), (0.0, 0.3), (0.7, 1.0), (1.0, 0.0)), W, H, ed, ee).flatten()
    centre = min((ed / 16) ** ee, 1.0)
    quarter = min((0.1875 * 0.25 * ed) ** ee, 1.0)
    assert torch.allclose(f, torch.tensor([centre, quarter, 0.0, 0.0, 0.0], dtype=torch.float64), atol=1e-12)


def test_edge_fade_shapes_symmetry_and_range():
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, W, H, 0.1, 10.0)
    px = cam.pixel_centers(torch.float64)[None].expand(2, -1, -1, -1)          # (2, 2, H, W)
    for mode in ("circular", "vignette"):
        f = edge_fade(px, W, H, mode=mode, edge_distance=20.0, edge_exponent=0.5)
        assert f.shape == (2, 1, H, W) and bool(((f >= 0) & (f <= 1)).all())
        assert torch.allclose(f, f.flip(-1)) and torch.allclose(f, f.flip(-2))   # symmetric about the centre
        flat = edge_fade(px[0].reshape(2, -1).T, W, H, mode=mode, edge_distance=20.0, edge_exponent=0.5, dim=-1)
        assert flat.shape == (H * W, 1) and torch.allclose(flat[:, 0], f[0, 0].reshape(-1))
    assert edge_fade(px.float(), W, H).dtype == torch.float32


def test_distance_fade_closed_form():
    d = torch.tensor([0.0, 2.5, 5.0, 10.0, 30.0], dtype=torch.float64)
    assert distance_fade(d, 10.0, 1.0).tolist() == [1.0, 0.75, 0.5, 0.0, 0.0]
    assert torch.allclose(distance_fade(d, 10.0, 2.0), torch.tensor([1.0, 0.9375, 0.75, 0.0, 0.0], dtype=torch.float64))
    assert distance_fade(d.view(1, 1, 1, 5), 10.0).shape == (1, 1, 1, 5)


@pytest.mark.parametrize("call,name", [
    (lambda: edge_fade(at((0.5, 0.5)), W, H, mode="box"), "mode"),
    (lambda: edge_fade(at((0.5, 0.5)), 0, H), "width"),
    (lambda: edge_fade(at((0.5, 0.5)), W, 2.5), "height"),
    (lambda: edge_fade(torch.zeros(1, 3, 4), W, H), "hit_pixel"),
    (lambda: edge_fade(at((0.5, 0.5)), W, H, edge_distance=-1.0), "edge_distance"),
    (lambda: edge_fade(at((0.5, 0.5)), W, H, edge_exponent=0.0), "edge_exponent"),
    (lambda: distance_fade(torch.ones(3), 0.0), "fade_distance"),
    (lambda: distance_fade(torch.ones(3), 1.0, -2.0), "fade_exponent"),
    (lambda: distance_fade(torch.ones(3), float("nan")), "fade_distance"),
])
def test_bad_arguments(call, name):
    with pytest.raises(ValueError, match=name):
        call()
