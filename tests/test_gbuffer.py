"""The GBuffer dataclass: validation, derived depth, dtype moves, select and cat."""
from __future__ import annotations

import dataclasses

import pytest
import torch

from ssbench import checks
from ssbench.camera import Camera
from ssbench.gbuffer import CHANNELS, FILL, GBuffer, field_names

CAM = Camera.from_look_at((0, 2, 6), (0, 0.6, 0), (0, 1, 0), 45.0, 5, 4, 0.1, 100.0)
H, W = CAM.height, CAM.width


def channel(name: str, b: int = 1, h: int = H, w: int = W, c: int | None = None) -> torch.Tensor:
    c = CHANNELS[name] if c is None else c
    g = torch.Generator().manual_seed(list(CHANNELS).index(name))
    if name == "mask":
        return torch.rand(b, c, h, w, generator=g) > 0.3
    if name == "shape_id":
        return torch.randint(-1, 3, (b, c, h, w), generator=g, dtype=torch.int32)
    if name in ("view_z", "back_z"):
        return -(0.5 + 5 * torch.rand(b, c, h, w, generator=g))
    return torch.rand(b, c, h, w, generator=g)


def full(b: int = 1, cam: Camera = CAM) -> GBuffer:
    return GBuffer(cam, **{n: channel(n, b, cam.height, cam.width) for n in CHANNELS})


def test_full_gbuffer_constructs():
    g = full(2)
    assert g.channels == tuple(CHANNELS)
    assert g.batch_size == 2 and (g.height, g.width) == (H, W)
    assert set(g.as_dict()) == set(CHANNELS)
    assert field_names() == ["camera", *CHANNELS]
    assert set(FILL) == set(CHANNELS)
    empty = GBuffer(CAM)
    assert empty.channels == () and empty.batch_size == 0


@pytest.mark.parametrize("name", list(CHANNELS))
def test_wrong_channel_count_names_channel(name):
    wrong = CHANNELS[name] + 1
    with pytest.raises(ValueError) as info:
        GBuffer(CAM, **{name: channel(name, c=wrong)})
    msg = str(info.value)
    assert msg.startswith(f"{name}:") and str(CHANNELS[name]) in msg and str(wrong) in msg


@pytest.mark.parametrize("name", ["view_z", "normal", "mask", "shape_id"])
@pytest.mark.parametrize("hw", [(H + 1, W), (H, W - 1), (W, H)])
def test_wrong_image_size_names_channel(name, hw):
    with pytest.raises(ValueError, match=f"^{name}:"):
        GBuffer(CAM, **{name: channel(name, h=hw[0], w=hw[1])})


def test_wrong_rank_names_channel():
    with pytest.raises(ValueError, match="^normal:"):
        GBuffer(CAM, normal=torch.zeros(3, H, W))


def test_mismatched_batch_names_channel():
    with pytest.raises(ValueError, match="^normal:.*batch"):
        GBuffer(CAM, view_z=channel("view_z", b=1), normal=channel("normal", b=2))
    with pytest.raises(ValueError, match="^mask:"):
        GBuffer(CAM, view_z=channel("view_z", b=3), normal=channel("normal", b=3), mask=channel("mask", b=2))


def test_dtype_errors_name_channel():
    with pytest.raises(TypeError, match="^mask:"):
        GBuffer(CAM, mask=torch.ones(1, 1, H, W))
    with pytest.raises(TypeError, match="^mask:"):
        GBuffer(CAM, mask=torch.ones(1, 1, H, W, dtype=torch.uint8))
    with pytest.raises(TypeError, match="^shape_id:"):
        GBuffer(CAM, shape_id=torch.zeros(1, 1, H, W))
    with pytest.raises(TypeError, match="^shape_id:"):
        GBuffer(CAM, shape_id=torch.zeros(1, 1, H, W, dtype=torch.bool))
    with pytest.raises(TypeError, match="^view_z:"):
        GBuffer(CAM, view_z=torch.zeros(1, 1, H, W, dtype=torch.int64))
    with pytest.raises(TypeError, match="^camera:"):
        GBuffer("not a camera", view_z=channel("view_z"))                 # type: ignore[arg-type]
    GBuffer(CAM, shape_id=torch.zeros(1, 1, H, W, dtype=torch.int64))     # any integer dtype is fine


def test_checks_can_be_disabled():
    bad = dict(normal=torch.zeros(1, 2, H, W), mask=torch.ones(1, 1, H, W), view_z=torch.zeros(3, 1, H + 1, W))
    with pytest.raises(ValueError):
        GBuffer(CAM, **bad)
    with checks.checks_disabled():
        g = GBuffer(CAM, **bad)
    assert g.normal.shape == (1, 2, H, W)
    with pytest.raises(ValueError):                                       # back on after the block
        GBuffer(CAM, **bad)


