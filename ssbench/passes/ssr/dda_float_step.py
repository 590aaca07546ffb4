"""The DDA's step (SSR article §2.2) with its flags as 0/1 floating-point numbers: what :func:`~.dda_march.dda_step`
computes, eagerly and without gradients, the same bits. Of the step's fifteen ``torch.where``, the two of the hit
pixel's axis swap and the six that keep a stopped ray's sample stay (:func:`~.masked_march.next_state`). (The
supercover walk's cell step, :func:`~.dda_supercover_walk.walk_step`, written the same way kept ten of its seventeen
and took 1.00–1.04× the time of its boolean form: it keeps that form.)

:mod:`ssbench.passes.float_masks` says why: on the CPU a comparison written into a bool tensor and ``torch.where`` cost
several additions each, a comparison written into a float buffer less than one. Here the working set's ``alive32``,
``steps`` and ``term`` (:class:`~.dda_march.DDAState`) and the rays' ``clipped32`` and ``b_index``
(:class:`~.dda_march.DDARay`) hold 0/1 flags, counts, codes and batch indices in the samples' dtype
(:func:`float_fields`, where :func:`~ssbench.passes.float_masks.float_flags` says every such integer, and every flat
texel index, is exact in it). The step's masks are then products and differences of 0/1 numbers, each of the old
boolean form's ``&``, ``|`` and ``~`` on sets that nest or are disjoint (``past`` and ``partial`` split ``beyond``;
``off`` and ``live`` split ``marching & ~past``; a hit is live), and a termination code is a sum of codes times
disjoint masks. The two selects of footprint values, ``back`` and ``half``, become ``partial · value`` (a value that
is finite and not negative: ``f`` is first cleared of NaN, which compares false as it did) and
``partial · f + (1 − partial)``, the same numbers.
"""
from __future__ import annotations

import dataclasses

import torch

from ..float_masks import inside_image
from .common import BEHIND_CAMERA, HIT, MAX_DISTANCE, OFF_SCREEN, ray_view_z
from .masked_march import next_state

__all__ = ["FLOAT_FIELDS", "float_fields", "float_dda_step"]

#: the marching set's integer fields (:class:`~.dda_march.MarchingRays`) that the float step keeps in the samples' dtype
FLOAT_FIELDS = ("alive32", "steps", "term", "clipped32", "b_index")


def float_fields(s):
    """The marching set ``s`` (:class:`~.dda_march.MarchingRays`) with :data:`FLOAT_FIELDS` in its samples' dtype.

    Example:
        >>> @dataclasses.dataclass
        ... class Rays:                                    # the fields it reads, of a set of two rays
        ...     k: torch.Tensor
        ...     alive32: torch.Tensor
        ...     steps: torch.Tensor
        ...     term: torch.Tensor
        ...     clipped32: torch.Tensor
        ...     b_index: torch.Tensor
        >>> i32 = lambda *v: torch.tensor(v, dtype=torch.int32)
        >>> s = float_fields(Rays(torch.zeros(2), i32(1, 1), i32(0, 0), i32(4, 4), i32(0, 1), i32(0, 0)))
        >>> s.term, s.clipped32
        (tensor([4., 4.]), tensor([0., 1.]))
    """
    return dataclasses.replace(s, **{f: getattr(s, f).to(s.k.dtype) for f in FLOAT_FIELDS})


