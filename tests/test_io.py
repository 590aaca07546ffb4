"""ssbench.io: EXR round trips through Mitsuba's Bitmap, PNG previews of every channel, atomic writes."""
import os
import warnings

import matplotlib.image as mimage
import numpy as np
import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import CHANNELS
from ssbench.io import preview_png, preview_rgb, to_hwc, write_exr


def _read_exr(path):
    from ssbench.reference import backend
    mi = backend.mitsuba()
    a = np.array(mi.Bitmap(path), copy=True)
    return a if a.ndim == 3 else a[:, :, None]


@pytest.mark.mitsuba
@pytest.mark.parametrize("layout", ["chw", "bchw", "hwc"])
def test_exr_round_trip(tmp_path, layout):
    rng = np.random.default_rng(0)
    hwc = rng.normal(size=(7, 9, 3)).astype(np.float32)
    hwc[0, 0] = [-100.0, -np.inf, 1e-30]
    x = {"chw": torch.from_numpy(hwc).permute(2, 0, 1), "bchw": torch.from_numpy(hwc).permute(2, 0, 1)[None],
         "hwc": hwc}[layout]
    path = str(tmp_path / "img.exr")
    assert write_exr(path, x) == path
    np.testing.assert_array_equal(_read_exr(path), hwc)
    assert [p for p in os.listdir(tmp_path)] == ["img.exr"]          # no temporary left behind


@pytest.mark.mitsuba
def test_exr_one_channel_bool_and_int(tmp_path):
    z = -torch.linspace(1, 50, 6 * 5).reshape(1, 1, 6, 5)
    write_exr(tmp_path / "z.exr", z)
    np.testing.assert_array_equal(_read_exr(str(tmp_path / "z.exr"))[..., 0], z[0, 0].numpy())
    m = torch.rand(1, 1, 6, 5) > 0.5
    write_exr(tmp_path / "m.exr", m)
    np.testing.assert_array_equal(_read_exr(str(tmp_path / "m.exr"))[..., 0], m[0, 0].float().numpy())
    sid = torch.randint(-1, 7, (1, 1, 6, 5), dtype=torch.int32)
    write_exr(tmp_path / "s.exr", sid)
    np.testing.assert_array_equal(_read_exr(str(tmp_path / "s.exr"))[..., 0], sid[0, 0].float().numpy())


def test_to_hwc_layouts():
    assert to_hwc(np.zeros((3, 10, 20))).shape == (10, 20, 3)
    assert to_hwc(np.zeros((10, 20, 3))).shape == (10, 20, 3)
    assert to_hwc(torch.zeros(1, 1, 10, 20)).shape == (10, 20, 1)
    assert to_hwc(np.zeros((10, 20))).shape == (10, 20, 1)
    with pytest.raises(ValueError, match="batch size 1"):
        to_hwc(np.zeros((2, 3, 4, 5)))


