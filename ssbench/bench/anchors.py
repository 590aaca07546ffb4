"""Outside anchors for the speed axis: hemisphere SSAO's sample loop and the linear SSR march, each written as one
Dr.Jit (LLVM) kernel (:func:`ssao_anchor`, :func:`linear_ssr_anchor`).

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

__all__ = ["ssao_anchor", "linear_ssr_anchor"]


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


def linear_ssr_anchor(gbuffer, params, generator: Optional[torch.Generator] = None) -> Optional[Callable[[], dict]]:
    """A call running the linear SSR march (SSR article §1.2–1.3) as one Dr.Jit kernel per ray, or ``None`` (no
    LLVM backend here). The rays are set up once, here, by the pass's own §1.1–1.2
    (:func:`ssbench.passes.ssr.linear_rays.linear_rays`); the call marches them — ``Q += deltaStep``, project,
    fetch the ``NEAREST`` texel, the thickness test, stop at a hit or off screen — then bisects the hits, with
    the same float32 operations in the same order as :mod:`ssbench.passes.ssr.linear_march`, and returns
    ``{"termination", "steps", "hit_view"}`` images equal to the torch pass's (tested). Its time is the march's
    alone (the set-up, the colour fetch and the fades are not in it), so a pass/anchor ratio slightly flatters
    the anchor.

    Args:
        gbuffer: as for :func:`~ssbench.passes.ssr.linear.ssr_linear` (float32).
        params: :class:`~ssbench.passes.ssr.linear.LinearSSRParams` without back-face depth (``ValueError``).
        generator: draws the jitter, as the pass does.
    """
    from ..passes.ssr.common import BEHIND_CAMERA, HIT, MAX_DISTANCE, NO_RAY, OFF_SCREEN, OUT_OF_STEPS
    from ..passes.ssr.linear import MAX_BINARY_SEARCH_ITERATIONS
    from ..passes.ssr.linear_rays import linear_rays
    if params.use_back_face_depth:
        raise ValueError("params: the anchor transcribes the constant-thickness test (use_back_face_depth=False)")
    if gbuffer.view_z.dtype != torch.float32:
        raise ValueError(f"gbuffer: the anchor runs float32, got view_z {gbuffer.view_z.dtype}")
    llvm = drjit_llvm()
    if llvm is None:
        return None
    import drjit as dr
    Float, UInt32, Int32, Bool = llvm.Float, llvm.UInt32, llvm.Int32, llvm.Bool
    rays = linear_rays(gbuffer, params, generator)
    cam, test = gbuffer.camera, rays.test
    B, _, H, W = gbuffer.view_z.shape
    n = rays.ray.numel()

    def up(x: torch.Tensor) -> list:                          # (n, 3) -> three Dr.Jit arrays
        return [Float(x[:, c].contiguous().cpu().numpy()) for c in range(3)]

    O, dS, Q0 = up(rays.origin), up(rays.delta), up(rays.start)
    clipped, base = Bool(rays.clipped.cpu().numpy()), UInt32(rays.base.to(torch.int32).cpu().numpy())
    scene_z, mask = Float(test.scene_z.contiguous().cpu().numpy()), Bool(test.mask.cpu().numpy())
    f32 = lambda v: float(torch.tensor(v, dtype=torch.float32))               # noqa: E731  torch's scalar cast
    a_x, a_y, neg_t = f32(cam.focal / cam.aspect), f32(cam.focal), f32(-test.thickness)
    n_run, n_bs = min(params.iterations, params.max_iterations), min(params.binary_search_iterations,
                                                                      MAX_BINARY_SEARCH_ITERATIONS)
    ended = OUT_OF_STEPS if n_run < params.iterations else None

    def texel(x, y, z, active):                               # project, NEAREST texel, rayIntersectsDepth
        w = -z
        u, v = (a_x * x / w) * 0.5 + 0.5, (a_y * y / w) * 0.5 + 0.5
        col, row = dr.floor(u * W), dr.floor((1.0 - v) * H)
        col = dr.clip(dr.select(dr.isnan(col), 0, col), 0, W - 1)
        row = dr.clip(dr.select(dr.isnan(row), 0, row), 0, H - 1)
        t = base + UInt32(Int32(row)) * UInt32(W) + UInt32(Int32(col))
        dist = z - dr.gather(Float, scene_z, t, active)
        hit = (dist < 0) & (dist > neg_t) & dr.gather(Bool, mask, t, active)
        return (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1), hit

    def body(i, x, y, z, alive, term, steps, hit_i, hx, hy, hz):
        x, y, z = x + dS[0], y + dS[1], z + dS[2]                              # Q += deltaStep
        on, hit = texel(x, y, z, alive)
        hit &= on
        stop = hit | ~on
        term = dr.select(hit, HIT, dr.select(stop, OFF_SCREEN, term))
        steps = dr.select(stop, Int32(i) + 1, steps)
        hit_i = dr.select(hit, Int32(i), hit_i)
        hx, hy, hz = dr.select(hit, x, hx), dr.select(hit, y, hy), dr.select(hit, z, hz)
        return i + 1, x, y, z, alive & ~stop, term, steps, hit_i, hx, hy, hz

    def call() -> dict:
        zero = dr.zeros(Float, n)
        state = (dr.zeros(UInt32, n), *Q0, dr.full(Bool, True, n), dr.full(Int32, NO_RAY, n), dr.zeros(Int32, n),
                 dr.full(Int32, -1, n), zero, zero, zero)
        _, _, _, _, alive, term, steps, hit_i, hx, hy, hz = dr.while_loop(
            state, lambda i, x, y, z, alive, *rest: alive & (i < n_run), body)
        last = dr.select(clipped, BEHIND_CAMERA, MAX_DISTANCE) if ended is None else Int32(ended)
        term, steps = dr.select(alive, last, term), dr.select(alive, n_run, steps)
        best = [hx, hy, hz]
        found = term == HIT
        if n_bs > 0:                                                           # §1.3 on the hits
            first = hit_i == 0
            qb = [dr.select(first, O[c], best[c] - dS[c]) for c in range(3)]
            step = [dr.select(first, best[c] - O[c], dS[c]) for c in range(3)]
            orig, stride = 0.5, Float(0.5)
            for _ in range(n_bs):
                qb = [qb[c] + step[c] * stride for c in range(3)]
                _, hb = texel(*qb, found)
                best = [dr.select(hb, qb[c], best[c]) for c in range(3)]
                orig *= 0.5
                stride = dr.select(hb, -orig, orig)
            steps = dr.select(found, steps + n_bs, steps)
        dr.eval(term, steps, *best)
        ray = rays.ray
        out_term = torch.full((B * H * W,), NO_RAY, dtype=torch.int8)
        out_steps = torch.zeros(B * H * W, dtype=torch.int32)
        hit_view = torch.zeros(B * H * W, 3)
        t_term = term.torch().to(torch.int8)
        out_term[ray], out_steps[ray] = t_term, steps.torch()
        h = t_term == HIT
        hit_view[ray[h]] = torch.stack([b.torch() for b in best], 1)[h]
        img = lambda x, c: x.reshape(B, H, W, c).permute(0, 3, 1, 2)           # noqa: E731
        return {"termination": img(out_term, 1), "steps": img(out_steps, 1), "hit_view": img(hit_view, 3)}

    for _ in range(2):                                        # trace and compile now, not while timed
        call()
    return call
