r"""Dense uniform march: the independent cross-check of :func:`ssbench.reference.implicit`.

Per pixel the clipped range ``[t0, t1]`` (the same slab clip as the reference) is sampled uniformly,
``t_i = t0 + i·(t1 − t0)/steps`` for ``i = 0..steps``, and the first bracket ``f(t_i) ≥ 0 > f(t_{i+1})`` (the
article's hit test) is returned. No interval arithmetic, no Lipschitz bound: with 10⁵ steps it finds every
entering root whose chord is wider than the step — the certified reference must never miss one of those.

Two backends compute the same samples: Dr.Jit (``surface.drjit_f(x, y, z)`` on ``drjit.llvm.Float64`` inside
one symbolic ``dr.while_loop``, compiled to a single kernel) and a chunked torch loop (``surface.f``), used when
no JIT variant is available or on request. They agree bracket for bracket up to the round-off of the sample
positions (the LLVM backend may fuse ``t0 + i·dt`` into an FMA).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

import torch

from ..indices import flat_nonzero
from ..rays import camera_rays

__all__ = ["dense_march", "DenseMarch", "clip_to_bounds"]

BACKENDS = ("auto", "drjit", "torch")
_EPS = 2.0 ** -52


@dataclass(frozen=True)
class DenseMarch:
    r"""First sign-change bracket per pixel; tensors are :math:`(B, 1, H, W)`.

    Attributes:
        hit: bool, some ``f(t_i) ≥ 0 > f(t_{i+1})`` on the clipped range.
        t_lo, t_hi: float64 the first such bracket (``t_far`` where none).
        t_start, t_end: float64 the clipped range (``t_far`` both where the ray misses the bounds).
        steps: samples intervals per ray; backend: ``"drjit"`` or ``"torch"``; seconds: wall time.
    """

    hit: torch.Tensor
    t_lo: torch.Tensor
    t_hi: torch.Tensor
    t_start: torch.Tensor
    t_end: torch.Tensor
    steps: int
    backend: str
    seconds: float = 0.0


def clip_to_bounds(o: torch.Tensor, d: torch.Tensor, t_near: torch.Tensor, t_far: torch.Tensor, bounds
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Slab test: ``[t0, t1] = [t_near, t_far] ∩ {t : o + t d ∈ bounds}``, widened outward by rounding slack.

    Args:
        o, d: :math:`(N, 3)` float64 origins and directions (a zero component is handled exactly).
        t_near, t_far: :math:`(N,)`.
        bounds: ``((x0, y0, z0), (x1, y1, z1))``.

    Returns:
        ``(t0, t1)``, :math:`(N,)`; ``t0 ≥ t1`` where the ray misses the box.

    Example:
        >>> o = torch.tensor([[0.0, 0.0, 4.0], [0.0, 5.0, 4.0]], dtype=torch.float64)
        >>> d = torch.tensor([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0]], dtype=torch.float64)
        >>> t0, t1 = clip_to_bounds(o, d, torch.zeros(2), torch.full((2,), 10.0), ((-1, -1, -1), (1, 1, 1)))
        >>> [round(v, 9) for v in t0.tolist()], bool(t0[1] >= t1[1])
        ([3.0, inf], True)
    """
    lo = torch.tensor(bounds[0], dtype=o.dtype, device=o.device)
    hi = torch.tensor(bounds[1], dtype=o.dtype, device=o.device)
    par = d == 0
    with torch.no_grad():
        ta, tb = (lo - o) / torch.where(par, 1.0, d), (hi - o) / torch.where(par, 1.0, d)
    inside = (o >= lo) & (o <= hi)
    inf = torch.full_like(ta, math.inf)
    tmin = torch.where(par, torch.where(inside, -inf, inf), torch.minimum(ta, tb))
    tmax = torch.where(par, torch.where(inside, inf, -inf), torch.maximum(ta, tb))
    enter, leave = tmin.amax(dim=-1), tmax.amin(dim=-1)
    scale = 16 * _EPS * (o.abs().amax(dim=-1) + lo.abs().max() + hi.abs().max())
    t0 = torch.maximum(t_near.to(o), enter - scale * (1 + enter.abs()).nan_to_num(0))
    t1 = torch.minimum(t_far.to(o), leave + scale * (1 + leave.abs()).nan_to_num(0))
    empty = ~(t1 > t0)                                             # also NaN
    return torch.where(empty, math.inf, t0), torch.where(empty, -math.inf, t1)


