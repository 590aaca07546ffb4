"""Screen-space reflections by a *supercover* DDA: every pixel the projected ray crosses, each fetched once.

The McGuire–Mara DDA (:mod:`.dda`, SSR article §2.2) samples one pixel per major-axis line: at stride 1 it never
samples a pixel twice and never skips a line (Fig. 11, right), but a pixel whose corner the segment clips is not
sampled. A thin occluder that covers only such a corner pixel is invisible to it. This pass walks the same
segment ``P0 → P1`` cell by cell in the order the segment enters them (Amanatides & Woo 1987, "A Fast Voxel
Traversal Algorithm", a DDA over the pixel grid): per ray it keeps the line parameters ``tMaxX``/``tMaxY`` of the
next column and row edge (in major-axis pixels ``n`` from ``P0``, after :mod:`.dda`'s ``permute``) and
steps across whichever edge comes first; both at a lattice corner, which the segment crosses in no pixel's
interior. So it fetches exactly the pixels :func:`~ssbench.passes.ssr.visits.crossed_pixels` lists, once each,
up to where the ray stops (the origin pixel excepted, as in the DDA).

Everything else is the DDA's: the same near-plane clipping, homogeneous pixel-space endpoints and degenerate-line
nudge (``ssr.dda.dda_rays`` at stride 1, no jitter), ``Q`` and ``k = 1/w`` linear in screen space (appendix A), the
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
equal ``max_steps`` budget a diagonal ray runs out sooner. Terminations as :mod:`.dda`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Optional

import torch
from torch import nn

from ...gbuffer import GBuffer
from ..common import check_count
from .common import BEHIND_CAMERA, HIT, MAX_DISTANCE, OFF_SCREEN, OUT_OF_STEPS, SSRResult
from ..gbuffer_checks import half_in_float32
from .dda import DEFAULTS_SOURCE, EQUAL_SETTINGS, REQUIRES, DDASSRParams, check_inputs, dda_rays, ray_pixels
from .dda_march import count_visits, ray_view_z
from .dda_assemble import assemble
from .dda_state import DDARays, MarchOutput, march_in_chunks
from .fade import FadeParams
from ..registry import Method, SpeedPanel

__all__ = ["METHOD", "REQUIRES", "EQUAL_SETTINGS", "DEFAULTS_SOURCE", "SupercoverDDASSRParams",
           "ssr_dda_supercover", "SupercoverDDASSR", "CellWalk", "cell_setup"]


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


@dataclass(kw_only=True)
class CellWalk(DDARays):
    """:class:`~ssbench.passes.ssr.dda_state.DDARays` plus the Amanatides–Woo cell state, each :math:`(N,)`
    (permuted frame, ``n`` in major-axis pixels from ``P0``): cell ``cx, cy``; edge parameters ``tx, ty``
    (``tMaxX/Y``); ``ddy`` (``tDeltaY``; ``tDeltaX = 1``); ``sy`` (``stepY``; ``stepX = stepDir``); ``nEnd``
    (``P1``); ``Wm, Hm``: the image's size along the major and minor axes."""

    cx: torch.Tensor
    cy: torch.Tensor
    tx: torch.Tensor
    ty: torch.Tensor
    ddy: torch.Tensor
    sy: torch.Tensor
    nEnd: torch.Tensor
    Wm: torch.Tensor
    Hm: torch.Tensor


def cell_setup(s: DDARays, H: int, W: int) -> CellWalk:
    """The cell walk's start from the DDA's set-up ``s`` (``ssr.dda.dda_rays`` at stride 1, no jitter)."""
    sd, dPy = s.stepDir, s.dPy
    cx, cy = s.Px.floor(), s.Py.floor()
    safe = torch.where(dPy != 0, dPy, 1.0)
    ty = torch.where(dPy > 0, (cy + 1 - s.Py) / safe, (cy - s.Py) / safe)
    return CellWalk(**{f.name: getattr(s, f.name) for f in fields(s)}, cx=cx, cy=cy,
                    tx=((cx + (sd > 0).to(cx.dtype)) - s.Px) * sd, ty=torch.where(dPy != 0, ty, math.inf),
                    ddy=torch.where(dPy != 0, 1.0 / safe.abs(), math.inf), sy=torch.sign(dPy), nEnd=s.end - s.Px * sd,
                    Wm=torch.where(s.permute, float(H), float(W)), Hm=torch.where(s.permute, float(W), float(H)))


