"""One input contract for every screen-space pass: what a G-buffer must hold, checked in one place.

Every pass calls :func:`check_gbuffer` with the channels it reads. The contract (also in ``ssbench/RELIABILITY.md``):

* ``gbuffer`` is a :class:`~ssbench.gbuffer.GBuffer` holding the channels; each is :math:`(B, C, H, W)` with the
  camera's ``H × W``, one batch size, one device; ``mask`` is ``torch.bool``, the other read channels share
  ``view_z``'s floating dtype (float16, bfloat16, float32 or float64).
* ``view_z`` is finite everywhere (the background holds ``−far``, what a cleared depth buffer reads back) and
  ``< 0`` on the mask. Depths beyond the far plane or closer than the near plane are legal.
* ``normal`` is finite and unit length on the mask, within a tolerance that scales with the dtype's epsilon
  (:func:`normal_tolerance`); background normals are not read.
* the channels in ``finite`` (``color``, ``position``, ``back_z``, …) hold no NaN.
* float16 and bfloat16 G-buffers are computed in float32 (:func:`half_in_float32`): their normals are checked at
  their own dtype's tolerance and renormalised, and the float outputs come back in the input dtype (hit
  positions stay float32: :data:`KEEP_FLOAT32`).
* on the ``meta`` device the AO passes return correctly shaped meta tensors; the SSR marchers, whose work
  depends on values, raise ``ValueError``.

A violation raises ``ValueError`` (``TypeError`` for a wrong type) whose message starts with the channel's name.
Value checks read tensor data, so they are skipped on the ``meta`` device, where only shapes and dtypes exist,
and when checks are switched off (:mod:`ssbench.checks`).
"""
from __future__ import annotations

import functools
from dataclasses import fields, replace
from typing import Iterable

import torch

from .. import checks
from ..gbuffer import CHANNELS, GBuffer
from ..rays import length


def has_values(t: torch.Tensor) -> bool:
    """Whether ``t`` carries data that a check can read (``False`` on the ``meta`` device)."""
    return t.device.type != "meta"


def normal_tolerance(dtype: torch.dtype) -> float:
    """Allowed ``| |n| − 1 |`` for unit normals stored in ``dtype``: ``max(1e-3, 8·eps)``.

    Example:
        >>> normal_tolerance(torch.float32), normal_tolerance(torch.bfloat16)
        (0.001, 0.0625)
    """
    return max(1e-3, 8.0 * torch.finfo(dtype).eps)


def check_unit_normals(normal: torch.Tensor, mask: torch.Tensor, name: str = "normal", tol: float | None = None) -> None:
    """Normals on ``mask`` must be finite and of unit length (background zeros are allowed).

    ``tol`` defaults to :func:`normal_tolerance` of the normals' dtype.
    """
    if not checks.checks_enabled() or not has_values(normal) or not has_values(mask):
        return
    tol = normal_tolerance(normal.dtype) if tol is None else tol
    n_len = length(normal.float() if normal.dtype in (torch.float16, torch.bfloat16) else normal)
    off = ~((n_len - 1).abs() <= tol)                           # NaN and inf lengths fail the comparison
    bad = mask & off
    if bool(bad.any()):
        worst = (n_len - 1).abs().nan_to_num(nan=float("inf"))[mask.expand_as(n_len)].max()
        raise ValueError(f"{name}: {int(bad.sum())} normals on geometry are not finite unit vectors "
                         f"(max |len-1| = {float(worst):.3g}, tolerance {tol:.3g} for {normal.dtype})")


