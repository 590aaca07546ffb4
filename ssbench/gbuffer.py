"""The G-buffer: a frozen dataclass of ``(B, C, H, W)`` tensors that carries a frame between stages.

Every channel is optional: the reference backend renders only the channels a pass asks for
(``ssbench.reference.gbuffer(..., channels=...)``). Background pixels (``mask`` False) hold documented fill
values (:data:`FILL`), chosen to be what a rasteriser's cleared buffers would hold, so a screen-space pass
sees exactly what it would see on a GPU.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Optional, Sequence

import torch

from . import checks
from .camera import Camera

#: channel name → number of channels
CHANNELS: dict[str, int] = {"view_z": 1, "normal": 3, "position": 3, "albedo": 3, "roughness": 1,
                            "metallic": 1, "shape_id": 1, "mask": 1, "back_z": 1, "color": 3,
                            "second_z": 1}

#: fill values on background pixels (``view_z``/``position`` fill is the far plane: GL depth 1).
FILL: dict[str, str] = {
    "view_z": "-far (GL depth buffer value 1.0)",
    "position": "the far-plane point on the pixel's ray, uv_to_view(uv, -far)",
    "normal": "(0, 0, 0)",
    "albedo": "(0, 0, 0)",
    "roughness": "1",
    "metallic": "0",
    "shape_id": "-1",
    "mask": "False",
    "back_z": "-inf (also on hits whose exit through the object was not found, e.g. open rectangles)",
    "color": "the radiance of the environment seen through the pixel",
    "second_z": "-inf (also where nothing lies behind the first object, or behind an open surface)",
}


@dataclass(frozen=True)
class GBuffer:
    """A frame of view-space surface data with its :class:`~ssbench.camera.Camera`.

    Args:
        camera: the camera all channels were rendered with (``H × W`` = its resolution).
        view_z: :math:`(B, 1, H, W)` view-space z of the first hit (negative in front of the camera).
        normal: :math:`(B, 3, H, W)` unit view-space shading normal, turned to face the camera.
        position: :math:`(B, 3, H, W)` view-space position of the first hit.
        albedo: :math:`(B, 3, H, W)` linear RGB diffuse albedo.
        roughness: :math:`(B, 1, H, W)` in [0, 1].
        metallic: :math:`(B, 1, H, W)` in [0, 1].
        shape_id: :math:`(B, 1, H, W)` int32 index into ``scene.shapes``; −1 on background.
        mask: :math:`(B, 1, H, W)` bool, True where the pixel-centre ray hits geometry.
        back_z: :math:`(B, 1, H, W)` view z where the ray leaves the first object it entered.
        color: :math:`(B, 3, H, W)` path-traced linear RGB.
        second_z: :math:`(B, 1, H, W)` view z of the second depth layer: the first surface the eye ray meets
            behind the first object (after its exit, ``back_z``; after the hit itself for an open surface).

    Background fill values are listed in :data:`FILL`.
    """

    camera: Camera
    view_z: Optional[torch.Tensor] = None
    normal: Optional[torch.Tensor] = None
    position: Optional[torch.Tensor] = None
    albedo: Optional[torch.Tensor] = None
    roughness: Optional[torch.Tensor] = None
    metallic: Optional[torch.Tensor] = None
    shape_id: Optional[torch.Tensor] = None
    mask: Optional[torch.Tensor] = None
    back_z: Optional[torch.Tensor] = None
    color: Optional[torch.Tensor] = None
    second_z: Optional[torch.Tensor] = None

    def __post_init__(self) -> None:
        if not isinstance(self.camera, Camera):
            raise TypeError(f"camera: expected a Camera, got {type(self.camera).__name__}")
        if not checks.checks_enabled():
            return
        batch = None
        for name, c in CHANNELS.items():
            t = getattr(self, name)
            if t is None:
                continue
            checks.check_shape(t, ["B", str(c), str(self.camera.height), str(self.camera.width)], name)
            if batch is not None and t.shape[0] != batch:
                raise ValueError(f"{name}: batch size {t.shape[0]} differs from the other channels' {batch}")
            batch = t.shape[0]
            if name == "mask" and t.dtype != torch.bool:
                raise TypeError(f"mask: expected dtype torch.bool, got {t.dtype}")
            if name == "shape_id" and (t.is_floating_point() or t.dtype == torch.bool):
                raise TypeError(f"shape_id: expected an integer dtype, got {t.dtype}")
            if name not in ("mask", "shape_id") and not t.is_floating_point():
                raise TypeError(f"{name}: expected a floating-point dtype, got {t.dtype}")

    # ------------------------------------------------------------------ introspection
    @property
    def channels(self) -> tuple[str, ...]:
        """Names of the channels present."""
        return tuple(n for n in CHANNELS if getattr(self, n) is not None)

    def require(self, *names: str) -> None:
        """Raise ``ValueError`` naming the channels a pass needs but this G-buffer lacks."""
        missing = [n for n in names if getattr(self, n, None) is None]
        if missing:
            raise ValueError(f"gbuffer: missing channel(s) {', '.join(missing)}; render them with "
                             f"ssbench.reference.gbuffer(..., channels=(...))")

    @property
    def batch_size(self) -> int:
        for n in self.channels:
            return getattr(self, n).shape[0]
        return 0

    @property
    def height(self) -> int:
        return self.camera.height

    @property
    def width(self) -> int:
        return self.camera.width

    # ------------------------------------------------------------------ derived depth encodings
    @property
    def depth(self) -> torch.Tensor:
        """:math:`(B, 1, H, W)` GL depth buffer value in [0, 1] (1 on background)."""
        self.require("view_z")
        return self.camera.view_z_to_depth(self.view_z)

    @property
    def linear_depth(self) -> torch.Tensor:
        """:math:`(B, 1, H, W)` linear (orthographic) depth ``(z + n) / (n − f)`` in [0, 1]."""
        self.require("view_z")
        return self.camera.view_z_to_orthographic_depth(self.view_z)

    # ------------------------------------------------------------------ transformations
    def to(self, device=None, dtype: Optional[torch.dtype] = None) -> "GBuffer":
        """Move every channel to ``device``; cast floating channels to ``dtype`` (masks and ids keep theirs).

        ``g.to(torch.float64)`` (a dtype in the device slot) is read as ``dtype``, as ``Tensor.to`` does.
        """
        if isinstance(device, torch.dtype):
            if dtype is not None:
                raise TypeError(f"device: got the dtype {device} while dtype={dtype} is given too")
            device, dtype = None, device
        if dtype is not None and not isinstance(dtype, torch.dtype):
            raise TypeError(f"dtype: expected a torch.dtype, got {dtype!r}")
        out = {}
        for n in self.channels:
            t = getattr(self, n)
            out[n] = t.to(device=device, dtype=dtype if (dtype is not None and t.is_floating_point()) else None)
        return replace(self, **out)

    def select(self, channels: Sequence[str]) -> "GBuffer":
        """A G-buffer holding only ``channels`` (the others become ``None``)."""
        unknown = [c for c in channels if c not in CHANNELS]
        if unknown:
            raise ValueError(f"channels: unknown channel(s) {unknown}; known: {list(CHANNELS)}")
        self.require(*channels)
        return replace(self, **{n: (getattr(self, n) if n in channels else None) for n in CHANNELS})

    @classmethod
    def cat(cls, items: Sequence["GBuffer"]) -> "GBuffer":
        """Concatenate G-buffers of the same camera and channels along the batch dimension."""
        if not items:
            raise ValueError("items: need at least one GBuffer")
        cam, chans = items[0].camera, items[0].channels
        for i, g in enumerate(items):
            if g.camera != cam:
                raise ValueError(f"items[{i}]: camera differs from items[0]; a batch shares one camera")
            if g.channels != chans:
                raise ValueError(f"items[{i}]: channels {g.channels} differ from items[0] {chans}")
        return cls(cam, **{n: torch.cat([getattr(g, n) for g in items], 0) for n in chans})

    def as_dict(self) -> dict[str, torch.Tensor]:
        """``{channel: tensor}`` of the channels present."""
        return {n: getattr(self, n) for n in self.channels}


def field_names() -> list[str]:
    """All dataclass field names (camera first)."""
    return [f.name for f in fields(GBuffer)]