def hit_at(h: DDARays, nA, nB, zA, sceneZMax):
    """``n`` of the hit: ``nA`` if the ray enters the cell at or behind ``sceneZMax``, else where it crosses
    ``z = sceneZMax`` (perspective-correct: ``Q_z(n) = sceneZMax·k(n)``), clamped to ``[nA, nB]``."""
    den = h.dQz - sceneZMax * h.dk
    n_star = (sceneZMax * h.k - h.Qz) / torch.where(den != 0, den, 1.0)
    n_star = torch.where((den != 0) & torch.isfinite(n_star), n_star, nA)
    return torch.where(zA <= sceneZMax, nA, torch.minimum(torch.maximum(n_star, nA), nB))


def supercover_march(s: DDARays, tex, z_thickness: float, max_steps: int, H: int, W: int,
                     visits: Optional[torch.Tensor]) -> MarchOutput:
    """The cell walk; per-ray outputs by ``s.i``. Finished rays freeze, dropped when 1/8 of ``s``."""
    N = s.count
    out = MarchOutput.empty(N, s.k.dtype, s.k.device, OUT_OF_STEPS)
    c = cell_setup(s, H, W)
    c.alive, dead = torch.ones(N, dtype=torch.bool, device=s.k.device), 0
    for _ in range(max_steps):
        if c.count == dead:
            break
        nA = torch.minimum(c.tx, c.ty)                                              # edge crossed into the cell
        stepx, stepy = c.tx <= c.ty, c.ty <= c.tx                                   # both: through a corner
        c.cx, c.tx = torch.where(stepx, c.cx + c.stepDir, c.cx), torch.where(stepx, c.tx + 1, c.tx)
        c.cy, c.ty = torch.where(stepy, c.cy + c.sy, c.cy), torch.where(stepy, c.ty + c.ddy, c.ty)
        nB = torch.minimum(torch.minimum(c.tx, c.ty), c.nEnd)                       # where it leaves (or P1)
        past = c.alive & (nA >= c.nEnd)
        off = c.alive & ~past & ((c.cx < 0) | (c.cx >= c.Wm) | (c.cy < 0) | (c.cy >= c.Hm))
        live = c.alive & ~past & ~off
        px, py = torch.where(c.permute, c.cy, c.cx), torch.where(c.permute, c.cx, c.cy)
        t = c.b * (H * W) + py.clamp(0, H - 1).long() * W + px.clamp(0, W - 1).long()
        sceneZMax, m = tex[0][t], tex[1][t]
        zA = ray_view_z(c.Qz + c.dQz * nA, c.k + c.dk * nA, c.zlo, c.zhi)
        zB = ray_view_z(c.Qz + c.dQz * nB, c.k + c.dk * nB, c.zlo, c.zhi)
        rayZMin, rayZMax = torch.minimum(zA, zB), torch.maximum(zA, zB)
        hit = live & m & (rayZMax >= sceneZMax - z_thickness) & (rayZMin <= sceneZMax)
        count_visits(out, visits, c.i, t, live)
        hi = hit.nonzero().squeeze(1)
        if hi.numel():
            h = c.select(hi)
            n = hit_at(h, nA[hi], nB[hi], zA[hi], sceneZMax[hi])
            inside = lambda v, cell: torch.minimum(torch.maximum(v, cell), torch.nextafter(cell + 1, cell))  # noqa: E731
            x, y = inside(h.Px + h.stepDir * n, h.cx), inside(h.Py + h.dPy * n, h.cy)
            out.P[h.i] = torch.where(h.permute[:, None], torch.stack([y, x], 1), torch.stack([x, y], 1))
            out.Q[h.i] = torch.stack([h.Q0x + h.dQx * n, h.Q0y + h.dQy * n, h.Qz + h.dQz * n], 1)
            out.k[h.i] = h.k + h.dk * n
        ended = torch.where(c.clipped, BEHIND_CAMERA, MAX_DISTANCE)
        term = torch.where(past, ended, torch.where(off, OFF_SCREEN, HIT))
        done = past | off | hit
        di = done.nonzero().squeeze(1)
        if di.numel():
            out.term[c.i[di]] = term[di].to(torch.int8)
            c.alive, dead = c.alive & ~done, dead + di.numel()
            if 8 * dead >= c.count:                                                 # compact
                c, dead = c.select(c.alive.nonzero().squeeze(1)), 0
    return out


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
    tex = (g64.view_z.reshape(-1), g64.mask.reshape(-1))
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
