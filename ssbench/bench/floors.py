"""The floors a pass is timed against: what the same number of texel reads costs with nothing else around them.

A pass that reads ``K`` depth texels per pixel cannot be faster than ``K`` reads per pixel; the ratio of its time
to a floor's, measured side by side in one process (:mod:`ssbench.bench.timing`), says how much of its time is
the method's arithmetic and framework overhead rather than memory traffic. Two floors:

* :func:`torch_floor` — the *torch gather floor*: ``K`` reads per pixel of the texture at random texels, one
  ``index_select`` per sample into one reused :math:`(B·H·W)` buffer. The indices come from a pool of at most
  :data:`POOL` rows of int32 texel ids drawn once (outside the timed call), so the floor's own working set is
  ``POOL`` index rows and one output row, whatever ``K`` and the image size: it has no cache cliff of its own.
  (Materialising ``(B, K, H, W)`` int64 column and row blocks, as the first floor did, made the floor itself
  leave the cache from 640×360 on and read 37× slower than this one at ``K = 32``.)
* :func:`fused_floor` — the *fused floor*: the same count of random reads as one Dr.Jit (LLVM) kernel, a loop
  over the samples in which every pixel hashes its texel id (PCG, O'Neill 2014) and adds the texel to a register:
  no index memory and one pass over the pixels — what a hand-written kernel of the same reads costs. ``None``
  when Dr.Jit has no working LLVM backend here (:mod:`ssbench.reference.backend`) or the texture is not on the
  CPU.
"""
from __future__ import annotations

from typing import Any, Callable, Optional

import torch

__all__ = ["POOL", "torch_floor", "fused_floor", "drjit_llvm"]

#: index rows the torch floor cycles through (sample ``k`` reads at row ``k mod POOL``)
POOL = 8


def _check(texture: torch.Tensor, samples: int) -> None:
    if not isinstance(texture, torch.Tensor) or texture.dim() != 4:
        raise ValueError(f"texture: expected a (B, C, H, W) tensor, got {getattr(texture, 'shape', texture)!r}")
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ValueError(f"samples: must be an integer >= 1, got {samples!r}")


def torch_floor(texture: torch.Tensor, samples: int, seed: int = 0) -> Callable[[], torch.Tensor]:
    """The torch gather floor of ``samples`` reads per pixel of ``texture`` :math:`(B, C, H, W)` (its first
    channel), as a call returning the last sample's reads :math:`(B·H·W,)`; ``call.index_pool`` is its
    ``(min(POOL, samples), B·H·W)`` index pool.

    Example:
        >>> z = torch.arange(12.0).view(1, 1, 3, 4)
        >>> out = torch_floor(z, 5)()
        >>> out.shape, bool(((out >= 0) & (out < 12)).all())
        (torch.Size([12]), True)
    """
    _check(texture, samples)
    flat = texture[:, :1].reshape(-1).contiguous()
    n = flat.numel()
    gen = torch.Generator().manual_seed(seed)
    index_dtype = torch.int32 if n < 2 ** 31 else torch.int64
    pool = torch.randint(0, n, (min(POOL, samples), n), generator=gen).to(index_dtype).to(texture.device)
    out = torch.empty_like(flat)

    def call() -> torch.Tensor:
        for k in range(samples):
            torch.index_select(flat, 0, pool[k % len(pool)], out=out)
        return out

    call.index_pool = pool                                  # type: ignore[attr-defined]  (what it holds)
    return call


def drjit_llvm() -> Optional[Any]:
    """``drjit.llvm`` when the backend chosen for this process has a working libLLVM, else ``None``."""
    from ..reference import backend
    try:
        if backend.choice().libllvm is None:
            return None
        backend.mitsuba()                                   # sets DRJIT_LIBLLVM_PATH before drjit loads
        import drjit.llvm as llvm
        return llvm
    except Exception:
        return None


def fused_floor(texture: torch.Tensor, samples: int, seed: int = 0) -> Optional[Callable[[], Any]]:
    """The fused floor of ``samples`` reads per pixel of ``texture`` (its first channel) as a call, or ``None``
    (no LLVM backend, or a texture off the CPU). The kernel is compiled here (Dr.Jit caches it on disk), so
    the call's time is the reads'. It runs on Dr.Jit's worker threads (all cores unless the process set
    otherwise, ``ssbench info``): changing Dr.Jit's thread count inside a process that also writes EXR files
    through Mitsuba hung that process (OpenEXR's pool), so the floor never changes it.

    Example:
        >>> z = torch.arange(12.0).view(1, 1, 3, 4)
        >>> call = fused_floor(z, 5)
        >>> call is None or len(call()) == 12                   # one sum of five reads per pixel
        True
    """
    _check(texture, samples)
    if texture.device.type != "cpu":
        return None
    llvm = drjit_llvm()
    if llvm is None:
        return None
    import drjit as dr
    Float, UInt32 = llvm.Float, llvm.UInt32
    flat = texture[:, :1].reshape(-1).to(torch.float32).contiguous()
    n = flat.numel()
    tex = Float(flat.numpy())
    salt, count, size = UInt32(seed * 2654435761 % 2 ** 32), UInt32(samples), UInt32(n)

    def pcg(v):                                             # PCG-RXS-M-XS 32 (O'Neill 2014), one round
        state = v * UInt32(747796405) + UInt32(2891336453)
        word = ((state >> ((state >> 28) + 4)) ^ state) * UInt32(277803737)
        return (word >> 22) ^ word

    def call():
        pixel = dr.arange(UInt32, n)

        def body(k, acc):
            return k + 1, acc + dr.gather(Float, tex, pcg(pixel * count + k + salt) % size)

        _, acc = dr.while_loop((UInt32(0), dr.zeros(Float, n)), lambda k, acc: k < count, body)
        dr.eval(acc)
        dr.sync_thread()
        return acc

    for _ in range(2):              # trace and compile now, not while timed (a cold cache compiles on both calls)
        call()
    return call
