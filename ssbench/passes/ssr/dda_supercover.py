"""Screen-space reflections by a *supercover* DDA: every pixel the projected ray crosses, each fetched once.

The McGuire–Mara DDA (:mod:`.dda`, SSR article §2.2) samples one pixel per major-axis line: at stride 1 it never
samples a pixel twice and never skips a line (Fig. 11, right), but a pixel whose corner the segment clips is not
sampled. A thin occluder that covers only such a corner pixel is invisible to it. This pass walks the same
segment ``P0 → P1`` cell by cell in the order the segment enters them (J. Amanatides and A. Woo, "A Fast Voxel
Traversal Algorithm for Ray Tracing", Eurographics 1987, http://www.cse.yorku.ca/~amana/research/grid.pdf: a DDA over
the pixel grid): per ray it keeps the line parameters ``tMaxX``/``tMaxY`` of the next column and row edge (in
major-axis pixels ``n`` from ``P0``, after :mod:`.dda`'s ``permute``) and steps across whichever edge comes first;
both at a lattice corner, which the segment crosses in no pixel's interior. So it fetches exactly the pixels
:func:`~ssbench.passes.ssr.visits.crossed_pixels` lists, once each, up to where the ray stops (the origin pixel
excepted, as in the DDA).

Everything else is the DDA's: the same near-plane clipping, homogeneous pixel-space endpoints and degenerate-line
nudge (``ssr.dda_rays.dda_rays`` at stride 1, no jitter), ``Q`` and ``k = 1/w`` linear in screen space (appendix A), the
same box test per texel. Only the z interval is exact: the ray enters the cell at ``nA`` and leaves at ``nB``
(or at ``P1``), so

.. math::
    \\{\\text{rayZMin}, \\text{rayZMax}\\} = \\{z(n_A), z(n_B)\\}, \\quad z(n) = \\frac{Q_z + n\\,dQ_z}{k + n\\,dk},
    \\qquad \\text{hit} \\iff \\text{rayZMax} \\ge \\text{sceneZMax} - \\text{zThickness} \\wedge
    \\text{rayZMin} \\le \\text{sceneZMax}

— the DDA's "half step" is this interval for the footprint ``[P − ½dP, P + ½dP]`` of a whole column. No refinement
is needed: the hit point is where the ray crosses the texel's plane ``z = sceneZMax`` inside ``[nA, nB]``
(``n* = (sceneZMax·k − Q_z) / (dQ_z − sceneZMax·dk)``), or ``nA`` if the ray enters the cell already behind it,
clamped into the hit cell. The cost: up to ``|Δx| + |Δy|`` fetches per ray instead of ``max(|Δx|, |Δy|)``, so at an
equal ``max_steps`` budget a diagonal ray runs out sooner. Terminations as :mod:`.dda`. The walk itself, one cell
per step for every ray (several steps per call when compiled, :mod:`ssbench.passes.compiled`), is in
:mod:`.dda_supercover_walk`.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import check_count
from .common import SSRResult
from ..gbuffer_checks import half_in_float32
from ..inference import autograd_free
from .dda import DEFAULTS_SOURCE, EQUAL_SETTINGS, REQUIRES, DDASSRParams, check_inputs, depth_texels
from .dda_rays import dda_rays, ray_pixels
from .dda_assemble import assemble
from .dda_state import march_in_chunks
from .dda_supercover_walk import supercover_march
from .fade import FadeParams
from ..registry import Method, SpeedPanel

__all__ = ["METHOD", "REQUIRES", "EQUAL_SETTINGS", "DEFAULTS_SOURCE", "SupercoverDDASSRParams",
           "ssr_dda_supercover", "SupercoverDDASSR"]


@dataclass(frozen=True)
class SupercoverDDASSRParams(FadeParams):
    """Parameters of :func:`ssr_dda_supercover`, named as :class:`~ssbench.passes.ssr.dda.DDASSRParams`.

    Attributes:
        max_ray_distance: ``MaxRayDistance``, view-space ray length before near-plane clipping.
        max_steps: the most pixels fetched per ray (a budget in depth reads, like the DDA's ``maxSteps``).
        z_thickness: ``zThickness``, view-space depth of every depth texel.
        edge_distance, edge_exponent, edge_fade_mode, fade_distance, fade_exponent: the fades (§1.4–1.5),
            inherited keyword-only from :class:`~ssbench.passes.ssr.fade.FadeParams`.

    There is no stride, jitter or refinement: the walk is one pixel at a time and the hit is exact in its cell.
    """

    max_ray_distance: float = 10.0
    max_steps: int = 256
    z_thickness: float = 0.1

    def __post_init__(self) -> None:
        super().__post_init__()                                                   # the fades
        check_count(self.max_steps, "max_steps")
        self.dda()                                                                 # the DDA checks the numbers

    def dda(self) -> DDASSRParams:
        """The :class:`DDASSRParams` whose set-up this pass shares (stride 1, no jitter)."""
        return DDASSRParams(max_ray_distance=self.max_ray_distance, max_steps=self.max_steps, pixel_stride=1.0,
                            z_thickness=self.z_thickness, jitter=0.0,
                            **{f.name: getattr(self, f.name) for f in fields(FadeParams)})


@autograd_free
@half_in_float32
def ssr_dda_supercover(gbuffer: GBuffer, params: SupercoverDDASSRParams = SupercoverDDASSRParams(), *,
                       generator: Optional[torch.Generator] = None, debug: bool = False) -> SSRResult:
    """Screen-space reflections walking every pixel the reflected ray's screen segment crosses, vectorised.

    Args:
        gbuffer: needs ``view_z``, ``normal`` (unit, view space), ``mask`` and ``color``, all :math:`(B, C, H, W)`.
        params: :class:`SupercoverDDASSRParams`.
        generator: unused (the walk draws nothing); accepted so every SSR pass takes the same call.
        debug: add ``visits`` :math:`(B, 1, H, W)` (depth fetches per texel over all rays) and ``ray_end``
            :math:`(B, 2, H, W)` (``P1`` in pixels, −1 off ``mask``).

    Returns:
        :class:`~ssbench.passes.ssr.common.SSRResult` as :func:`~ssbench.passes.ssr.dda.ssr_dda`; ``steps``
        counts the pixels fetched.

    Raises:
        ValueError: missing channels, bad values (the message names the argument).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 10.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 6, 8), -2.0), normal=n,
        ...             mask=torch.ones(1, 1, 6, 8, dtype=torch.bool), color=torch.ones(1, 3, 6, 8))
        >>> r = ssr_dda_supercover(g)               # a wall facing the camera reflects toward the camera
        >>> r.hit.any().item(), r.termination.unique().tolist(), r.color.shape
        (False, [2], torch.Size([1, 3, 6, 8]))
    """
    if not isinstance(params, SupercoverDDASSRParams):
        raise TypeError(f"params: expected SupercoverDDASSRParams, got {type(params).__name__}")
    dda = params.dda()
    check_inputs(gbuffer, dda)
    B, _, H, W = gbuffer.view_z.shape
    zero = torch.zeros(B, 1, H, W, dtype=torch.float64)
    # The walk runs in float64 whatever the input dtype: which of two cells a ray enters at a pixel corner is a
    # discrete choice, and float32 rounding flipped it on 13 of 3072 cornell_box pixels (another texel's colour).
    g64 = gbuffer.select(("view_z", "normal", "mask")).to(dtype=torch.float64)   # the walk reads no colour
    sel = ray_pixels(g64)
    visits = torch.zeros(B * H * W, dtype=torch.int32, device=gbuffer.view_z.device) if debug else None
    tex = depth_texels(g64, dda)                     # view z and mask, and view z with NaN off the mask (the walk's)
    o, P1 = march_in_chunks(sel, lambda part: dda_rays(g64, dda, zero, part),
                            lambda rays: supercover_march(rays, tex, params.z_thickness, params.max_steps, H, W,
                                                          visits))               # bounded working set
    return assemble(gbuffer, params, sel, P1, o, visits)


class SupercoverDDASSR(nn.Module):
    """``nn.Module`` wrapper of :func:`ssr_dda_supercover`; ``forward(gbuffer)`` returns its :class:`SSRResult`."""

    def __init__(self, params: SupercoverDDASSRParams = SupercoverDDASSRParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer) -> SSRResult:
        return ssr_dda_supercover(gbuffer, self.params, debug=self.debug)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("dda_supercover", ssr_dda_supercover, SupercoverDDASSRParams, SupercoverDDASSR, order=30,
                title="supercover DDA: every crossed pixel once")

#: the debug buffers the report draws (``debug=True`` results): buffer -> caption; each is a per-pixel count
#: shown on a log scale (the SSR article's Fig. 11 visit map)
DEBUG_VIEWS = {"visits": "depth fetches per texel"}
#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"max_steps": [32, 128]}]}
SPEED_PANELS = (SpeedPanel("hits", "max_steps", (("z_thickness", 0.1),)),)
#: the depth-read budget of an equal-reads comparison (ssbench.analysis.equal_reads): the parameter that caps
#: reads, and the settings that make every read count:
#: one read per crossed pixel
READ_BUDGET = ("max_steps", {})
