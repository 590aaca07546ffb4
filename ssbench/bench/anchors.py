"""An outside anchor for the speed axis: hemisphere SSAO's sample loop written as one Dr.Jit (LLVM) kernel.

The torch pass (:func:`ssbench.passes.ao.ssao.hemisphere_ssao`) runs the SSAO article's §2.2 sample loop as ~30
tensor operations per band of rows, each its own trip through memory. :func:`ssao_anchor` is the same loop as
a shader would run it: per pixel, a loop over the ``K`` kernel samples in registers — build ``samplePoint``,
project it, fetch the depth texel, compare, count — traced once by Dr.Jit into one fused CPU kernel. It reads
the same inputs (:func:`ssbench.passes.ao.ssao.hemisphere_frame`: positions, the TBN frame, the kernel, the
depth texture) and does the same float32 operations in the same order, so its counts equal the torch pass's
(tested). Its time is what "the same method written as one kernel" costs on this machine: the bar against
which the torch pass (eager or compiled) is measured in ``benchmarks/bench_passes.py``.
"""
from __future__ import annotations

from typing import Any, Callable, Optional

import torch

from .floors import drjit_llvm

__all__ = ["ssao_anchor"]


def ssao_anchor(gbuffer, params, generator: Optional[torch.Generator] = None) -> Optional[Callable[[], Any]]:
    """A call running hemisphere SSAO's sample loop as one Dr.Jit kernel and returning the :math:`(B, 1, H, W)`
    int32 count of samples that pass the range check, or ``None`` (no LLVM backend here). The inputs are drawn
    and uploaded once, here, and the kernel compiled, so the call's time is the loop's.

    Args:
        gbuffer: as for :func:`~ssbench.passes.ao.ssao.hemisphere_ssao` (float32; float64 is run in float32).
        params: :class:`~ssbench.passes.ao.ssao.HemisphereSSAOParams`.
        generator: draws the kernel and the noise, as the pass does.

    It runs on Dr.Jit's worker threads as they are (see :func:`~ssbench.bench.floors.fused_floor`: the count is
    never changed here).
    """
    from ..passes.ao.ssao import hemisphere_frame
    llvm = drjit_llvm()
    if llvm is None:
        return None
    import drjit as dr
    Float, UInt32, Int32 = llvm.Float, llvm.UInt32, llvm.Int32
    fr = hemisphere_frame(gbuffer, params, generator)
    cam, p = gbuffer.camera, params
    B, _, H, W = gbuffer.view_z.shape
    n_px = B * H * W

    def channels(x: torch.Tensor) -> list:                    # (B, C, H, W) -> C flat Dr.Jit arrays
        x = x.detach().to(torch.float32).cpu()
        return [Float(x[:, c].reshape(-1).contiguous().numpy()) for c in range(x.shape[1])]

    pos, t, b, n = channels(fr.position), channels(fr.tangent), channels(fr.bitangent), channels(fr.normal)
    tex = channels(fr.texture)[0]
    kern = [Float(fr.kernel[:, c].detach().to(torch.float32).cpu().contiguous().numpy()) for c in range(3)]
    base = (dr.arange(UInt32, n_px) // UInt32(H * W)) * UInt32(H * W)          # each pixel's image in the batch
    f32 = lambda v: float(torch.tensor(v, dtype=torch.float32))               # noqa: E731  torch's scalar cast
    a_x, a_y, radius = f32(cam.focal / cam.aspect), f32(cam.focal), f32(p.kernel_radius)
    near, far = cam.near, cam.far
    nf, fmn, f_, n_, nmf = f32(near * far), f32(far - near), f32(far), f32(near), f32(near - far)
    tiny = -float(torch.finfo(torch.float32).tiny)
    lo, hi = f32(p.min_distance), f32(p.max_distance)
    from_depth = p.position_from == "depth"

    def ortho(z):                                             # viewZToOrthographicDepth
        return (z + n_) / nmf

    def body(k, count):
        kx, ky, kz = (dr.gather(Float, kern[c], k) for c in range(3))
        sv = [(t[c] * kx + b[c] * ky) + n[c] * kz for c in range(3)]         # kernelMatrix · Kernel[i]
        sx, sy, sz = (pos[c] + sv[c] * radius for c in range(3))             # samplePoint
        zp = dr.select(sz == 0, tiny, sz)
        w = -zp
        u = (a_x * sx / w) * 0.5 + 0.5                                        # NDC -> uv (v up)
        v = (a_y * sy / w) * 0.5 + 0.5
        col, row = dr.floor(u * W), dr.floor((1.0 - v) * H)                   # NEAREST, CLAMP_TO_EDGE
        col = dr.clip(dr.select(dr.isnan(col), 0, col), 0, W - 1)            # (NaN reads texel 0, as torch)
        row = dr.clip(dr.select(dr.isnan(row), 0, row), 0, H - 1)
        real = dr.gather(Float, tex, base + UInt32(Int32(row)) * UInt32(W) + UInt32(Int32(col)))
        if from_depth:
            real = nf / (fmn * real - f_)                                     # perspectiveDepthToViewZ
        delta = ortho(sz) - ortho(real)
        return k + 1, count + dr.select((delta > lo) & (delta < hi), 1, 0)

    def call():
        _, count = dr.while_loop((UInt32(0), dr.zeros(Int32, n_px)), lambda k, c: k < p.kernel_size, body)
        dr.eval(count)
        return count.torch().reshape(B, 1, H, W)

    for _ in range(2):                                        # trace and compile now, not while timed
        call()
    return call
