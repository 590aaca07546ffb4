"""4×4 transforms as nested lists (row-major, column vectors), shared by the scene readers and the backend.

``T · R · S`` from ``translate``, ``rotate`` (Euler degrees, ``R = Rz · Ry · Rx``: x applied first) and
``scale``. (Mitsuba scene files keep their own transforms: Mitsuba loads them.)
"""
from __future__ import annotations

import math
from typing import Sequence

Mat4 = tuple[tuple[float, ...], ...]


def identity4() -> list[list[float]]:
    return [[1.0 if i == j else 0.0 for j in range(4)] for i in range(4)]


def matmul4(a: Sequence[Sequence[float]], b: Sequence[Sequence[float]]) -> list[list[float]]:
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def translate4(t: Sequence[float]) -> list[list[float]]:
    m = identity4()
    m[0][3], m[1][3], m[2][3] = (float(v) for v in t)
    return m


def scale4(s: Sequence[float]) -> list[list[float]]:
    m = identity4()
    m[0][0], m[1][1], m[2][2] = (float(v) for v in s)
    return m


def rotate4(euler_deg: Sequence[float]) -> list[list[float]]:
    """``Rz · Ry · Rx`` from Euler angles in degrees (x applied first)."""
    ax, ay, az = (math.radians(float(v)) for v in euler_deg)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = [[1, 0, 0, 0], [0, cx, -sx, 0], [0, sx, cx, 0], [0, 0, 0, 1]]
    ry = [[cy, 0, sy, 0], [0, 1, 0, 0], [-sy, 0, cy, 0], [0, 0, 0, 1]]
    rz = [[cz, -sz, 0, 0], [sz, cz, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    return matmul4(rz, matmul4(ry, rx))


def frame_z_to(axis: Sequence[float]) -> list[list[float]]:
    """A rotation taking local +z to the unit vector ``axis`` (for disks and cylinder caps)."""
    z = [float(v) for v in axis]
    n = math.sqrt(sum(v * v for v in z))
    z = [v / n for v in z]
    helper = [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0]
    x = [helper[1] * z[2] - helper[2] * z[1], helper[2] * z[0] - helper[0] * z[2],
         helper[0] * z[1] - helper[1] * z[0]]
    xn = math.sqrt(sum(v * v for v in x))
    x = [v / xn for v in x]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    return [[x[0], y[0], z[0], 0.0], [x[1], y[1], z[1], 0.0], [x[2], y[2], z[2], 0.0], [0.0, 0.0, 0.0, 1.0]]


def freeze4(m: Sequence[Sequence[float]]) -> Mat4:
    return tuple(tuple(float(v) for v in row) for row in m)
