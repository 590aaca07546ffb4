"""4×4 transforms as nested lists (row-major, column vectors), shared by the scene readers and the backend.

``T · R · S`` from ``translate``, ``rotate`` (Euler degrees, ``R = Rz · Ry · Rx``: x applied first) and
``scale``; :func:`decompose` is the inverse, used to import Mitsuba XML transform chains.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

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


def clean(x: float) -> float:
    """Round away float noise (12 significant digits, |x| < 1e-12 → 0) so 30° stays 30°."""
    return 0.0 if abs(x) < 1e-12 else float(f"{x:.12g}")


def decompose(m: Any) -> tuple[list[float], list[float], list[float]]:
    """Split an affine 4×4 ``M = T · R · S`` into translate, Euler degrees (``R = Rz·Ry·Rx``) and positive scale.

    Raises ``ValueError`` for projective, singular, sheared (beyond 1e-5) or mirroring matrices."""
    if any(abs(m[3][j] - (1.0 if j == 3 else 0.0)) > 1e-12 for j in range(4)):
        raise ValueError("the last row must be 0 0 0 1 (projective transforms are not supported)")
    s = [math.sqrt(sum(m[i][j] ** 2 for i in range(3))) for j in range(3)]
    if min(s) <= 1e-12 * max(s) or max(s) == 0.0:
        raise ValueError("singular transform (a scale is zero)")
    r = [[m[i][j] / s[j] for j in range(3)] for i in range(3)]
    if max(abs(sum(r[k][i] * r[k][j] for k in range(3)) - (i == j)) for i in range(3) for j in range(3)) > 1e-5:
        raise ValueError("shear is not supported (only translate, rotate and per-axis scale)")
    det = (r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
           + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]))
    if det < 0:
        raise ValueError("negative determinant (a mirroring) is not supported")
    ax = math.atan2(r[2][1], r[2][2])
    ay = math.atan2(-r[2][0], math.hypot(r[0][0], r[1][0]))
    sa, ca = math.sin(ax), math.cos(ax)      # az from R · Rx(ax)^T = Rz · Ry: stable at gimbal lock too
    az = math.atan2(sa * r[0][2] - ca * r[0][1], ca * r[1][1] - sa * r[1][2])
    return ([clean(m[i][3]) for i in range(3)], [clean(math.degrees(a)) for a in (ax, ay, az)],
            [clean(v) for v in s])


def rotate_axis4(axis: list[float], deg: float) -> list[list[float]]:
    x, y, z = axis
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    C = 1.0 - c
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s, 0.0],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s, 0.0],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C, 0.0], [0.0, 0.0, 0.0, 1.0]]


def unit(v: list[float]) -> list[float]:
    n = math.sqrt(sum(a * a for a in v))
    return [a / n for a in v]


def cross(a: list[float], b: list[float]) -> list[float]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def default_up(d: list[float]) -> list[float]:
    """Mitsuba's ``coordinate_system(d).first``: the up vector of a ``<lookat>`` without ``up``."""
    sign = 1.0 if d[2] >= 0 else -1.0
    a = -1.0 / (sign + d[2])
    return [1.0 + sign * d[0] * d[0] * a, sign * d[0] * d[1] * a, -sign * d[0]]
