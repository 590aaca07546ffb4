"""Temporal accumulation of a screen-space effect: reproject last frame's output, reject what the depth says is
new, clamp it to the current neighbourhood, blend (the TAA-style resolve real-time AO ships with; Karis,
"High Quality Temporal Supersampling", SIGGRAPH 2014 Advances in Real-Time Rendering,
https://advances.realtimerendering.com/s2014/).

Per frame, with the current G-buffer and the previous frame's camera and view depth:

1. **Reproject**: the pixel's view position → world (minus the surface's own motion since the last frame, when
   motion vectors are given: :func:`object_motion`) → the previous camera's view → its pixel; the previous
   output and view depth are read there (bilinear, ``grid_sample``, pixel centres at half-integers).
2. **Reject** (disocclusion): the history is invalid off the previous screen, on its background, or where the
   previous depth there differs from the reprojected depth by more than ``depth_tolerance`` (relative).
3. **Clamp** (``clamp="minmax"``): the history is clamped to the min/max of the current output over the 3×3
   neighbourhood, which bounds ghosting where the rejection misses (``"none"``: no clamp).
4. **Blend**: ``out = lerp(history, current, alpha)`` where the history is valid, ``current`` elsewhere.

With a still camera and ``clamp="none"`` this is the exponential moving average of the frames, exactly (tested).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import torch
import torch.nn.functional as F

from ..camera import Camera
from ..gbuffer import GBuffer

__all__ = ["AccumulationParams", "reproject", "accumulate", "TemporalAccumulator", "CLAMPS", "object_motion"]

CLAMPS = ("minmax", "none")


@dataclass(frozen=True)
class AccumulationParams:
    """Settings of :func:`accumulate`.

    Args:
        alpha: the current frame's weight (0.1: about ten frames of history, as TAA resolves ship).
        clamp: ``"minmax"`` (3×3 neighbourhood clamp) or ``"none"``.
        depth_tolerance: relative view-depth mismatch beyond which the history is rejected (``math.inf``: never;
            TXAA on a still camera relies on the clamp alone, since the jitter moves silhouettes every frame).
        background: also resolve background pixels (a shaded image whose background is a colour, as an implicit
            render's sky; ``False``: AO or reflections, undefined there, pass through).
    """

    alpha: float = 0.1
    clamp: str = "minmax"
    depth_tolerance: float = 0.02
    background: bool = False

    def __post_init__(self) -> None:
        if isinstance(self.alpha, bool) or not isinstance(self.alpha, (int, float)) or not 0 < self.alpha <= 1:
            raise ValueError(f"alpha: must be a number in (0, 1], got {self.alpha!r}")
        if self.clamp not in CLAMPS:
            raise ValueError(f"clamp: expected one of {CLAMPS}, got {self.clamp!r}")
        t = self.depth_tolerance
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not 0 < t <= float("inf"):
            raise ValueError(f"depth_tolerance: must be a number > 0 (inf: no rejection), got {t!r}")
        if not isinstance(self.background, bool):
            raise ValueError(f"background: expected a bool, got {self.background!r}")


def object_motion(gbuffer: GBuffer, shape: int, displacement) -> torch.Tensor:
    """:math:`(B, 3, H, W)` motion vectors in world units (where each pixel's surface point is now minus where it
    was last frame) for one rigidly translated shape: ``displacement`` on the pixels whose G-buffer ``shape_id``
    is ``shape``, 0 elsewhere (static geometry and background).

    Example:
        >>> import torch
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 2), (0, 0, 0), (0, 1, 0), 60.0, 2, 1, 0.1, 10.0)
        >>> g = GBuffer(camera=cam, view_z=-torch.ones(1, 1, 1, 2), shape_id=torch.tensor([[[[0, 1]]]]))
        >>> object_motion(g, 1, (0.5, 0.0, 0.0))[0, 0].tolist()
        [[0.0, 0.5]]
    """
    if gbuffer.shape_id is None:
        raise ValueError("gbuffer: object motion needs the shape_id channel")
    d = torch.as_tensor(displacement, dtype=gbuffer.view_z.dtype, device=gbuffer.view_z.device)
    if d.shape != (3,) or not bool(torch.isfinite(d).all()):
        raise ValueError(f"displacement: expected three finite numbers, got {displacement!r}")
    on = (gbuffer.shape_id == int(shape)).to(d.dtype)
    return on * d.view(1, 3, 1, 1)


def reproject(history: torch.Tensor, prev_camera: Camera, prev_view_z: torch.Tensor, gbuffer: GBuffer,
              depth_tolerance: float = 0.02, motion: Optional[torch.Tensor] = None, background: bool = False
              ) -> tuple[torch.Tensor, torch.Tensor]:
    """``(history_here, valid)``: last frame's :math:`(B, C, H, W)` ``history`` read at where each current pixel
    was (bilinear), and :math:`(B, 1, H, W)` where that is trusted (see the module docstring, steps 1–2).
    ``motion``: :math:`(B, 3, H, W)` world-space motion vectors (:func:`object_motion`; ``None``: a static
    world, only the camera moves). ``background``: background pixels may keep history too."""
    from .. import checks
    checks.check_shape(history, ["B", "C", "H", "W"], "history")
    checks.check_shape(prev_view_z, ["B", "1", "H", "W"], "prev_view_z")
    cam = gbuffer.camera
    z = gbuffer.view_z
    dt = history.dtype
    pos = cam.uv_to_view(cam.uv_grid(dt, z.device).unsqueeze(0), z.to(dt))           # (B, 3, H, W) view
    world = cam.view_to_world(pos, dim=1)
    if motion is not None:
        checks.check_shape(motion, ["B", "3", "H", "W"], "motion")
        world = world - motion.to(dt)
    prev = prev_camera.world_to_view(world, dim=1)
    px = prev_camera.view_to_pixel(prev, dim=1)                                         # (B, 2, H, W)
    W, H = prev_camera.width, prev_camera.height
    grid = torch.stack([px[:, 0] / W * 2 - 1, px[:, 1] / H * 2 - 1], -1)                # align_corners=False
    grid = torch.nan_to_num(grid, nan=-2.0, posinf=-2.0, neginf=-2.0)
    sample = lambda img: F.grid_sample(img.to(dt), grid, mode="bilinear", padding_mode="border",   # noqa: E731
                                       align_corners=False)
    here = sample(history)
    prev_z = sample(prev_view_z)
    inside = ((grid.abs() <= 1).all(-1) & (prev[:, 2] < 0)).unsqueeze(1)
    agree = (prev_z - prev[:, 2:3]).abs() <= depth_tolerance * prev[:, 2:3].abs()   # inf: every finite mismatch
    valid = inside & agree if background else inside & agree & gbuffer.mask
    return here, valid


def _neighbourhood(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    hi = F.max_pool2d(x, 3, 1, 1)
    lo = -F.max_pool2d(-x, 3, 1, 1)
    return lo, hi


def accumulate(current: torch.Tensor, history: torch.Tensor, valid: torch.Tensor,
               params: AccumulationParams = AccumulationParams()) -> torch.Tensor:
    """One resolve (steps 3–4): ``current`` and reprojected ``history`` :math:`(B, C, H, W)`, ``valid``
    :math:`(B, 1, H, W)` → the accumulated frame.

    Example:
        >>> cur, hist = torch.zeros(1, 1, 2, 2), torch.ones(1, 1, 2, 2)
        >>> ok = torch.ones(1, 1, 2, 2, dtype=torch.bool)
        >>> accumulate(cur, hist, ok, AccumulationParams(alpha=0.25, clamp="none"))[0, 0, 0, 0].item()
        0.75
    """
    if params.clamp == "minmax":
        lo, hi = _neighbourhood(current)
        history = torch.minimum(torch.maximum(history, lo), hi)
    blended = history + (current - history) * params.alpha
    return torch.where(valid, blended, current)


class TemporalAccumulator:
    """Frame-by-frame state of :func:`accumulate`: ``step(current, gbuffer)`` returns the accumulated frame and
    remembers it, the camera and the view depth for the next frame (the first frame passes through)."""

    def __init__(self, params: AccumulationParams = AccumulationParams()) -> None:
        if not isinstance(params, AccumulationParams):
            raise TypeError(f"params: expected AccumulationParams, got {type(params).__name__}")
        self.params = params
        self._prev: Optional[tuple] = None
        self.valid: Optional[torch.Tensor] = None                   # the last step's trusted-history mask

    def step(self, current: torch.Tensor, gbuffer: GBuffer, motion: Optional[torch.Tensor] = None) -> torch.Tensor:
        """One frame: ``current`` :math:`(B, C, H, W)` with its G-buffer, and the motion vectors since the last
        frame (:func:`object_motion`; ``None``: nothing but the camera moved)."""
        if self._prev is None:
            out = current
            self.valid = torch.zeros_like(gbuffer.mask)
        else:
            history, cam, z = self._prev
            here, self.valid = reproject(history, cam, z, gbuffer, self.params.depth_tolerance, motion,
                                         self.params.background)
            out = accumulate(current, here, self.valid, self.params)
        self._prev = (out, gbuffer.camera, gbuffer.view_z)
        return out
