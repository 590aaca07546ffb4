"""SSR fades of the SSR article (§1.4 screen-edge fade, §1.5 distance fade), as pure tensor functions.

Fades hide failures, so every SSR pass also returns its raw, unfaded colour (``SSRResult.raw_color``).

**Screen edge (§1.4)**, two forms, both of a uv ``(u, v)`` in [0, 1]² (v up; both are symmetric in ``v ↔ 1 − v``
so the row flip does not matter):

* ``"circular"``: ``uvFactor = (2·|uv − (0.5, 0.5)|)²``, ``edge = max(0, 1 − uvFactor)``: 1 at the centre, 0 on
  the circle touching the middle of each edge and beyond (the corners are always 0).
* ``"vignette"``: ``edgeuv = uv·(1 − uv.yx)``, ``edge = saturate(|edgeuv.x·edgeuv.y·EdgeDistance|^EdgeExponent)``
  ``= saturate((u(1−u)·v(1−v)·EdgeDistance)^EdgeExponent)``: 0 on every edge, ``(EdgeDistance/16)^EdgeExponent``
  (saturated) at the centre.

**Distance (§1.5)**: ``saturate(1 − (d / FadeDistance)^FadeExponent)`` with ``d = length(rayOrg − hitPoint)``.

Defaults are the article demo's uniforms (``mebiusbox/ssr`` ``ssr.html``: ``EdgeDistance 50``,
``EdgeExponent 1``, ``FadeDistance 10``, ``FadeExponent 1``; its comments name 15 and 0.25 as older defaults).
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from ..common import check_positive

EDGE_FADE_MODES = ("circular", "vignette")


def edge_fade(hit_pixel: torch.Tensor, width: int, height: int, edge_distance: float = 50.0,
              edge_exponent: float = 1.0, mode: str = "vignette", dim: int = 1) -> torch.Tensor:
    """Screen-edge fade (SSR article §1.4) at continuous pixel coordinates ``(px, py)``.

    .. math::
        \\text{circular: } \\max(0, 1 - 4\\,|uv - \\tfrac12|^2) \\qquad
        \\text{vignette: } \\operatorname{sat}\\big((u(1-u)\\,v(1-v)\\,E_d)^{E_e}\\big)

    Args:
        hit_pixel: :math:`(B, 2, *S)` pixel coordinates (``px`` right, ``py`` down, see ``CONVENTIONS.md``);
            the component axis is ``dim``.
        width, height: image size ``W``, ``H`` in pixels (``u = px / W``, ``v = 1 − py / H``).
        edge_distance: ``EdgeDistance`` (vignette only), ≥ 0.
        edge_exponent: ``EdgeExponent`` (vignette only), > 0.
        mode: ``"circular"`` or ``"vignette"``.

    Returns:
        :math:`(B, 1, *S)` fade weight in [0, 1] (size 1 on ``dim``).

    Raises:
        ValueError: bad ``mode``, size or parameter (the message names it).

    Example:
        >>> px = torch.tensor([[8.0, 6.0], [0.0, 6.0], [16.0, 0.0]]).T[None]       # centre, left edge, corner
        >>> edge_fade(px, 16, 12, mode="circular").flatten().tolist()
        [1.0, 0.0, 0.0]
        >>> edge_fade(px, 16, 12, edge_distance=8.0, edge_exponent=1.0).flatten().tolist()
        [0.5, 0.0, 0.0]
    """
    if mode not in EDGE_FADE_MODES:
        raise ValueError(f"mode: expected one of {EDGE_FADE_MODES}, got {mode!r}")
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
            raise ValueError(f"{name}: must be a positive integer, got {v!r}")
    if hit_pixel.shape[dim] != 2:
        raise ValueError(f"hit_pixel: dimension {dim} must have 2 components, got shape {tuple(hit_pixel.shape)}")
    px, py = hit_pixel.unbind(dim)
    u, v = px / width, 1.0 - py / height                       # NOTE: the row flip (py down, v up)
    if mode == "circular":
        uvFactor = 2.0 * torch.sqrt((u - 0.5) ** 2 + (v - 0.5) ** 2)     # 2·length(hitPixel − 0.5)
        uvFactor = uvFactor * uvFactor
        edge = torch.clamp(1.0 - uvFactor, min=0.0)
    else:
        check_positive(edge_distance, "edge_distance", allow_zero=True)
        check_positive(edge_exponent, "edge_exponent")
        edgeuv_x, edgeuv_y = u * (1.0 - v), v * (1.0 - u)       # edgeuv = vUv·(1 − vUv.yx)
        edge = edgeuv_x * edgeuv_y * edge_distance
        edge = torch.clamp(torch.pow(edge.abs(), edge_exponent), 0.0, 1.0)
    return edge.unsqueeze(dim)


def distance_fade(ray_distance: torch.Tensor, fade_distance: float = 10.0,
                  fade_exponent: float = 1.0) -> torch.Tensor:
    """Distance fade (SSR article §1.5): ``saturate(1 − pow(d / FadeDistance, FadeExponent))``.

    Args:
        ray_distance: any shape, ``d = length(rayOrg − hitPoint)`` ≥ 0 in view-space units.
        fade_distance: ``FadeDistance`` > 0 (the distance where the reflection has faded out).
        fade_exponent: ``FadeExponent`` > 0.

    Returns:
        Fade weight in [0, 1], the shape of ``ray_distance``.

    Example:
        >>> distance_fade(torch.tensor([0.0, 5.0, 10.0, 20.0]), 10.0, 2.0).tolist()
        [1.0, 0.75, 0.0, 0.0]
    """
    check_positive(fade_distance, "fade_distance")
    check_positive(fade_exponent, "fade_exponent")
    d = ray_distance.abs()                                      # a length; abs() keeps pow real for −0.0
    return torch.clamp(1.0 - torch.pow(d / fade_distance, fade_exponent), 0.0, 1.0)


@dataclass(frozen=True, kw_only=True)
class FadeParams:
    """The fades every SSR pass applies (§1.4–1.5), shared by their parameter classes (which inherit these fields,
    keyword-only, so ``--param fade_distance=…`` and the rows stay flat).

    Attributes:
        edge_distance, edge_exponent: ``EdgeDistance`` (≥ 0), ``EdgeExponent`` (> 0) of the §1.4 vignette.
        edge_fade_mode: ``"vignette"`` (the demo's) or ``"circular"``.
        fade_distance, fade_exponent: ``FadeDistance``, ``FadeExponent`` (§1.5), both > 0.
    """

    edge_distance: float = 50.0
    edge_exponent: float = 1.0
    edge_fade_mode: str = "vignette"
    fade_distance: float = 10.0
    fade_exponent: float = 1.0

    def __post_init__(self) -> None:
        check_positive(self.edge_distance, "edge_distance", allow_zero=True)
        for name in ("edge_exponent", "fade_distance", "fade_exponent"):
            check_positive(getattr(self, name), name)
        if self.edge_fade_mode not in EDGE_FADE_MODES:
            raise ValueError(f"edge_fade_mode: expected one of {EDGE_FADE_MODES}, got {self.edge_fade_mode!r}")

    def fade(self, hit_pixel: torch.Tensor, pixel_centre: torch.Tensor, width: int, height: int,
             distance: torch.Tensor) -> torch.Tensor:
        """``edge · distance`` fade: the edge term at ``hit_pixel`` (``"circular"``) or at the ray's own pixel
        centre ``pixel_centre`` (``"vignette"``, the demo's ``vUv``), both :math:`(B, 2, *S)`; ``distance`` is
        :math:`(B, 1, *S)` ``|rayOrg − hitPoint|``. Returns :math:`(B, 1, *S)` in [0, 1]."""
        at = hit_pixel if self.edge_fade_mode == "circular" else pixel_centre
        return edge_fade(at, width, height, self.edge_distance, self.edge_exponent, self.edge_fade_mode) * \
            distance_fade(distance, self.fade_distance, self.fade_exponent)
