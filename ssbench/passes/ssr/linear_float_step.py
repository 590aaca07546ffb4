"""The linear march's step (SSR article §1.2) with its masks as 0/1 floating-point numbers: what
:func:`~.linear_march.march_step` computes, eagerly and without gradients, the same bits, without a boolean tensor or
a ``torch.where``.

:mod:`ssbench.passes.float_masks` says why: on the CPU a comparison written into a bool tensor and ``torch.where`` cost
several additions each, a comparison written into a float buffer less than one. Here a working set's flags ``live``
and ``hit`` are 0/1 and its ``steps`` a count, all in the samples' dtype, and the texel index is formed in floating
point (exact integers: :func:`~ssbench.passes.float_masks.float_flags` takes this form only while every texel index
and every count is below :math:`2/\\varepsilon`, :math:`2^{24}` in float32).

A ray that has stopped keeps its sample ``Q`` without a select: ``Q + live·deltaStep`` adds ``1·deltaStep`` (the
step's ``Q + deltaStep``, bit for bit) or ``0·deltaStep``, a signed zero, which leaves every ``Q`` as it was: a
nonzero ``Q`` is unchanged by a zero; ``+0 + (±0) = +0``; and a sum is ``−0`` only where both terms are, so a
stopped ray's ``Q.x = −0`` (it stopped on a step ``Q + deltaStep``) means ``deltaStep.x = −0`` and
``−0 + 0·(−0) = −0``. That needs a finite ``deltaStep``, which every marched ray has
(:func:`~.linear_rays.ray_steps`).
"""
from __future__ import annotations

from typing import Optional

import torch

from ...camera import Camera
from ..common import texel_of

__all__ = ["float_march_step"]


def float_march_step(scale: tuple, size: tuple, thickness: float, front: torch.Tensor, back: Optional[torch.Tensor],
                     rays: tuple) -> tuple:
    """:func:`~.linear_march.march_step` (``go`` absent) on a working set with 0/1 float flags
    (:func:`~ssbench.passes.float_masks.float_flags`), the same bits: ``Q += deltaStep``, project to the ``NEAREST``
    texel, read ``front`` (the scene z, NaN off the mask), test ``rayIntersectsDepth`` and the screen; a live ray
    stops on a hit or off screen.

    Args:
        scale: the camera's :meth:`~ssbench.camera.Camera.ndc_scale`; size: ``(H, W)``.
        rays: ``(qx, qy, qz, dx, dy, dz, base, live, hit, steps)``, each :math:`(m,)` in the samples' dtype (``base``,
            each ray's batch offset, too).

    Returns:
        ``(rays, t, on, h)``: the new state, the int32 texel index, the on-screen test and this step's hits (1.0 / 0.0).

    Example:
        >>> one = torch.ones(1)
        >>> rays = (0 * one, 0 * one, -2 * one, 0 * one, 0 * one, -one, 0 * one, one, 0 * one, 0 * one)
        >>> state, t, on, h = float_march_step((1.0, 1.0), (2, 2), 1.0, torch.full((4,), -2.5), None, rays)
        >>> [float(c) for c in state[2:3] + state[7:]], int(t), float(h)      # Q.z = −3 is behind −2.5: a hit
        ([-3.0, 0.0, 1.0, 1.0], 3, 1.0)
    """
    qx, qy, qz, dx, dy, dz, base, live, hit, steps = rays
    x, y, z = qx + dx, qy + dy, qz + dz                                           # Q += deltaStep (for live rays)
    u, v = Camera.scaled_uv_xy(x, y, z, scale)                                    # hitPixel (uv, v up)
    col, row = texel_of(u, v, size[0], size[1], dtype=u.dtype)                    # integer-valued floats
    t = torch.add(col, row, alpha=size[1]).add_(base).to(torch.int32)            # base + row·W + col: exact
    dist = z - front.index_select(0, t)                                           # dist = Q.z − sceneZMax
    h = torch.lt(dist, 0, out=torch.empty_like(dist))
    test = torch.empty_like(dist)
    if back is None:
        h.mul_(torch.gt(dist, -thickness, out=test))                              # rayIntersectsDepth
    else:
        h.mul_(torch.gt(z, back.index_select(0, t).sub_(thickness), out=test))
    on = torch.ge(u, 0, out=torch.empty_like(u)).mul_(torch.le(u, 1, out=test))  # hitPixel in [0, 1]²
    on.mul_(torch.ge(v, 0, out=test)).mul_(torch.le(v, 1, out=test))
    h.mul_(on)
    stop = torch.rsub(on, 1).add_(h).mul_(live)                                   # live & (hit | off screen)
    state = (torch.addcmul(qx, live, dx), torch.addcmul(qy, live, dy), torch.addcmul(qz, live, dz),   # see above
             dx, dy, dz, base, live - stop, torch.addcmul(hit, live, h), steps + live)
    return state, t, on, h
