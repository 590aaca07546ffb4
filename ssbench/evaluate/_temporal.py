"""Frames of one AO method on a static scene, as a real-time renderer produces them: the noise advanced every
frame and the camera jittered by a sub-pixel offset, so :func:`ssbench.metrics.flicker` can say how much the
output changes from frame to frame.

* the noise advances as the method does it: a pass module that declares ``FRAME_PARAM`` (GTAO: ``frame``,
  XeGTAO's ``288·(frame mod 64)`` Hilbert offset) gets the frame index there; every pass also gets a fresh
  generator per frame (``seed + frame``), which redraws the kernels and rotation textures drawn from it (an
  animated noise texture). ``advance_noise=False`` keeps frame 0's noise (three.js ``SSAOPass`` ships a static
  texture: its flicker comes from the jitter alone);
* the jitter is the Halton (2, 3) sequence of TAA, centred on the pixel (offsets in [−½, ½)), applied with
  :meth:`ssbench.camera.Camera.jittered`; each frame's G-buffer is rendered by Mitsuba from the jittered camera.
"""
from __future__ import annotations

import dataclasses
import importlib
from typing import Optional

import torch

from ..metrics.temporal import flicker
from ._common import resolve_params

__all__ = ["AOFrames", "ao_frames", "halton"]


def halton(index: int, base: int) -> float:
    """The radical inverse of ``index`` in ``base`` (Halton sequence), in [0, 1).

    Example:
        >>> [halton(i, 2) for i in range(1, 5)]
        [0.5, 0.25, 0.75, 0.125]
    """
    f, r, i = 1.0, 0.0, index
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r


@dataclasses.dataclass(frozen=True)
class AOFrames:
    """What :func:`ao_frames` produced.

    Attributes:
        ao: :math:`(T, 1, 1, H, W)` the method's AO per frame.
        mask: :math:`(T, 1, 1, H, W)` bool valid pixels per frame.
        offsets: the ``(dx, dy)`` pixel jitter of each frame.
        flicker: :func:`ssbench.metrics.flicker` of ``ao`` over the pixels valid in every frame.
        params: the parameters of frame 0.
    """

    ao: torch.Tensor
    mask: torch.Tensor
    offsets: tuple
    flicker: float
    params: object


def ao_frames(scene, method: str, params=None, *, frames: int = 8, jitter: bool = True,
              advance_noise: bool = True, width: int = 160, height: int = 120, radius: Optional[float] = None,
              seed: int = 0, use_cache: bool = True) -> AOFrames:
    """Run AO ``method`` on ``frames`` frames of a static ``scene`` (see the module docstring).

    Args:
        scene: catalog name, scene file, dict or :class:`~ssbench.scenes.Scene`.
        method: a name of :data:`ssbench.passes.AO_METHODS`.
        params: ``None``, the params dataclass or a dict of overrides.
        frames: number of frames (≥ 2).
        jitter: jitter the camera by the Halton (2, 3) sub-pixel offsets (``False``: the same pixel centres).
        advance_noise: advance the noise every frame (``False``: frame 0's noise throughout).
        width, height: image size.
        radius: sets the pass's radius parameter (as :func:`ssbench.evaluate.ao`).
        seed: the generator seed of frame 0 (frame ``t`` uses ``seed + t`` when the noise advances).
        use_cache: let the G-buffer renders use the disk cache.
    """
    from .. import reference
    from ..passes import ao_method, declared
    from ..scenes import load as load_scene
    from ._ao import radius_param
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 2:
        raise ValueError(f"frames: must be an integer >= 2, got {frames!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    fn, params_cls, requires = ao_method(method)
    module = importlib.import_module(fn.__module__)
    p = resolve_params(params_cls, params, method)
    if radius is not None:
        rname = radius_param(params_cls, module)
        if rname is None:
            raise ValueError(f"radius: method {method!r} has no radius parameter")
        p = dataclasses.replace(p, **{rname: float(radius)})
    frame_param = declared(fn, "FRAME_PARAM")
    sc = load_scene(scene)
    cam = sc.camera.with_resolution(width, height)
    aos, masks, offsets = [], [], []
    for t in range(frames):
        dx, dy = (halton(t + 1, 2) - 0.5, halton(t + 1, 3) - 0.5) if jitter else (0.0, 0.0)
        g = reference.gbuffer(sc.with_camera(cam.jittered(dx, dy)), width, height,
                              channels=tuple(dict.fromkeys(tuple(requires) + ("mask",))), use_cache=use_cache)
        k = t if advance_noise else 0
        pt = dataclasses.replace(p, **{frame_param: k}) if frame_param else p
        out = fn(g, pt, generator=torch.Generator().manual_seed(seed + k)).ao.detach().float().cpu()
        aos.append(out)
        masks.append(g.mask.cpu())
        offsets.append((dx, dy))
    ao, mask = torch.stack(aos), torch.stack(masks)
    return AOFrames(ao, mask, tuple(offsets), float(flicker(ao, mask)), p)
