"""Image writers: float EXR (through Mitsuba's ``Bitmap``) and 8-bit PNG previews of G-buffer channels.

Both write to a temporary file next to the target and ``os.replace`` it into place, so a reader never sees a
half-written file. PNGs go through :func:`matplotlib.image.imsave` (Pillow underneath, no pyplot state, no
display needed).

Preview encodings (:func:`preview_png`), background pixels black unless noted:

* ``color``: linear RGB × exposure, clamped to [0, 1], sRGB transfer curve;
* ``view_z``/``back_z``/``second_z``: linear distance ``−z`` normalised over the foreground (near = bright), viridis;
* ``normal``: ``(n + 1) / 2``; ``position``: each axis normalised over the foreground;
* ``albedo``: as is; ``roughness``/``metallic``: grey, as is (background keeps its fill value);
* ``shape_id``: categorical tab20; ``mask``: white on black.
"""
from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import tempfile
from typing import Optional

import numpy as np

from .gbuffer import CHANNELS

__all__ = ["write_exr", "preview_png", "preview_rgb", "to_hwc"]


def _numpy(x) -> np.ndarray:
    if hasattr(x, "detach"):                                    # torch tensor
        return x.detach().cpu().numpy()
    return np.asarray(x)


def to_hwc(x, layout: Optional[str] = None) -> np.ndarray:
    """``(H, W, C)`` numpy copy of ``(C, H, W)``, ``(1, C, H, W)``, ``(H, W, C)`` or ``(H, W)`` input.

    ``layout`` (``"chw"`` or ``"hwc"``) settles 3-D inputs; by default torch tensors are channel-first and
    numpy arrays are channel-first only when their first axis is short (≤ 4) and their last is not.
    """
    is_torch = hasattr(x, "detach")
    a = _numpy(x)
    if a.ndim == 4:
        if a.shape[0] != 1:
            raise ValueError(f"array: expected batch size 1 for a (1, C, H, W) image, got shape {a.shape}")
        a, layout = a[0], "chw"
    if a.ndim == 2:
        return a[:, :, None]
    if a.ndim != 3:
        raise ValueError(f"array: expected (C, H, W), (1, C, H, W), (H, W, C) or (H, W), got shape {a.shape}")
    if layout is None:
        layout = "chw" if is_torch or (a.shape[0] <= 4 < a.shape[-1]) else "hwc"
    if layout not in ("chw", "hwc"):
        raise ValueError(f"layout: expected 'chw' or 'hwc', got {layout!r}")
    return np.moveaxis(a, 0, -1) if layout == "chw" else a


def umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def umask_mode() -> int:
    return 0o666 & ~umask()


def replace_dir(new: str, dest: str) -> str:
    """Publish the finished folder ``new`` as ``dest`` so that ``dest`` always exists and is never half-written.

    ``dest`` is a symbolic link to a hidden sibling folder ``.<name>@<token>``: ``new`` is renamed to such a
    folder, a fresh link to it is renamed over ``dest`` (``rename(2)`` replaces a link atomically, so a reader
    sees the old tree or the new one, never neither). The previous folder is kept until the next swap, so a
    reader that resolved the old link (a browser fetching images) still finds its files; older ones are
    removed. Swaps of one ``dest`` are serialised by an ``flock`` on ``.<name>.lock``, so concurrent
    publishers leave nothing behind. A ``dest`` that is still a real folder (an older ssbench) is moved once.
    """
    root = os.path.dirname(os.path.abspath(dest))
    name = os.path.basename(os.path.abspath(dest))
    with _locked(os.path.join(root, f".{name}.lock")):
        target = tempfile.mkdtemp(prefix=f".{name}@", dir=root)
        os.rmdir(target)
        os.replace(new, target)
        previous = os.readlink(dest) if os.path.islink(dest) else None
        if previous is None and os.path.isdir(dest):           # the pre-link layout: one last non-atomic swap
            aside = tempfile.mkdtemp(prefix=f".{name}@", dir=root)
            os.rmdir(aside)
            os.replace(dest, aside)
            previous = os.path.basename(aside)
        link = os.path.join(root, f".{name}.link-{os.getpid()}-{secrets.token_hex(4)}")
        os.symlink(os.path.basename(target), link)
        os.replace(link, dest)
        keep = {os.path.basename(target), previous}
        for entry in os.listdir(root):
            if entry.startswith(f".{name}@") and entry not in keep:
                shutil.rmtree(os.path.join(root, entry), ignore_errors=True)
    return dest


