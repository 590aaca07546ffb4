r"""Prove a declared bounds box honest: f > 0 on every face, by interval arithmetic (adaptive subdivision).

The certified reference (:mod:`ssbench.reference.implicit`) clips every ray to an object's ``bounds`` and
reads "f > 0 outside them" as a fact. A box that cuts through the surface breaks that silently: a sphere of
radius 1.5 declared with bounds ±1 is *inside* (f < 0) on the whole box, so the reference sees rays that
start inside and reports almost nothing, while a marcher that is right is scored as false hits. A surface
that crosses a face is exactly such a box, so :func:`check_bounds` refuses it at load time.

Method, per face :math:`F` of the local box (axis :math:`k` fixed at its lower or upper value), in float64:

1. Cover :math:`F` by ``grid × grid`` rectangles; a rectangle is a degenerate box (zero width along
   :math:`k`) whose enclosure ``expression.interval`` gives.
2. ``lo > 0``: f > 0 on the whole rectangle (proved). Otherwise evaluate f at the rectangle's centre: f ≤ 0
   (or NaN; the most negative centre is reported) is a witness that the surface reaches the face, and the
   box is refused naming the face and the point. Otherwise split the rectangle in four and repeat.
3. A rectangle still undecided after ``max_depth`` splits, or more than ``max_cells`` rectangles alive,
   refuses the box too ("could not prove"): a tangency on the face or interval over-estimation that
   subdivision does not remove. Widening the box by a little always helps a closed surface.

Proving the faces is what the ray clipping needs: a ray enters the box through a face, so f > 0 where it
enters. (A component wholly outside the box is simply not part of the object, as the schema says.)
The object's transform does not matter: the world field is ``s·f_local`` with ``s > 0``, so the sign on the
local box's faces is the sign on the world box's faces.
"""
from __future__ import annotations

import math
from typing import Any, Optional

import torch

__all__ = ["check_bounds", "BoundsError", "FACES"]

#: the faces of a box, in the order they are checked: ``(name, axis, side)`` with side 0 = lower, 1 = upper
FACES = tuple((f"{'-+'[side]}{'xyz'[axis]}", axis, side) for axis in range(3) for side in range(2))

_PROVED: dict = {}                                    # (expression key, bounds, settings) -> True


class BoundsError(ValueError):
    """A bounds box the surface reaches (or that could not be proved honest). ``face`` names the face
    (``"-x"`` … ``"+z"``); ``point`` is the local witness point with f ≤ 0 (``None`` when undecided)."""

    def __init__(self, message: str, face: str, point: Optional[tuple] = None):
        super().__init__(message)
        self.face, self.point = face, point