def flat_rays(camera, batch, jitter):
    """Flattened float64 pixel rays ``(o, d, t_near, t_far)`` (N = B·H·W) and a ``(N·C) → (B, C, H, W)`` map."""
    rays = camera_rays(camera, batch=batch, jitter=jitter, dtype=torch.float64)
    B, _, H, W = rays.direction.shape
    flat = lambda x: x.permute(0, 2, 3, 1).reshape(-1, x.shape[1]).contiguous()      # noqa: E731
    img = lambda x, c=1: x.reshape(B, H, W, c).permute(0, 3, 1, 2).contiguous()      # noqa: E731
    return flat(rays.origin), flat(rays.direction), flat(rays.t_near)[:, 0], flat(rays.t_far)[:, 0], img


def _jit_module():
    """``(drjit, drjit.llvm or drjit.cuda)`` after :func:`ssbench.reference.backend.mitsuba`; None without JIT."""
    from . import backend as be
    if not be.is_jit():
        return None
    be.mitsuba()
    import drjit as dr
    if be.choice().variant.startswith("cuda"):
        import drjit.cuda as m
    else:
        import drjit.llvm as m
    return dr, m


def _march_drjit(surface, o, d, t0, t1, steps):
    dr, m = _jit_module()
    F, U = m.Float64, m.UInt32
    valid = t1 > t0
    lo_t = torch.where(valid, t0, 0.0).contiguous()
    dt_t = torch.where(valid, (t1 - t0) / steps, 0.0).contiguous()
    ox, oy, oz = (F(o[:, k].contiguous().numpy()) for k in range(3))
    dx, dy, dz = (F(d[:, k].contiguous().numpy()) for k in range(3))
    t0j, dtj = F(lo_t.numpy()), F(dt_t.numpy())

    def f_at(t):
        return surface.drjit_f(ox + t * dx, oy + t * dy, oz + t * dz)

    i = dr.select(m.Bool(valid.numpy()), U(0), U(steps))
    fprev = f_at(t0j)
    found = m.Bool(False) | (i > U(steps))                   # per-lane False

    def cond(i, fprev, found):
        return (i < steps) & ~found

    def body(i, fprev, found):
        fn = f_at(t0j + F(i + 1) * dtj)
        hit = (fprev >= 0) & (fn < 0)
        return dr.select(hit, i, i + 1), fn, hit

    i, fprev, found = dr.while_loop(state=(i, fprev, found), cond=cond, body=body, mode="symbolic")
    dr.eval(i, found)
    return torch.from_numpy(found.numpy().copy()).bool(), torch.from_numpy(i.numpy().astype("int64"))