def _gbuffer_like(h=12, w=16):
    cam = Camera.from_look_at((0, 2, 6), (0, 0.6, 0), (0, 1, 0), 45.0, w, h, 0.1, 100.0)
    mask = torch.zeros(1, 1, h, w, dtype=torch.bool)
    mask[..., h // 2:, :] = True
    z = torch.where(mask, -torch.linspace(2, 9, h * w).reshape(1, 1, h, w), torch.tensor(-cam.far))
    n = torch.nn.functional.normalize(torch.randn(1, 3, h, w), dim=1) * mask
    data = {"view_z": z, "back_z": torch.where(mask, z - 0.5, torch.tensor(-float("inf"))), "normal": n,
            "position": torch.randn(1, 3, h, w), "albedo": torch.rand(1, 3, h, w),
            "roughness": torch.rand(1, 1, h, w), "metallic": torch.rand(1, 1, h, w),
            "shape_id": torch.where(mask, torch.tensor(3, dtype=torch.int32), torch.tensor(-1, dtype=torch.int32)),
            "mask": mask, "color": torch.rand(1, 3, h, w) * 3,
            "second_z": torch.where(mask & (torch.rand(1, 1, h, w) < 0.5), z - 2.0, torch.tensor(-float("inf")))}
    return cam, mask, data


@pytest.mark.parametrize("name", list(CHANNELS))
def test_preview_png_valid_image_of_right_size(tmp_path, name):
    cam, mask, data = _gbuffer_like()
    path = str(tmp_path / f"{name}.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")                               # no NaN / invalid-value warnings
        preview_png(path, name, data[name], mask=mask, camera=cam)
    img = mimage.imread(path)
    assert img.shape[:2] == (12, 16) and img.shape[2] in (3, 4)
    assert np.isfinite(img).all()
    assert os.listdir(tmp_path) == [f"{name}.png"]


@pytest.mark.parametrize("name", ["view_z", "back_z", "normal", "position", "shape_id"])
@pytest.mark.parametrize("with_mask", [True, False])
def test_background_black_and_nan_free(name, with_mask):
    cam, mask, data = _gbuffer_like()
    x = data[name].clone()
    if name == "back_z":
        x[..., -1, -1] = -float("inf")                                 # a hit with no exit found
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rgb = preview_rgb(name, x, mask=mask if with_mask else None, camera=cam)
    assert rgb.dtype == np.uint8 and rgb.shape == (12, 16, 3)
    if with_mask or name != "position":                              # fill values alone reveal the background
        assert (rgb[:6] == 0).all()
    assert rgb[6:].any()


def test_depth_preview_near_is_bright_and_colour_is_srgb():
    cam, mask, data = _gbuffer_like()
    rgb = preview_rgb("view_z", data["view_z"], mask=mask, camera=cam).astype(int)
    assert rgb[6, 0].sum() > rgb[-1, -1].sum()                      # nearest (top of the fg) brighter
    col = preview_rgb("color", torch.tensor([0.0, 0.5, 7.0]).reshape(3, 1, 1))
    assert col[0, 0].tolist() == [0, 188, 255]                       # sRGB(0.5) = 0.735, clamped highlight


def test_preview_all_background_nan_free():
    cam, mask, data = _gbuffer_like()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rgb = preview_rgb("view_z", torch.full((1, 1, 4, 4), -cam.far), camera=cam)
        rgb2 = preview_rgb("back_z", torch.full((1, 1, 4, 4), -float("inf")))
    assert (rgb == 0).all() and (rgb2 == 0).all()


def test_write_rgb_png_round_trips_and_rejects_other_arrays(tmp_path):
    from ssbench.io import write_rgb_png
    rgb = np.random.default_rng(0).integers(0, 256, (5, 7, 3), dtype=np.uint8)
    path = str(tmp_path / "x.png")
    assert write_rgb_png(path, rgb) == path
    back = (mimage.imread(path)[..., :3] * 255 + 0.5).astype(np.uint8)
    assert np.array_equal(back, rgb)                                  # lossless, whatever the zlib level
    few = rgb // 64 * 64                                              # 64 colours: stored as a palette
    for name, img, mode in (("few.png", few, "P"), ("grey.png", np.repeat(rgb[..., :1], 3, -1), "P"),
                            ("one.png", np.zeros_like(rgb), "P"), ("x.png", rgb, "P"),
                            ("many.png", np.random.default_rng(1).integers(0, 256, (20, 20, 3), dtype=np.uint8), "RGB")):
        write_rgb_png(str(tmp_path / name), img)
        from PIL import Image
        with Image.open(tmp_path / name) as im:
            assert im.mode == mode and np.array_equal(np.asarray(im.convert("RGB")), img), name
    for bad in (rgb.astype(np.float32), rgb[..., :2], rgb[..., 0]):
        with pytest.raises(ValueError, match="^rgb:"):
            write_rgb_png(str(tmp_path / "bad.png"), bad)
    assert sorted(os.listdir(tmp_path)) == ["few.png", "grey.png", "many.png", "one.png", "x.png"]   # no leftovers


def _swapper(root: str, tag: str, n: int) -> None:
    import tempfile as _t
    from ssbench.io import replace_dir
    for i in range(n):
        new = _t.mkdtemp(prefix=".new-", dir=root)
        with open(os.path.join(new, "index.html"), "w") as f:
            f.write(f"{tag}{i}")
        replace_dir(new, os.path.join(root, "latest"))


@pytest.mark.slow
def test_latest_is_present_in_every_poll_of_two_concurrent_swappers(tmp_path):
    """Regression: the folder swap had a window without ``latest`` (89 errors and 5 stray
    ``.old-latest-*`` folders in 30k swaps with two swappers); now a symlink is renamed over it, under a lock, so
    the link is always there. Following it can still fail when two swaps complete inside one lookup (the link read,
    then its target removed as the folder before the previous one): measured once in 20 432 polls with two
    swappers and the poller sharing 2 cores, so that is bounded, not zero."""
    import multiprocessing as mp
    root = str(tmp_path)
    _swapper(root, "init", 1)
    ctx = mp.get_context("fork")
    procs = [ctx.Process(target=_swapper, args=(root, t, 300)) for t in ("a", "b")]
    for p in procs:
        p.start()
    polls = missing = unresolved = read = 0
    while any(p.is_alive() for p in procs):
        polls += 1
        if not os.path.lexists(os.path.join(root, "latest")):                 # the link is there, always
            missing += 1
        elif not os.path.isdir(os.path.join(root, "latest")):                 # and resolves but for rare races
            unresolved += 1
        try:                                                                    # and its files can be read
            with open(os.path.join(root, "latest", "index.html")) as f:
                read += f.read()[:1] in ("i", "a", "b")
        except FileNotFoundError:             # only if two swaps fall between resolving the link and open()
            pass
    for p in procs:
        p.join()
        assert p.exitcode == 0
    assert polls > 100 and missing == 0 and unresolved <= polls // 1000 and read > polls // 2, \
        (polls, missing, unresolved, read)
    kept = [n for n in os.listdir(root) if n.startswith(".latest@")]
    assert os.readlink(os.path.join(root, "latest")) in kept and len(kept) == 2          # current + previous
    assert sorted(n for n in os.listdir(root) if n not in kept and n != ".latest.lock") == ["latest"]


def test_shrink_rgb_averages_blocks_and_keeps_categories():
    from ssbench.io import shrink_rgb
    rgb = np.zeros((5, 7, 3), np.uint8)
    rgb[:2, :2] = 255
    assert shrink_rgb(rgb, 2).shape == (2, 3, 3) and shrink_rgb(rgb, 2)[0, 0].tolist() == [255] * 3
    rgb[0, 0] = (10, 20, 30)                                          # a mixed block: mean, or its corner
    assert shrink_rgb(rgb, 2)[0, 0].tolist() == [194, 196, 199]
    assert shrink_rgb(rgb, 2, nearest=True)[0, 0].tolist() == [10, 20, 30]
    assert shrink_rgb(rgb, 1) is rgb
    with pytest.raises(ValueError, match="factor"):
        shrink_rgb(rgb, 0)