@contextlib.contextmanager
def _locked(path: str):
    """An exclusive ``flock`` on ``path`` for the block (no lock where ``fcntl`` is missing)."""
    try:
        import fcntl
    except ImportError:                                        # pragma: no cover - not POSIX
        yield
        return
    with open(path, "a") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def write_atomic(path: str, suffix: str, write) -> str:
    path = os.fspath(path)
    d = os.path.dirname(os.path.abspath(path))
    os.makedirs(d, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=suffix, dir=d)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, umask_mode())                            # mkstemp makes 0600; give the usual mode
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def write_exr(path, array, layout: Optional[str] = None) -> str:
    """Write a float32 OpenEXR of ``array`` (any shape :func:`to_hwc` takes; bool/int become float32)."""
    from .reference import backend
    mi = backend.mitsuba()
    hwc = np.ascontiguousarray(to_hwc(array, layout).astype(np.float32))
    return write_atomic(path, ".exr", lambda tmp: mi.Bitmap(hwc).write(tmp))


# ---------------------------------------------------------------------------------------------- previews
def _srgb(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def _normalise(v: np.ndarray, fg: np.ndarray) -> np.ndarray:
    """Map ``v`` linearly to [0, 1] over its foreground range (0 where there is none)."""
    out = np.zeros(v.shape, np.float64)
    if not fg.any():
        return out
    lo, hi = float(v[fg].min()), float(v[fg].max())
    out[fg] = (v[fg] - lo) / (hi - lo) if hi > lo else 0.5
    return out


def _cmap(name: str):
    import matplotlib
    return matplotlib.colormaps[name]


def preview_rgb(name: str, x, mask=None, camera=None, exposure: float = 1.0) -> np.ndarray:
    """The ``(H, W, 3)`` uint8 preview of channel ``name`` (see the module docstring for the encodings).

    Args:
        name: a channel from :data:`ssbench.gbuffer.CHANNELS` (others: RGB clamped, or one channel normalised).
        x: the channel, ``(1, C, H, W)``, ``(C, H, W)``, ``(H, W, C)`` or ``(H, W)``.
        mask: optional foreground mask of the same size; when absent the channel's fill values tell.
        camera: optional :class:`~ssbench.camera.Camera`; depth at or beyond its far plane is background.
    """
    want = CHANNELS.get(name)
    shape, layout = _numpy(x).shape, None
    if len(shape) == 3 and want is not None and (shape[0] == want) != (shape[-1] == want):
        layout = "chw" if shape[0] == want else "hwc"
    a = to_hwc(x, layout)
    raw = a.astype(np.float64)
    finite = np.isfinite(raw).all(-1)
    v = np.where(np.isfinite(raw), raw, 0.0)                    # no NaN/inf past this line
    fg = finite if mask is None else (to_hwc(mask)[..., 0].astype(bool) & finite)

    if name == "color":
        rgb = _srgb(v[..., :3] * exposure)
    elif name in ("view_z", "back_z", "second_z"):
        z = v[..., 0]
        if camera is not None:
            fg = fg & (z > -camera.far * (1 - 1e-6))
        t = 1.0 - _normalise(-z, fg)                            # near = 1 (yellow), far = 0 (purple)
        rgb = np.where(fg[..., None], _cmap("viridis")(t)[..., :3], 0.0)
    elif name == "normal":
        if mask is None:
            fg = fg & (np.abs(v).sum(-1) > 0)
        rgb = np.where(fg[..., None], (v[..., :3] + 1.0) / 2.0, 0.0)
    elif name == "position":
        rgb = np.stack([_normalise(v[..., k], fg) for k in range(3)], -1)
        rgb = np.where(fg[..., None], rgb, 0.0)
    elif name == "shape_id":
        ids = v[..., 0].round().astype(np.int64)
        fg = fg & (ids >= 0)
        rgb = np.where(fg[..., None], _cmap("tab20")(np.mod(ids, 20))[..., :3], 0.0)
    elif name == "mask":
        rgb = np.repeat((v[..., :1] > 0.5).astype(np.float64), 3, -1)
    elif a.shape[-1] >= 3:                                      # albedo and any other RGB-like channel
        rgb = v[..., :3]
    elif name in ("roughness", "metallic"):
        rgb = np.repeat(v[..., :1], 3, -1)
    else:                                                       # unknown one-channel data: normalised grey
        rgb = np.repeat(_normalise(v[..., 0], fg)[..., None], 3, -1)
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def write_rgb_png(path, rgb: np.ndarray) -> str:
    """Write an ``(H, W, 3)`` uint8 image as a PNG, atomically and losslessly; returns ``path``.

    An image of at most 256 distinct colours (grey maps, false colour through a 256-entry colour map, class maps)
    is stored as an exact palette PNG (one byte per pixel: the report's maps shrink ~2-3x, decoding gives the
    same RGB); others as RGB. zlib level 6 (the default): on the 640×360 report's 277 images 1.2 s in all and
    14.7 MB, against 0.6 s and 15.4 MB at level 1 (and 3.7 s, 14.5 MB at 9).
    """
    from PIL import Image
    rgb = np.ascontiguousarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[-1] != 3:
        raise ValueError(f"rgb: expected an (H, W, 3) uint8 array, got {rgb.dtype} {rgb.shape}")
    key = (rgb[..., 0].astype(np.uint32) << 16) | (rgb[..., 1].astype(np.uint32) << 8) | rgb[..., 2]
    colours, index = np.unique(key.ravel(), return_inverse=True)
    if colours.size <= 256:
        img = Image.fromarray(index.reshape(key.shape).astype(np.uint8), mode="P")
        img.putpalette(np.stack([colours >> 16, (colours >> 8) & 255, colours & 255], 1).astype(np.uint8).ravel()
                       .tolist())
    else:
        img = Image.fromarray(rgb)
    return write_atomic(path, ".png", lambda tmp: img.save(tmp, format="png", compress_level=6))


def save_figure(fig, path, dpi: int = 100) -> str:
    """Save a matplotlib figure as PNG atomically (zlib level 1, as :func:`write_rgb_png`); returns ``path``."""
    return write_atomic(path, ".png", lambda tmp: fig.savefig(tmp, format="png", dpi=dpi,
                                                          pil_kwargs={"compress_level": 1}))


def shrink_rgb(rgb: np.ndarray, factor: int, nearest: bool = False) -> np.ndarray:
    """``(H, W, 3)`` uint8 reduced ``factor``× in each axis: the mean of each ``factor``² block (rounded), or its
    top-left pixel when ``nearest`` (categorical maps: ids, masks); the last partial rows and columns dropped.

    Example:
        >>> shrink_rgb(np.arange(48, dtype=np.uint8).reshape(4, 4, 3), 2)[0, 0].tolist()
        [8, 9, 10]
    """
    if isinstance(factor, bool) or not isinstance(factor, int) or factor < 1:
        raise ValueError(f"factor: expected a positive integer, got {factor!r}")
    if factor == 1:
        return rgb
    h, w = rgb.shape[0] // factor * factor, rgb.shape[1] // factor * factor
    if nearest:
        return np.ascontiguousarray(rgb[:h:factor, :w:factor])
    blocks = rgb[:h, :w].reshape(h // factor, factor, w // factor, factor, 3).astype(np.float64)
    return (blocks.mean(axis=(1, 3)) + 0.5).astype(np.uint8)


def preview_png(path, name: str, tensor, mask=None, camera=None, exposure: float = 1.0) -> str:
    """Write the 8-bit PNG preview of channel ``name`` to ``path`` (atomically); returns ``path``."""
    return write_rgb_png(path, preview_rgb(name, tensor, mask=mask, camera=camera, exposure=exposure))
