"""three.js ``GTAOShader`` on a band of image rows, as :mod:`ssbench.passes.ao.three_gtao` runs it band by band:
the band's per-pixel frame (step 1, :func:`band_frame`) and, one direction at a time, the slice, its horizon march
and the arc integral (steps 2–4, :func:`slice_visibility`). Both are the pass's compilable kernels
(:mod:`ssbench.passes.compiled`); the direction's rotation is a tensor argument, so one compilation serves all.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import torch

from ..common import component_dot, component_norm, cross, fetch_texels, gl_texel, nan_to_zero, vector_norm
from ..compiled import kernel

if TYPE_CHECKING:
    from .three_gtao import ThreeGTAOParams

__all__ = ["BandFrame", "band_frame", "slice_visibility", "cos_to_sample", "view_position", "dot", "normalize"]


def view_position(minv: torch.Tensor, u, v, d) -> torch.Tensor:
    """``getViewPosition``: ``(P⁻¹ · (2(u, v, d) − 1, 1)).xyz / w`` of ``(B, *S)`` coordinates → ``(B, 3, *S)``."""
    clip = (u * 2.0 - 1.0, v * 2.0 - 1.0, d * 2.0 - 1.0, torch.ones_like(u))
    q = [sum(minv[i, k] * clip[k] for k in range(4)) for i in range(4)]
    return torch.stack(q[:3], 1) / q[3].unsqueeze(1)


def dot(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``dot`` of ``(B, 3, *S)`` vectors → ``(B, *S)``."""
    return (a * b).sum(1)


def normalize(a: torch.Tensor) -> torch.Tensor:
    """``normalize`` of ``(B, 3, *S)`` vectors (a zero vector gives NaN, as in GLSL)."""
    return a / vector_norm(a)


class BandFrame(NamedTuple):
    """A band's per-pixel frame (step 1 of :mod:`.three_gtao`), each :math:`(B, 3, h, W)` unless said otherwise."""

    view_pos: torch.Tensor     #: ``viewPos``
    view_dir: torch.Tensor     #: ``normalize(−viewPos)``
    normal: torch.Tensor       #: ``viewNormal``
    tangent: torch.Tensor      #: the noise-turned frame ``(t, b)`` about view z
    bitangent: torch.Tensor
    w: torch.Tensor            #: :math:`(B, h, W)` ``0.5 + 0.5·noise.w``, the radius jitter


@kernel
def band_frame(minv: torch.Tensor, uv: torch.Tensor, depth: torch.Tensor, normal: torch.Tensor,
               noise: torch.Tensor) -> BandFrame:
    """Step 1 on a band of rows: ``uv`` :math:`(B, 2, h, W)`, ``depth`` :math:`(B, 1, h, W)` (GL depth), ``normal``
    :math:`(B, 3, h, W)` and ``noise`` :math:`(B, 4, h, W)` of the band's pixels; ``minv`` the inverse projection."""
    view_pos = view_position(minv, uv[:, 0], uv[:, 1], depth[:, 0])                       # (B, 3, h, W)
    rnd = noise[:, :3] * 2.0 - 1.0
    zero = torch.zeros_like(rnd[:, 0])
    tangent = normalize(torch.stack([rnd[:, 0], rnd[:, 1], zero], 1))
    bitangent = torch.stack([-tangent[:, 1], tangent[:, 0], zero], 1)
    return BandFrame(view_pos, normalize(-view_pos), normal, tangent, bitangent, 0.5 + 0.5 * noise[:, 3])


def cos_to_sample(minv: torch.Tensor, u, v, d, frame: "BandFrame") -> tuple[torch.Tensor, torch.Tensor]:
    """``dot(viewDir, normalize(samplePos − viewPos))`` and ``(samplePos − viewPos).z`` :math:`(B, h, W)` of the
    sample at ``(u, v, d)``, on components: :func:`view_position`, :func:`normalize` and :func:`dot`'s bits, and
    compiled, no stored stack and no reduction per sample."""
    clip = (u * 2.0 - 1.0, v * 2.0 - 1.0, d * 2.0 - 1.0, torch.ones_like(u))
    q = [sum(minv[i, k] * clip[k] for k in range(4)) for i in range(4)]
    delta = [q[c] / q[3] - frame.view_pos[:, c] for c in range(3)]
    length = component_norm(*delta)
    return component_dot(frame.view_dir.unbind(1), [c / length for c in delta]), delta[2]