def _march_torch(surface, o, d, t0, t1, steps, chunk):
    N = o.shape[0]
    valid = t1 > t0
    dt = torch.where(valid, (t1 - t0) / steps, 0.0)
    t0 = torch.where(valid, t0, 0.0)
    found = torch.zeros(N, dtype=torch.bool)
    first = torch.full((N,), steps, dtype=torch.int64)
    active = valid.clone()
    k0 = 0
    while k0 < steps:
        idx = flat_nonzero(active)
        if idx.numel() == 0:
            break
        K = max(1, min(steps - k0, chunk // max(1, idx.numel())))
        k = torch.arange(k0, k0 + K + 1, dtype=torch.float64)                  # K + 1 samples, K brackets
        t = t0[idx, None] + k[None, :] * dt[idx, None]
        with torch.no_grad():
            f = surface.f(o[idx, None, :] + t[..., None] * d[idx, None, :]).to(torch.float64)
        c = (f[:, :-1] >= 0) & (f[:, 1:] < 0)
        any_c = c.any(dim=1)
        j = c.to(torch.int8).argmax(dim=1)
        hit_rows = idx[any_c]
        found[hit_rows] = True
        first[hit_rows] = k0 + j[any_c]
        active[hit_rows] = False
        k0 += K
    return found, first


def dense_march(surface, camera, steps: int = 100_000, *, batch: int = 1, jitter: Optional[torch.Tensor] = None,
                backend: str = "auto", chunk: int = 2_000_000) -> DenseMarch:
    r"""First ``f(t_i) ≥ 0 > f(t_{i+1})`` bracket on ``steps`` uniform intervals of each pixel's clipped ray.

    Args:
        surface: the implicit surface protocol (``bounds``; ``drjit_f`` for Dr.Jit, ``f`` for torch).
        camera: rays as :func:`ssbench.reference.implicit` (``camera_rays(..., dtype=float64)``).
        steps: number of uniform intervals (samples ``steps + 1``).
        batch, jitter: as :func:`~ssbench.rays.camera_rays`.
        backend: ``"auto"`` (Dr.Jit when a JIT variant works and the surface has ``drjit_f``), ``"drjit"``
            or ``"torch"``.
        chunk: torch backend: samples evaluated per chunk (memory ≈ 100 bytes per sample).

    Returns:
        :class:`DenseMarch`.

    Example:
        >>> from ssbench.camera import Camera
        >>> class Plate:                                  # |z| − 0.01: a slab of chord 0.02 on the axis
        ...     bounds = ((-1, -1, -0.01), (1, 1, 0.01))
        ...     def f(self, p): return p[..., 2].abs() - 0.01
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 10.0, 1, 1, 0.1, 10.0)
        >>> dm = dense_march(Plate(), cam, steps=10, backend="torch")
        >>> bool(dm.hit), float(dm.t_lo) <= 3.99 < float(dm.t_hi)
        (True, True)
    """
    if isinstance(steps, bool) or not isinstance(steps, int) or steps <= 0:
        raise ValueError(f"steps: must be a positive integer, got {steps!r}")
    if backend not in BACKENDS:
        raise ValueError(f"backend: must be one of {BACKENDS}, got {backend!r}")
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk <= 0:
        raise ValueError(f"chunk: must be a positive integer, got {chunk!r}")
    bounds = getattr(surface, "bounds", None)
    if bounds is None or len(bounds) != 2 or any(len(b) != 3 for b in bounds):
        raise ValueError(f"surface.bounds: expected ((x0, y0, z0), (x1, y1, z1)), got {bounds!r}")
    start = time.perf_counter()
    o, d, tn, tf, img = flat_rays(camera, batch, jitter)
    t0, t1 = clip_to_bounds(o, d, tn, tf, bounds)
    use = backend
    if backend == "auto":
        use = "drjit" if callable(getattr(surface, "drjit_f", None)) and _jit_module() is not None else "torch"
    if use == "drjit":
        if not callable(getattr(surface, "drjit_f", None)):
            raise TypeError(f"surface: backend='drjit' needs a callable drjit_f(x, y, z), "
                            f"got {type(surface).__name__}")
        if _jit_module() is None:
            raise RuntimeError("backend='drjit' needs a vectorised Dr.Jit variant (libLLVM >= 17); "
                               "use backend='torch' or apt-get install -y libllvm19")
        found, i = _march_drjit(surface, o, d, t0, t1, steps)
    else:
        if not callable(getattr(surface, "f", None)):
            raise TypeError(f"surface: backend='torch' needs a callable f(p), got {type(surface).__name__}")
        found, i = _march_torch(surface, o, d, t0, t1, steps, chunk)
    valid = t1 > t0
    found = found & valid
    dt = torch.where(valid, (t1 - t0) / steps, 0.0)
    base = torch.where(valid, t0, 0.0)
    lo = torch.where(found, base + i.to(torch.float64) * dt, tf)
    hi = torch.where(found, base + (i + 1).to(torch.float64) * dt, tf)
    return DenseMarch(hit=img(found), t_lo=img(lo), t_hi=img(hi), t_start=img(torch.where(valid, t0, tf)),
                      t_end=img(torch.where(valid, t1, tf)), steps=steps, backend=use,
                      seconds=time.perf_counter() - start)

