"""The per-ray state of the DDA marchers (SSR article §2.2; McGuire & Mara 2014), as dataclasses instead of dicts.

:class:`DDARays` is what the set-up (:func:`~ssbench.passes.ssr.dda_rays.dda_rays`) hands the march: every ray that
starts, flat over ``N`` rays, in the *permuted* frame (the major axis first, G3D's ``permute``). The march
advances ``Px, Py, Qz, k, n`` in place and drops finished rays (:meth:`DDARays.select`); it is owned by one
march at a time. :class:`MarchOutput` is what a march returns per ray for
:func:`~ssbench.passes.ssr.dda_assemble.assemble`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, NamedTuple, Optional

import torch

__all__ = ["DDARays", "DepthTexels", "MarchOutput", "RAY_CHUNK", "march_in_chunks", "select_rows"]

#: rays marched at once: a march's per-step temporaries stay a few MB, whatever the image size
RAY_CHUNK = 1 << 16


class DepthTexels(NamedTuple):
    """What the DDA march reads per texel, flat :math:`(B·H·W,)` (:func:`~ssbench.passes.ssr.dda.depth_texels`):
    ``view_z``, ``mask``, ``back_z`` and ``second_z`` (``None`` where the parameters do not use them), and
    ``marched``, the ``(view_z, back_z, second_z)`` the step kernel reads: NaN off the mask (a NaN compares false,
    so a cleared texel is never hit), built once per pass rather than once per chunk of rays."""

    view_z: torch.Tensor
    mask: torch.Tensor
    back_z: Optional[torch.Tensor]
    second_z: Optional[torch.Tensor]
    marched: tuple


@dataclass
class DDARays:
    """Per-ray DDA state, each field an :math:`(N,)` tensor (the article's / G3D's names).

    Attributes:
        i: the ray's row in the march outputs; ``b``: its batch index.
        Px, Py: the current sample point ``P`` in pixels (permuted); ``Qz``: homogeneous ``Q.z``; ``k``: ``1/w``;
            ``n``: samples taken, in strides from ``P0`` (fractional after a shortened last footprint).
        dPx, dPy, dQz, dk: their per-stride increments (``dP``, ``dQ.z``, ``dk``); ``stride``: pixels per stride.
        Q0x, Q0y, dQx, dQy: ``Q.xy`` at the start and per stride (``Q.xy`` is rebuilt from ``n`` at a hit).
        end: ``P1`` along the major axis, signed by ``stepDir``; ``stop``: ``end`` or the viewport edge, sooner.
        stepDir: ±1, the major-axis direction; ``permute``: bool, the line is more vertical than horizontal.
        zlo, zhi: the segment's view-z range (``Q.z / k`` is clamped into it); ``prevZ``: the ray's z at the
            previous footprint edge (``rayZMin`` of the next sample).
        clipped: bool, the ray was shortened by the near plane (ending past ``P1`` is then ``BEHIND_CAMERA``).
        alive: bool, not finished (set by the march).
    """

    i: torch.Tensor
    b: torch.Tensor
    Px: torch.Tensor
    Py: torch.Tensor
    Qz: torch.Tensor
    k: torch.Tensor
    n: torch.Tensor
    dPx: torch.Tensor
    dPy: torch.Tensor
    dQz: torch.Tensor
    dk: torch.Tensor
    stride: torch.Tensor
    Q0x: torch.Tensor
    Q0y: torch.Tensor
    dQx: torch.Tensor
    dQy: torch.Tensor
    end: torch.Tensor
    stop: torch.Tensor
    stepDir: torch.Tensor
    permute: torch.Tensor
    zlo: torch.Tensor
    zhi: torch.Tensor
    prevZ: torch.Tensor
    clipped: torch.Tensor
    alive: Optional[torch.Tensor] = None

    def select(self, index: torch.Tensor) -> "DDARays":
        """The rays at ``index`` (a :math:`(M,)` long tensor), every field (also a subclass's) indexed."""
        return select_rows(self, index)

    def ray(self, r: int) -> dict:
        """Ray ``r`` as plain Python numbers, by field name (for the per-pixel teaching twins)."""
        return {f.name: getattr(self, f.name)[r].item() for f in dataclasses.fields(self)
                if isinstance(getattr(self, f.name), torch.Tensor)}

    @property
    def count(self) -> int:
        """``N``, the rays held."""
        return self.i.numel()


def select_rows(state, index: torch.Tensor):
    """A copy of the per-ray dataclass ``state`` keeping the rows ``index`` of every tensor field."""
    return dataclasses.replace(state, **{f.name: getattr(state, f.name).index_select(0, index)
                                         for f in dataclasses.fields(state)
                                         if isinstance(getattr(state, f.name), torch.Tensor)})


@dataclass
class MarchOutput:
    """What a DDA march returns per ray (rows by :attr:`DDARays.i`).

    Attributes:
        term: :math:`(N,)` int8 termination code (``ssbench.passes.ssr.common``).
        steps: :math:`(N,)` int32 depth fetches (samples and refinement probes).
        P: :math:`(N, 2)` hit pixel (unpermuted, −1 without a hit); ``Q``: :math:`(N, 3)` homogeneous hit point;
            ``k``: :math:`(N,)` its ``1/w`` (``hitPoint = Q / k``).
    """

    term: torch.Tensor
    steps: torch.Tensor
    P: torch.Tensor
    Q: torch.Tensor
    k: torch.Tensor

    @classmethod
    def empty(cls, n: int, dtype: torch.dtype, device, term: int) -> "MarchOutput":
        """``n`` rays that have not hit: termination ``term``, no fetches, ``P = −1``, ``Q = 0``, ``k = 1``."""
        return cls(term=torch.full((n,), term, dtype=torch.int8, device=device),
                   steps=torch.zeros(n, dtype=torch.int32, device=device),
                   P=torch.full((n, 2), -1.0, dtype=dtype, device=device),
                   Q=torch.zeros(n, 3, dtype=dtype, device=device), k=torch.ones(n, dtype=dtype, device=device))

    def write_ends(self, rows: torch.Tensor, i: torch.Tensor, term: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
        """Copy the termination codes ``term`` and fetch counts ``steps`` (any integer type, or integer-valued floats)
        of a working set's ``rows`` (its output rows ``i``) into these outputs, as every marcher writes back its
        stopped rays; returns those rows' codes.

        Example:
            >>> out = MarchOutput.empty(3, torch.float32, "cpu", 4)
            >>> out.write_ends(torch.tensor([1]), torch.tensor([2, 0]), torch.tensor([5, 1], dtype=torch.int8),
            ...                torch.tensor([7, 9], dtype=torch.int32)).tolist(), out.term.tolist(), out.steps.tolist()
            ([1], [1, 4, 4], [9, 0, 0])
        """
        at, codes = i.index_select(0, rows), term.index_select(0, rows)
        self.term.index_copy_(0, at, codes.to(self.term.dtype))
        self.steps.index_copy_(0, at, steps.index_select(0, rows).to(self.steps.dtype))
        return codes

    def write_hits(self, i: torch.Tensor, P: torch.Tensor, Q: torch.Tensor, k: torch.Tensor) -> None:
        """Copy hit points into output rows ``i`` :math:`(m,)`: ``P`` :math:`(m, 2)`, ``Q`` :math:`(m, 3)`, ``k``
        :math:`(m,)` (``index_copy_``: 0.8x the time of ``out.P[i] = P``).

        Example:
            >>> out = MarchOutput.empty(3, torch.float32, "cpu", 4)
            >>> out.write_hits(torch.tensor([2]), torch.tensor([[5.0, 6.0]]), torch.ones(1, 3), torch.tensor([0.5]))
            >>> out.P.tolist(), out.k.tolist()
            ([[-1.0, -1.0], [-1.0, -1.0], [5.0, 6.0]], [1.0, 1.0, 0.5])
        """
        self.P.index_copy_(0, i, P.to(self.P.dtype))
        self.Q.index_copy_(0, i, Q.to(self.Q.dtype))
        self.k.index_copy_(0, i, k.to(self.k.dtype))


def march_in_chunks(sel: torch.Tensor, setup: Callable[[torch.Tensor], tuple], march: Callable[[DDARays], MarchOutput],
                    chunk: Optional[int] = None) -> tuple[MarchOutput, torch.Tensor]:
    """Set up and march the rays of pixels ``sel`` :math:`(N,)` ``chunk`` rays (default :data:`RAY_CHUNK`) at a
    time and join the results: ``(MarchOutput, P1)`` for all ``N`` rays, in ``sel``'s order.

    ``setup(part)`` returns ``(DDARays, sel, P0, P1)`` for the pixels ``part`` (rows ``i`` = 0 … len(part)−1, as
    :func:`~ssbench.passes.ssr.dda_rays.dda_rays` does); ``march(rays)`` a :class:`MarchOutput`. Rays do not
    interact and debug visit counts are sums, so the outputs are those of one chunk holding every ray, with a
    working set (set-up and march temporaries) that no longer grows with the image.

    Example:
        >>> def setup(part):
        ...     rays = DDARays(**{f.name: part.double() for f in dataclasses.fields(DDARays)})
        ...     rays.i = torch.arange(len(part))
        ...     return rays, part, None, part[:, None].double()
        >>> march = lambda r: MarchOutput.empty(r.count, torch.float32, "cpu", 4 + int(r.i.max()))
        >>> out, P1 = march_in_chunks(torch.arange(5), setup, march, chunk=2)   # chunks of 2, 2, 1 rays
        >>> out.term.tolist(), P1[:, 0].tolist()
        ([5, 5, 5, 5, 4], [0.0, 1.0, 2.0, 3.0, 4.0])
    """
    chunk = RAY_CHUNK if chunk is None else int(chunk)
    outs, ends = [], []
    for c0 in range(0, max(1, sel.numel()), chunk):
        rays, _, _, P1 = setup(sel[c0:c0 + chunk])
        outs.append(march(rays))
        ends.append(P1)
    return (MarchOutput(**{f.name: torch.cat([getattr(o, f.name) for o in outs], 0)
                           for f in dataclasses.fields(MarchOutput)}), torch.cat(ends, 0))