@kernel
def slice_visibility(frame: BandFrame, depth: torch.Tensor, proj: torch.Tensor, minv: torch.Tensor,
                     rotation: torch.Tensor, params: "ThreeGTAOParams") -> torch.Tensor:
    """Steps 2–4 for one direction on a band: its slice, its two horizons and their arc integral.

    A NaN ``gain`` counts 0 (the shader's ``max(0, NaN)`` on the GPU), written as
    :func:`~ssbench.passes.common.nan_to_zero` instead of ``nan_to_num``: a ``gain`` is finite or NaN (a cosine of
    unit vectors minus one, times a constant), so the two agree, and inductor vectorises this form.

    Args:
        frame: the band's :class:`BandFrame`; depth: :math:`(B, 1, H, W)` the whole GL depth buffer;
        proj, minv: :math:`(4, 4)` the projection matrix and its inverse;
        rotation: :math:`(2,)` ``(cos, sin)`` of the direction's angle ``iπ/DIRECTIONS``.

    Returns:
        :math:`(B, h, W)` ``nx·½(acos h₂ − acos h₁ + sin h₁ cos h₁ − sin h₂ cos h₂) + ny·½(2 − cos²h₁ − cos²h₂)``.
    """
    p, f = params, frame
    B, _, H, W = depth.shape
    steps = p.steps
    sample_dir = normalize(f.tangent * rotation[0] + f.bitangent * rotation[1])
    slice_bitangent = normalize(cross(sample_dir, f.view_dir, dim=1))
    slice_tangent = cross(slice_bitangent, f.view_dir, dim=1)
    n_slice = normalize(f.normal - slice_bitangent * dot(f.normal, slice_bitangent).unsqueeze(1))
    to_normal = cross(n_slice, slice_bitangent, dim=1)
    cos_h = [dot(f.view_dir, to_normal), dot(f.view_dir, -to_normal)]
    for j in range(steps):
        offset = sample_dir * (p.radius * f.w * ((j + 1) / steps) ** p.distance_exponent).unsqueeze(1)
        for side, sign in ((0, 1.0), (1, -1.0)):
            q = f.view_pos + sign * offset
            clip = [sum(proj[r, k] * (q[:, k] if k < 3 else 1.0) for k in range(4)) for r in (0, 1, 3)]
            su, sv = clip[0] / clip[2] * 0.5 + 0.5, clip[1] / clip[2] * 0.5 + 0.5      # getSceneUvAndDepth
            sd = fetch_texels(depth, *gl_texel(su, sv, H, W)).reshape(su.shape)
            c, delta_z = cos_to_sample(minv, su, sv, sd, f)
            gain = nan_to_zero((c - cos_h[side]) * (1.0 + (2.0 / (j + 2) - 1.0) * p.distance_fall_off))
            cos_h[side] = torch.where(delta_z.abs() < p.thickness, cos_h[side] + gain.clamp_min(0.0), cos_h[side])
    h1, h2 = cos_h[0].clamp(-1.0, 1.0), cos_h[1].clamp(-1.0, 1.0)
    s1, s2 = (1.0 - h1 * h1).clamp_min(0.0).sqrt(), (1.0 - h2 * h2).clamp_min(0.0).sqrt()
    nx, ny = dot(n_slice, slice_tangent), dot(n_slice, f.view_dir)
    nxb = 0.5 * (torch.acos(h2) - torch.acos(h1) + s1 * h1 - s2 * h2)
    nyb = 0.5 * (2.0 - h1 * h1 - h2 * h2)
    return nx * nxb + ny * nyb