def float_dda_step(state, ray, tex: tuple, size: tuple, z_thickness: float) -> tuple:
    """:func:`~.dda_march.dda_step` (``go`` absent) on a working set in :func:`float_fields` form, the same bits:
    advance by a stride, shorten the last footprint at ``stop``, ``texelFetch`` and the depth test; a stopped ray
    keeps its state.

    Args:
        state: :class:`~.dda_march.DDAState`; ray: :class:`~.dda_march.DDARay`.
        tex: ``(front, back, second)`` flat: the scene view z with NaN off the mask, the back-face and second-layer z
            (or ``None``) likewise.

    Returns:
        ``(state, done, t, live)``: the new state, the rays that stopped here (1.0), the fetched texels (int32) and
        the rays that fetched them (1.0).
    """
    st, r = state, ray
    front, back_z, second_z = tex
    H, W = size
    marching, keep = st.alive32, st.alive32 != 0
    Px, Py, Qz, k = st.Px + r.dPx, st.Py + r.dPy, st.Qz + r.dQz, st.k + r.dk
    n = st.n + 1.0
    u = Px * r.stepDir
    beyond = torch.gt(u, r.stop, out=torch.empty_like(u)).mul_(marching)        # centre past P1 / the edge
    f = ((r.stop - u) / r.stride + 0.5).nan_to_num_(0.0).clamp_(0.0, 1.0)       # footprint share before stop
    partial = torch.gt(f, 0, out=torch.empty_like(f)).mul_(beyond)               # last, shortened footprint
    past = beyond - partial                                                       # nothing left to test: ended
    back = torch.rsub(f, 1.0).mul_(0.5).mul_(partial)                            # centre of [P − ½dP, stop]
    Px, Py, Qz, k = Px - r.dPx * back, Py - r.dPy * back, Qz - r.dQz * back, k - r.dk * back
    n = n - back
    half = torch.addcmul(torch.rsub(partial, 1.0), partial, f).mul_(0.5)
    swap = r.permute32 != 0
    px, py = torch.where(swap, Py, Px), torch.where(swap, Px, Py)                 # hitPixel = permute ? P.yx : P
    on = inside_image(px, py, W, H)
    col, row = px.floor().clamp_(0, W - 1), py.floor().clamp_(0, H - 1)
    t = torch.add(col, row, alpha=W).add_(r.b_index, alpha=H * W)                 # exact integers
    t = t.nan_to_num_(0.0).to(torch.int32)       # a NaN sample (degenerate input) is off screen: any texel will do
    sceneZMax = front.index_select(0, t)
    in_range = marching - past                                                    # marching & ~past
    live = in_range * on                                                          # this sample is fetched
    off = in_range - live
    rayZMin = st.prevZ
    rayZMax = ray_view_z(r.dQz * half + Qz, r.dk * half + k, r.zlo, r.zhi)      # footprint end
    prevZ = rayZMax
    rayZMin, rayZMax = torch.minimum(rayZMin, rayZMax), torch.maximum(rayZMin, rayZMax)   # swap
    bottom = back_z.index_select(0, t) if back_z is not None else sceneZMax       # layered depth: the back face
    hit = _between(rayZMin, rayZMax, bottom - z_thickness, sceneZMax).mul_(live)
    if second_z is not None:                                                      # the second depth layer
        z2 = second_z.index_select(0, t)
        hit = torch.maximum(hit, _between(rayZMin, rayZMax, z2 - z_thickness, z2).mul_(live))
    # the code: OFF_SCREEN off screen, HIT on a hit, else past P1 at the full step's centre the segment's end
    # (BEHIND_CAMERA where clipped, MAX_DISTANCE) or OFF_SCREEN
    end = r.clipped32 * (BEHIND_CAMERA - MAX_DISTANCE) + (MAX_DISTANCE - OFF_SCREEN)
    code = end.mul_(torch.gt(u, r.end, out=torch.empty_like(u))).add_(OFF_SCREEN)
    code.mul_(torch.rsub(hit, 1.0).sub_(off)).add_(hit, alpha=HIT).add_(off, alpha=OFF_SCREEN)
    done = torch.maximum(torch.maximum(off, hit), partial).add_(past)           # disjoint from past
    return next_state(st, keep, (Px, Py, Qz, k, n, prevZ), done, live, code), done, t, live


def _between(z_min: torch.Tensor, z_max: torch.Tensor, lo: torch.Tensor, hi: torch.Tensor) -> torch.Tensor:
    """``(z_max >= lo) & (z_min <= hi)`` as 1.0 / 0.0: the footprint ``[z_min, z_max]`` overlaps ``[lo, hi]``."""
    return torch.ge(z_max, lo, out=torch.empty_like(z_max)).mul_(torch.le(z_min, hi, out=torch.empty_like(z_min)))
