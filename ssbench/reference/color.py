"""Path-traced linear RGB of a scene with a box pixel filter (each pixel averages its own footprint only).

The image is rendered in passes of at most :data:`PASS_SPP` samples per pixel, each with its own seed derived
from ``seed``, and averaged; the passes drive a tqdm bar when the render is large. Same ``seed`` → same bits.
"""
from __future__ import annotations

import time
from typing import Optional

import numpy as np
import torch
from tqdm import tqdm

from . import backend, cache, convert
from .gbuffer import resolve_camera

PASS_SPP = 16
_KERNEL_VERSION = 1


def pass_seed(seed: int, k: int) -> int:
    return (seed * 0x9E3779B1 + k * 0x85EBCA6B + 1) % (1 << 32)


def color(scene, width: Optional[int] = None, height: Optional[int] = None, spp: int = 64, seed: int = 0,
          *, use_cache: bool = True, progress: Optional[bool] = None, info: Optional[dict] = None) -> torch.Tensor:
    """Path-traced linear RGB, :math:`(1, 3, H, W)` float32, row 0 at the top.

    Args:
        scene: a :class:`~ssbench.scenes.Scene`, catalog name, file path or dict.
        width, height: image size (default: the scene camera's).
        spp: samples per pixel (> 0).
        seed: integer seed; the same seed gives bit-identical images.
        progress: show a tqdm bar (default: when the render has over ~4 M samples).
        info: a dict to receive ``{"cached": bool, "seconds": float or None}``: whether the image came from the
            cache and how long its path tracing took (then, when it was rendered; ``None`` if not recorded).
    """
    if isinstance(spp, bool) or not isinstance(spp, int) or spp <= 0:
        raise ValueError(f"spp: samples per pixel must be a positive integer, got {spp!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    sc, cam = resolve_camera(scene, width, height)
    key = cache.make_key("color", _KERNEL_VERSION, sc.content_hash(), cam, spp, seed, PASS_SPP)
    stored: dict = {}
    hit = cache.load(key, stored) if use_cache else None
    if hit is not None:
        if info is not None:
            info.update(cached=True, seconds=stored.get("seconds"))
        return torch.from_numpy(hit["color"])
    t0 = time.perf_counter()                                        # scene conversion + path tracing
    mi = backend.mitsuba()
    import drjit as dr
    mscene = convert.load(sc, cam)
    passes = [PASS_SPP] * (spp // PASS_SPP) + ([spp % PASS_SPP] if spp % PASS_SPP else [])
    show = progress if progress is not None else cam.width * cam.height * spp > 4_000_000
    acc = torch.zeros((cam.height, cam.width, 3), dtype=torch.float64)
    for k, n in enumerate(tqdm(passes, desc=f"color {sc.name} {cam.width}x{cam.height} {spp}spp",
                               disable=not show, leave=False)):
        s = pass_seed(seed, k)
        s = dr.opaque(mi.UInt32, s) if backend.is_jit() else s
        img = mi.render(mscene, spp=n, seed=s)
        acc += (img.torch() if backend.is_jit() else torch.from_numpy(np.array(img))).double() * n  # (H, W, 3)
    rgb = (acc / spp).float().permute(2, 0, 1)[None].contiguous().numpy()        # (1, 3, H, W)
    seconds = time.perf_counter() - t0
    if use_cache:
        cache.store(key, {"color": rgb}, {"seconds": seconds})
    if info is not None:
        info.update(cached=False, seconds=seconds)
    return torch.from_numpy(rgb)