def test_require_names_missing_channels():
    g = GBuffer(CAM, view_z=channel("view_z"), mask=channel("mask"))
    g.require("view_z", "mask")
    with pytest.raises(ValueError) as info:
        g.require("view_z", "normal", "albedo")
    msg = str(info.value)
    assert "normal" in msg and "albedo" in msg and "view_z" not in msg.split("channels=")[0]


def test_depth_properties():
    z = channel("view_z")
    z[0, 0, 0, 0] = -CAM.far                                              # background fill
    z[0, 0, 0, 1] = -CAM.near
    g = GBuffer(CAM, view_z=z)
    n, f = CAM.near, CAM.far
    torch.testing.assert_close(g.depth, (f * (z + n)) / ((f - n) * z))
    torch.testing.assert_close(g.linear_depth, (z + n) / (n - f))
    assert g.depth[0, 0, 0, 0].item() == pytest.approx(1.0, abs=1e-6)
    assert g.depth[0, 0, 0, 1].item() == pytest.approx(0.0, abs=1e-6)
    assert g.linear_depth[0, 0, 0, 0].item() == pytest.approx(1.0, abs=1e-6)
    with pytest.raises(ValueError, match="view_z"):
        GBuffer(CAM, normal=channel("normal")).depth
    with pytest.raises(ValueError, match="view_z"):
        GBuffer(CAM, normal=channel("normal")).linear_depth


def test_to_float64_keeps_mask_and_ids():
    g = full(2)
    g64 = g.to(dtype=torch.float64)
    assert g64.mask.dtype == torch.bool and torch.equal(g64.mask, g.mask)
    assert g64.shape_id.dtype == torch.int32 and torch.equal(g64.shape_id, g.shape_id)
    for n in CHANNELS:
        if n not in ("mask", "shape_id"):
            assert getattr(g64, n).dtype == torch.float64
            torch.testing.assert_close(getattr(g64, n), getattr(g, n).double())
    assert g64.camera == g.camera
    assert g.view_z.dtype == torch.float32                                 # the original is untouched
    g_same = g.to("cpu")
    assert g_same.view_z.dtype == torch.float32 and g_same.view_z.device.type == "cpu"


def test_select():
    g = full()
    s = g.select(["view_z", "mask"])
    assert s.channels == ("view_z", "mask")
    assert s.view_z is g.view_z and s.normal is None
    with pytest.raises(ValueError, match="^channels:.*bogus"):
        g.select(["view_z", "bogus"])
    with pytest.raises(ValueError, match="normal"):
        s.select(["normal"])


def test_cat():
    a, b = full(1), full(2)
    c = GBuffer.cat([a, b])
    assert c.batch_size == 3 and c.channels == a.channels
    for n in CHANNELS:
        torch.testing.assert_close(getattr(c, n), torch.cat([getattr(a, n), getattr(b, n)]))
    assert c.mask.dtype == torch.bool and c.shape_id.dtype == torch.int32


def test_cat_errors():
    a = full(1)
    other = Camera.from_look_at((0, 2, 7), (0, 0.6, 0), (0, 1, 0), 45.0, 5, 4, 0.1, 100.0)
    with pytest.raises(ValueError, match=r"^items\[1\]:.*camera"):
        GBuffer.cat([a, full(1, other)])
    with pytest.raises(ValueError, match=r"^items\[1\]:.*channels"):
        GBuffer.cat([a, a.select(["view_z"])])
    with pytest.raises(ValueError, match="^items"):
        GBuffer.cat([])


def test_frozen():
    g = full()
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.view_z = channel("view_z")  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.camera = CAM  # type: ignore[misc]


def test_to_accepts_a_positional_dtype_like_tensor_to():
    from ssbench.camera import Camera
    from ssbench.gbuffer import GBuffer
    cam = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 45.0, 4, 3, 0.1, 100.0)
    g = GBuffer(cam, view_z=torch.full((1, 1, 3, 4), -5.0), mask=torch.ones(1, 1, 3, 4, dtype=torch.bool))
    h = g.to(torch.float64)
    assert h.view_z.dtype == torch.float64 and h.mask.dtype == torch.bool
    assert torch.equal(h.view_z, g.view_z.double())
    with pytest.raises(TypeError, match="device: got the dtype"):
        g.to(torch.float64, dtype=torch.float32)
    with pytest.raises(TypeError, match="dtype: expected a torch.dtype"):
        g.to(dtype="float64")
