"""Rebuild view-space position and normals from a depth buffer, the way the articles' shaders do.

* :func:`position_from_depth` — both SSAO-article ways: ``"inverse_projection"`` (SSAO ``getViewPosition``,
  §2.2) and ``"uv_to_view"`` (HBAO ``viewPos``/``uvToView`` with ``UvToViewParams``, §3.3).
* :func:`normals_from_position` — the HBAO ``minDiff`` tangents (§3.3): of the two one-sided differences
  toward the left/right (or bottom/top) neighbour, take the shorter; the normal is ``dPdu × dPdv``.
"""
from __future__ import annotations

import torch
import torch.nn.functional as F

from . import checks
from .camera import Camera
from .passes.common import cross, length as vector_length


def position_from_depth(depth: torch.Tensor, camera: Camera, method: str = "uv_to_view") -> torch.Tensor:
    """View-space positions of pixel centres from a GL depth buffer.

    Args:
        depth: :math:`(B, 1, H, W)` GL depth buffer values in [0, 1].
        camera: the camera that rendered ``depth``.
        method: ``"uv_to_view"`` (HBAO, SSAO article §3.3) or ``"inverse_projection"`` (SSAO, §2.2).

    Returns:
        :math:`(B, 3, H, W)` view-space positions.

    Example:
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
        >>> d = cam.view_z_to_depth(torch.full((1, 1, 3, 4), -2.0, dtype=torch.float64))
        >>> position_from_depth(d, cam)[0, 2, 0, 0].item()
        -2.0
    """
    checks.check_shape(depth, ["B", "1", str(camera.height), str(camera.width)], "depth")
    uv = camera.uv_grid(depth.dtype, depth.device).unsqueeze(0)          # (1, 2, H, W)
    if method == "uv_to_view":
        return camera.uv_to_view(uv, camera.depth_to_view_z(depth))
    if method == "inverse_projection":
        return camera.view_position_from_depth(uv.expand(depth.shape[0], -1, -1, -1), depth)
    raise ValueError(f"method: expected 'uv_to_view' or 'inverse_projection', got {method!r}")


def _min_diff(p: torch.Tensor, forward: torch.Tensor, backward: torch.Tensor,
              fwd_ok: torch.Tensor, bwd_ok: torch.Tensor) -> torch.Tensor:
    """HBAO ``minDiff``: the shorter of ``forward − P`` and ``P − backward`` (missing neighbours lose)."""
    v1, v2 = forward - p, p - backward
    l1 = torch.where(fwd_ok, (v1 * v1).sum(1, keepdim=True), torch.full_like(v1[:, :1], float("inf")))
    l2 = torch.where(bwd_ok, (v2 * v2).sum(1, keepdim=True), torch.full_like(v2[:, :1], float("inf")))
    return torch.where(l1 < l2, v1, v2)


def normals_from_position(position: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Unit view-space normals from a position buffer by HBAO's ``minDiff`` (SSAO article §3.3).

    ``dPdu`` is taken toward the right/left neighbours and ``dPdv`` toward the upper/lower ones (``v`` up, so
    "upper" is row − 1). Neighbours outside the image or off ``mask`` are never chosen. Pixels with no valid
    neighbour on an axis, and pixels off ``mask``, get the zero vector.

    Args:
        position: :math:`(B, 3, H, W)` view-space positions.
        mask: optional :math:`(B, 1, H, W)` bool, True on geometry.

    Returns:
        :math:`(B, 3, H, W)` unit normals facing the camera side (``n · (−P) > 0`` on front faces).
    """
    checks.check_shape(position, ["B", "3", "H", "W"], "position")
    B, _, H, W = position.shape
    if mask is None:
        mask = torch.ones(B, 1, H, W, dtype=torch.bool, device=position.device)
    checks.check_same_size(position, mask, "position", "mask")
    p = F.pad(position, (1, 1, 1, 1), mode="replicate")                   # (B, 3, H+2, W+2)
    m = F.pad(mask.to(torch.uint8), (1, 1, 1, 1), value=0).bool()         # out-of-image = invalid
    c = (slice(None), slice(None))
    right, left = p[c + (slice(1, -1), slice(2, None))], p[c + (slice(1, -1), slice(0, -2))]
    up, down = p[c + (slice(0, -2), slice(1, -1))], p[c + (slice(2, None), slice(1, -1))]
    m_r, m_l = m[c + (slice(1, -1), slice(2, None))], m[c + (slice(1, -1), slice(0, -2))]
    m_u, m_d = m[c + (slice(0, -2), slice(1, -1))], m[c + (slice(2, None), slice(1, -1))]
    dpdu = _min_diff(position, right, left, m_r, m_l)
    dpdv = _min_diff(position, up, down, m_u, m_d)
    n = cross(dpdu, dpdv, dim=1)
    length = vector_length(n)
    ok = mask & (m_r | m_l) & (m_u | m_d) & (length > 0)
    return torch.where(ok, n / length.clamp_min(torch.finfo(n.dtype).tiny), torch.zeros_like(n))


def normals_from_depth(depth: torch.Tensor, camera: Camera, mask: torch.Tensor | None = None) -> torch.Tensor:
    """:func:`normals_from_position` of :func:`position_from_depth` (``uv_to_view`` way)."""
    return normals_from_position(position_from_depth(depth, camera), mask)