def _face_boxes(lo: torch.Tensor, hi: torch.Tensor, axis: int, value: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Degenerate 3-D boxes of face rectangles ``lo, hi`` (n, 2) on the plane ``x_axis = value``."""
    others = [a for a in range(3) if a != axis]
    blo = torch.empty(lo.shape[0], 3, dtype=torch.float64)
    bhi = torch.empty_like(blo)
    blo[:, others], bhi[:, others] = lo, hi
    blo[:, axis] = bhi[:, axis] = value
    return blo, bhi


def _prove_face(expression: Any, box: tuple, axis: int, side: int, grid: int, max_depth: int,
                max_cells: int) -> tuple[str, Optional[tuple], float]:
    """``("proved", None, nan)``, ``("reached", point, f(point))`` or ``("undecided", None, nan)`` for one face."""
    blo, bhi = (torch.tensor(b, dtype=torch.float64) for b in box)
    value = float((blo if side == 0 else bhi)[axis])
    others = [a for a in range(3) if a != axis]
    u = torch.linspace(0.0, 1.0, grid + 1, dtype=torch.float64)
    a0 = blo[others[0]] + u * (bhi[others[0]] - blo[others[0]])
    a1 = blo[others[1]] + u * (bhi[others[1]] - blo[others[1]])
    i, j = torch.meshgrid(torch.arange(grid), torch.arange(grid), indexing="ij")
    lo = torch.stack([a0[i.flatten()], a1[j.flatten()]], -1)                # (n, 2) rectangle corners
    hi = torch.stack([a0[i.flatten() + 1], a1[j.flatten() + 1]], -1)
    for _ in range(max_depth + 1):
        flo, _fhi = expression.interval(*_face_boxes(lo, hi, axis, value))
        open_ = ~(flo > 0)                                                   # NaN enclosure: not proved
        if not bool(open_.any()):
            return "proved", None, math.nan
        lo, hi = lo[open_], hi[open_]
        centre = (lo + hi) / 2
        p, _ = _face_boxes(centre, centre, axis, value)
        fc = expression(p)
        bad = ~(fc > 0)
        if bool(bad.any()):
            worst = int(torch.where(bad, fc.nan_to_num(nan=-torch.inf), torch.inf).argmin())
            return "reached", tuple(float(v) for v in p[worst]), float(fc[worst])   # the most negative witness
        if 4 * lo.shape[0] > max_cells:
            return "undecided", None, math.nan
        mid = centre
        quads = []
        for qa in (0, 1):
            for qb in (0, 1):
                qlo = torch.stack([(lo, mid)[qa][:, 0], (lo, mid)[qb][:, 1]], -1)
                qhi = torch.stack([(mid, hi)[qa][:, 0], (mid, hi)[qb][:, 1]], -1)
                quads.append((qlo, qhi))
        lo = torch.cat([q[0] for q in quads])
        hi = torch.cat([q[1] for q in quads])
    return "undecided", None, math.nan


def check_bounds(expression: Any, bounds: tuple, name: str = "object", *, grid: int = 8, max_depth: int = 10,
                 max_cells: int = 1 << 18) -> None:
    r"""Raise :class:`BoundsError` unless f > 0 is proved on all six faces of ``bounds`` (module docstring).

    Args:
        expression: the local field: callable on points ``(n, 3)`` with ``interval(lo, hi)`` enclosures.
        bounds: the local box ``((x0, y0, z0), (x1, y1, z1))``.
        name: the object's id, for the message.
        grid: initial rectangles per face edge.
        max_depth: how many times a rectangle may be split in four.
        max_cells: most rectangles alive per face at once.

    Results are memoised per ``(expression, bounds, settings)``, so copies of one object (animation poses,
    translated copies) are proved once.

    Example:
        >>> from ssbench.implicit.expression import parse
        >>> check_bounds(parse("length(p) - 1"), ((-1.05,) * 3, (1.05,) * 3), "ball")      # honest: no error
        >>> try:
        ...     check_bounds(parse("length(p) - 1.5"), ((-1.0,) * 3, (1.0,) * 3), "ball")
        ... except BoundsError as e:
        ...     print(e.face, str(e).split(";")[0])
        -x object 'ball': the surface reaches the bounds face -x (f = -0.484 at local (-1, -0.125, -0.125))
    """
    from .surface import expression_key
    key = (expression_key(expression), tuple(map(tuple, bounds)), grid, max_depth, max_cells)
    if key in _PROVED:
        return
    for face, axis, side in FACES:
        verdict, point, fval = _prove_face(expression, bounds, axis, side, grid, max_depth, max_cells)
        if verdict == "reached":
            raise BoundsError(
                f"object {name!r}: the surface reaches the bounds face {face} (f = {fval:.3g} at local "
                f"({', '.join(f'{v:.4g}' for v in point)})); the reference needs f > 0 on and outside the box: "
                f"enlarge 'bounds' so that it encloses the surface", face, point)
        if verdict == "undecided":
            raise BoundsError(
                f"object {name!r}: could not prove f > 0 on the bounds face {face} by interval arithmetic "
                f"({max_depth} subdivisions); the surface may touch it: enlarge 'bounds' a little", face)
    _PROVED[key] = True
