"""Shading of implicit-surface hits: the unit normal ``∇f/|∇f|`` and which object of a union was hit.

Shared by the ray casters (``ssbench.passes.implicit_*``) and the certified reference (``ssbench.reference``),
so the truth never imports the passes it checks.
"""
from __future__ import annotations

import torch

__all__ = ["safe_normal", "shade_hits"]


def safe_normal(grad: torch.Tensor) -> torch.Tensor:
    """``∇f/|∇f|`` along the last axis; 0 where the gradient is 0 or not finite (never NaN)."""
    n = grad.norm(dim=-1, keepdim=True)
    ok = torch.isfinite(n) & (n > 0)
    return torch.where(ok, grad / torch.where(ok, n, torch.ones_like(n)), torch.zeros_like(grad))


def shade_hits(surface, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Unit normals (n, 3) and object indices (n,) int32 at hit points (n, 3): one ``f_and_grad`` (counted as
    one evaluation by the callers) and ``object_index`` (0 if the surface has none). The gradient is taken outside
    inference mode (the ray casters run in it, :func:`ssbench.passes.inference.autograd_free`), on a normal copy
    of inference-tensor points."""
    if points.shape[0] == 0:
        return points.new_zeros(0, 3), torch.zeros(0, dtype=torch.int32, device=points.device)
    with torch.inference_mode(False):          # ∇f by autograd, also for a caller in inference mode (a pass is)
        at = points.clone() if points.is_inference() else points
        if hasattr(surface, "f_and_grad"):
            _, g = surface.f_and_grad(at)
        else:
            with torch.enable_grad():
                q = at.detach().requires_grad_(True)
                (g,) = torch.autograd.grad(surface.f(q).sum(), q, allow_unused=True)
            g = torch.zeros_like(at) if g is None else g.detach()
    idx = surface.object_index(points) if hasattr(surface, "object_index") else torch.zeros(
        points.shape[:-1], dtype=torch.long, device=points.device)
    return safe_normal(g.to(points.dtype)), idx.to(torch.int32)