def check_gbuffer(gbuffer: GBuffer, requires: Iterable[str], *, finite: Iterable[str] = (),
                  meta_ok: bool = True) -> None:
    """Check a pass's G-buffer against the contract above; messages name the channel.

    Args:
        gbuffer: the pass's input.
        requires: the channels the pass reads (``view_z`` and ``mask`` are always checked when present).
        finite: further channels that must hold no NaN.
        meta_ok: whether the pass can run on the ``meta`` device (shape inference). Passes whose work depends on
            values (the SSR marchers compact live rays) pass ``False`` and get a ``ValueError`` naming ``view_z``.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
        >>> z = torch.full((1, 1, 3, 4), -2.0)
        >>> check_gbuffer(GBuffer(cam, view_z=z, mask=z < 0), ("view_z", "mask"))
        >>> check_gbuffer(GBuffer(cam, view_z=z * 0 + float("nan"), mask=z < 0), ("view_z", "mask"))
        Traceback (most recent call last):
        ...
        ValueError: view_z: must be finite everywhere (background holds -far); found 12 NaN or infinite values
    """
    if not isinstance(gbuffer, GBuffer):
        raise TypeError(f"gbuffer: expected a GBuffer, got {type(gbuffer).__name__}")
    requires = tuple(requires)
    gbuffer.require(*requires)
    if not checks.checks_enabled():
        return
    z, m = gbuffer.view_z, gbuffer.mask
    H, W = str(gbuffer.height), str(gbuffer.width)
    for name in requires:
        t = getattr(gbuffer, name)
        checks.check_shape(t, ["B", str(CHANNELS[name]), H, W], name)
        if z is not None:
            checks.check_same_size(z, t, "view_z", name)
            if t.device != z.device:
                raise ValueError(f"{name}: on device {t.device}, view_z on {z.device}; move the G-buffer with .to()")
        if name == "mask":
            if t.dtype != torch.bool:
                raise ValueError(f"mask: expected dtype torch.bool, got {t.dtype}")
        elif name == "shape_id":
            continue
        elif not t.is_floating_point():
            raise ValueError(f"{name}: expected a floating-point dtype, got {t.dtype}")
        elif z is not None and t.dtype != z.dtype:
            raise ValueError(f"{name}: dtype {t.dtype} must match view_z's {z.dtype}")
    if z is not None and not has_values(z) and not meta_ok:
        raise ValueError("view_z: on the meta device, which holds no values; this pass's work depends on them "
                         "(it compacts rays by value), so run it on cpu or cuda tensors")
    if z is None or m is None or not has_values(z):
        return
    if not checks.all_finite(z):
        raise ValueError(f"view_z: must be finite everywhere (background holds -far); "
                         f"found {int((~torch.isfinite(z)).sum())} NaN or infinite values")
    if bool((m & (z >= 0)).any()):
        raise ValueError("view_z: must be < 0 on geometry (points in front of the camera)")
    if "normal" in requires:
        check_unit_normals(gbuffer.normal, m, "normal")
    for name in finite:
        t = getattr(gbuffer, name)
        if t is not None and checks.has_nan(t):
            raise ValueError(f"{name}: contains NaN")


HALF = (torch.float16, torch.bfloat16)
#: result fields that stay float32 for half inputs: float16 holds a pixel coordinate above 2048 only to 2 px
#: (and bfloat16 above 256), so a hit's position would name another texel than the one the pass read
KEEP_FLOAT32 = ("hit_pixel", "hit_view")


def half_in_float32(fn):
    """Decorator of a pass ``fn(gbuffer, ...)``: a float16/bfloat16 G-buffer is promoted to float32, the pass
    runs, and its result's float32 tensors are cast back to the input dtype (except :data:`KEEP_FLOAT32`).

    Half precision cannot carry a pass's intermediate values (squared view-space distances overflow float16
    above 256, and a projection at near = 1e-6 underflows), so the pass computes in float32, as a GPU shader
    reading a half-float G-buffer does. Normals within :func:`normal_tolerance` of unit length *for the input
    dtype* are renormalised after the promotion; the others stay as they are and are refused by the pass's
    checks. Other dtypes, and the ``meta`` device, pass through untouched.
    """
    @functools.wraps(fn)
    def wrapper(gbuffer, *args, **kwargs):
        z = getattr(gbuffer, "view_z", None)
        if not isinstance(gbuffer, GBuffer) or not isinstance(z, torch.Tensor) or z.dtype not in HALF:
            return fn(gbuffer, *args, **kwargs)
        g32 = gbuffer.to(dtype=torch.float32)
        if g32.normal is not None and g32.mask is not None and has_values(g32.normal):
            n_len = length(g32.normal)
            ok = g32.mask & ((n_len - 1).abs() <= normal_tolerance(z.dtype))
            g32 = replace(g32, normal=torch.where(ok, g32.normal / n_len.clamp_min(1e-30), g32.normal))
        out = fn(g32, *args, **kwargs)
        cast = {f.name: getattr(out, f.name).to(z.dtype) for f in fields(out) if f.name not in KEEP_FLOAT32
                and isinstance(getattr(out, f.name), torch.Tensor) and getattr(out, f.name).dtype == torch.float32}
        return replace(out, **cast)
    return wrapper
