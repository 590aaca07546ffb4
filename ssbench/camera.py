"""The one camera module: every conversion between world, view, clip, NDC, UV, pixel and depth lives here.

It enforces ``ssbench/CONVENTIONS.md``: view space is OpenGL / three.js (eye at the origin looking down −z, +x
right, +y up, ``view_z < 0`` in front); projection is ``gluPerspective(fovy, W / H, near, far)`` to NDC [−1, 1]³;
UV is ``ndc·0.5 + 0.5`` with ``v`` *up*, as in the articles' shaders; pixels ``(px, py)`` have ``py`` *down* and
the centre of (column i, row j) at ``(i + ½, j + ½)``; depth is a GL buffer ``d ∈ [0, 1]``, view z, or linear
``(z + n)/(n − f)`` (SSAO article §2.2, three.js ``packing.glsl``). Mitsuba puts camera-local +x to the image
*left* and defaults to a horizontal fov; that mapping (:meth:`Camera.mitsuba_sensor`) is written here only.

Vector functions take ``dim``, the axis of the components: ``-3`` (default) for ``(B, 3, H, W)`` and ``(3, H, W)``
images, ``-1`` for ``(N, 3)`` point lists.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

import torch

from .layout import stack
from .vec3 import Vec3, cross, norm, normalize, split_components, sub, vec3


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with OpenGL conventions (see the module docstring and ``CONVENTIONS.md``).

    Build one with :meth:`from_look_at`. All fields are plain Python numbers so the camera is hashable and
    can key a cache; matrices are produced on demand in the dtype and device asked for.

    Example:
        >>> cam = Camera.from_look_at((0, 2, 6), (0, 0.6, 0), (0, 1, 0), 45.0, 320, 240, 0.1, 100.0)
        >>> cam.projection_matrix().shape
        torch.Size([4, 4])
        >>> cam.view_z_to_depth(torch.tensor([-0.1, -100.0], dtype=torch.float64)).tolist()
        [0.0, 1.0]
    """

    eye: Vec3
    target: Vec3
    up: Vec3
    fovy_deg: float
    width: int
    height: int
    near: float
    far: float

    # ------------------------------------------------------------------ construction and validation
    @classmethod
    def from_look_at(cls, eye: Sequence[float], target: Sequence[float], up: Sequence[float],
                     fovy_deg: float, width: int, height: int, near: float, far: float) -> "Camera":
        """Camera at ``eye`` looking at ``target``; ``fovy_deg`` is the *vertical* field of view."""
        return cls(vec3(eye, "eye"), vec3(target, "target"), vec3(up, "up"), float(fovy_deg),
                   width, height, float(near), float(far))

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise ValueError(f"{name}: image size must be a positive integer, got {v!r}")
        if not (math.isfinite(self.fovy_deg) and 0.0 < self.fovy_deg < 180.0):
            raise ValueError(f"fovy_deg: must lie in (0, 180) degrees, got {self.fovy_deg}")
        if not (math.isfinite(self.near) and self.near > 0.0):
            raise ValueError(f"near: must be a finite number > 0, got {self.near}")
        if not (math.isfinite(self.far) and self.far > self.near):
            raise ValueError(f"far: must be finite and greater than near={self.near}, got {self.far}")
        fwd = sub(self.target, self.eye)
        if norm(fwd) < 1e-12:
            raise ValueError(f"target: must differ from eye {self.eye}")
        if norm(self.up) < 1e-12 or norm(cross(normalize(fwd), normalize(self.up))) < 1e-6:
            raise ValueError(f"up: must be non-zero and not parallel to the view direction, got {self.up}")

    def with_resolution(self, width: int, height: int) -> "Camera":
        """The same camera with another image size (the vertical fov is kept)."""
        return replace(self, width=width, height=height)

    def jittered(self, dx: float, dy: float) -> "Camera":
        """The camera turned so its pixel grid slides ``(dx, dy)`` pixels over the scene (x right, y down; a
        point seen at the centre moves by ``(−dx, −dy)`` in the image): the sub-pixel jitter of temporal
        anti-aliasing, done as a small rotation (a real camera, so every conversion stays exact) rather than a
        projection offset; away from the centre the shift grows by up to ``1 + tan²`` of the half field of
        view (1.2× at the edges of a 45° frame).

        Example:
            >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, 4, 4, 0.1, 10.0)
            >>> j = cam.jittered(0.5, 0.0)
            >>> p = j.view_to_pixel(j.world_to_view(torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64), 0), 0)
            >>> [round(v, 6) for v in p.tolist()]                      # the old centre, half a pixel left
            [1.5, 2.0]
        """
        for v, name in ((dx, "dx"), (dy, "dy")):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name}: must be a finite number of pixels, got {v!r}")
        right, up, _ = self.basis
        dist = norm(sub(self.target, self.eye))
        px = 2.0 * math.tan(math.radians(self.fovy_deg) / 2.0) * dist / self.height      # one pixel at the target
        shift = tuple(px * (dx * r - dy * u) for r, u in zip(right, up))
        return replace(self, target=tuple(t + s for t, s in zip(self.target, shift)))

    # ------------------------------------------------------------------ scalars
    @property
    def aspect(self) -> float:
        """``W / H``."""
        return self.width / self.height

    @property
    def focal(self) -> float:
        """``F = 1 / tan(fovy / 2)`` (SSAO article §3.3)."""
        return 1.0 / math.tan(math.radians(self.fovy_deg) / 2.0)

    @property
    def fovx_deg(self) -> float:
        """Horizontal field of view in degrees."""
        return math.degrees(2.0 * math.atan(math.tan(math.radians(self.fovy_deg) / 2.0) * self.aspect))

    @property
    def basis(self) -> tuple[Vec3, Vec3, Vec3]:
        """World-space unit vectors (right, up, back) of the view frame: view +x, +y, +z."""
        back = normalize(sub(self.eye, self.target))
        right = normalize(cross(self.up, back))
        return right, cross(back, right), back

    # ------------------------------------------------------------------ matrices
    def view_matrix(self, dtype: torch.dtype = torch.float64, device=None) -> torch.Tensor:
        """World → view 4×4 matrix (``gluLookAt``)."""
        r, u, b = self.basis
        e = self.eye
        rows = [[*r, -(r[0] * e[0] + r[1] * e[1] + r[2] * e[2])],
                [*u, -(u[0] * e[0] + u[1] * e[1] + u[2] * e[2])],
                [*b, -(b[0] * e[0] + b[1] * e[1] + b[2] * e[2])],
                [0.0, 0.0, 0.0, 1.0]]
        return torch.tensor(rows, dtype=dtype, device=device)

    def camera_to_world(self, dtype: torch.dtype = torch.float64, device=None) -> torch.Tensor:
        """View → world 4×4 matrix (inverse of :meth:`view_matrix`)."""
        r, u, b = self.basis
        e = self.eye
        rows = [[r[0], u[0], b[0], e[0]], [r[1], u[1], b[1], e[1]], [r[2], u[2], b[2], e[2]],
                [0.0, 0.0, 0.0, 1.0]]
        return torch.tensor(rows, dtype=dtype, device=device)

    def projection_matrix(self, dtype: torch.dtype = torch.float64, device=None) -> torch.Tensor:
        """GL perspective matrix (SSAO article §3.3, ``M_perspective``)."""
        n, f, F = self.near, self.far, self.focal
        rows = [[F / self.aspect, 0.0, 0.0, 0.0],
                [0.0, F, 0.0, 0.0],
                [0.0, 0.0, -(f + n) / (f - n), -2.0 * f * n / (f - n)],
                [0.0, 0.0, -1.0, 0.0]]
        return torch.tensor(rows, dtype=dtype, device=device)

    def inverse_projection_matrix(self, dtype: torch.dtype = torch.float64, device=None) -> torch.Tensor:
        """Closed-form inverse of :meth:`projection_matrix`."""
        n, f, F = self.near, self.far, self.focal
        rows = [[self.aspect / F, 0.0, 0.0, 0.0],
                [0.0, 1.0 / F, 0.0, 0.0],
                [0.0, 0.0, 0.0, -1.0],
                [0.0, 0.0, -(f - n) / (2.0 * f * n), (f + n) / (2.0 * f * n)]]
        return torch.tensor(rows, dtype=dtype, device=device)

    # ------------------------------------------------------------------ world <-> view
    def _apply(self, m: torch.Tensor, x: torch.Tensor, dim: int, translate: bool, name: str) -> torch.Tensor:
        c = split_components(x, dim, 3, name)
        m = m.to(dtype=x.dtype, device=x.device)
        out = []
        for i in range(3):
            v = m[i, 0] * c[0] + m[i, 1] * c[1] + m[i, 2] * c[2]
            out.append(v + m[i, 3] if translate else v)
        return stack(out, dim)

    def world_to_view(self, p: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """World points → view points."""
        return self._apply(self.view_matrix(), p, dim, True, "p")

    def view_to_world(self, p: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """View points → world points."""
        return self._apply(self.camera_to_world(), p, dim, True, "p")

    def world_to_view_dir(self, v: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """World directions (and normals: the map is a rotation) → view directions."""
        return self._apply(self.view_matrix(), v, dim, False, "v")

    def view_to_world_dir(self, v: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """View directions (and normals) → world directions."""
        return self._apply(self.camera_to_world(), v, dim, False, "v")

    # ------------------------------------------------------------------ view <-> NDC <-> UV <-> pixel
    def view_to_ndc(self, p: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """View points → NDC ``(x, y, z)`` in [−1, 1]³ inside the frustum (divide by ``w = −z``)."""
        x, y, z = split_components(p, dim, 3, "p")
        n, f = self.near, self.far
        return stack([*self.view_to_ndc_xy(x, y, z), (f + n) / (f - n) + 2.0 * f * n / ((f - n) * z)], dim)

    def view_to_ndc_xy(self, x: torch.Tensor, y: torch.Tensor, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """NDC ``x, y`` of view points given as separate components (what :meth:`view_to_ndc` computes, op for
        op, without stacking: a compiled kernel fuses it with the fetch that follows)."""
        return self.scaled_ndc_xy(x, y, z, self.ndc_scale())

    def ndc_scale(self) -> tuple[float, float]:
        """``(F / aspect, F)``: the factors :meth:`view_to_ndc_xy` multiplies view ``x`` and ``y`` by before the
        divide, as plain numbers (what a compiled kernel takes instead of the camera)."""
        F = self.focal
        return F / self.aspect, F

    @staticmethod
    def scaled_ndc_xy(x: torch.Tensor, y: torch.Tensor, z: torch.Tensor,
                      scale: tuple[float, float]) -> tuple[torch.Tensor, torch.Tensor]:
        """:meth:`view_to_ndc_xy` with the camera's :meth:`ndc_scale` given: ``(sx·x / w, sy·y / w)``, ``w = −z``."""
        w = -z
        return scale[0] * x / w, scale[1] * y / w

    @staticmethod
    def scaled_uv_xy(x: torch.Tensor, y: torch.Tensor, z: torch.Tensor,
                     scale: tuple[float, float]) -> tuple[torch.Tensor, torch.Tensor]:
        r""":meth:`ndc_to_uv` of :meth:`scaled_ndc_xy`, :math:`u = 0.5 + 0.5\,s_x x / (-z)`, in two passes per axis
        over the points instead of four and a shared negation (a marcher's or an AO sample loop's projection):
        :math:`(-s_x) x`, then one ``addcdiv``, :math:`0.5 + (0.5\,(-s_x x)) / z`. Negating and halving are exact, so
        this is the two-step :math:`u` bit for bit, except where :math:`|s_x x|` is subnormal or :math:`s_x x / z`
        overflows; the texel it reads is the same there too (tested at the extremes).

        Example:
            >>> [c.item() for c in Camera.scaled_uv_xy(torch.tensor(1.0), torch.tensor(-1.0), torch.tensor(-2.0),
            ...                                         (1.0, 1.0))]
            [0.75, 0.25]
        """
        half = torch.full((), 0.5, dtype=x.dtype, device=x.device)
        return torch.addcdiv(half, x * -scale[0], z, value=0.5), torch.addcdiv(half, y * -scale[1], z, value=0.5)

    def ndc_to_view(self, ndc: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """NDC ``(x, y, z)`` → view points (inverse of :meth:`view_to_ndc`)."""
        x, y, zn = split_components(ndc, dim, 3, "ndc")
        z = self.depth_to_view_z(zn * 0.5 + 0.5)
        return stack([x * -z * self.aspect / self.focal, y * -z / self.focal, z], dim)

    @staticmethod
    def ndc_to_uv(ndc_xy: torch.Tensor) -> torch.Tensor:
        """NDC → UV (``v`` up): ``uv = ndc * 0.5 + 0.5``."""
        return ndc_xy * 0.5 + 0.5

    @staticmethod
    def uv_to_ndc(uv: torch.Tensor) -> torch.Tensor:
        """UV → NDC: ``ndc = 2 uv − 1``."""
        return uv * 2.0 - 1.0

    def uv_to_pixel(self, uv: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """UV (v up) → continuous pixel coordinates ``(px, py)`` (py down, row 0 at the top)."""
        u, v = split_components(uv, dim, 2, "uv")
        return stack(self.uv_to_pixel_xy(u, v), dim)

    def uv_to_pixel_xy(self, u, v):
        """:meth:`uv_to_pixel` on separate components, plain arithmetic (torch tensors, Dr.Jit arrays, floats):
        ``(u · W, (1 − v) · H)``."""
        # NOTE: the row axis flips here: UV's v grows upward, image rows grow downward.
        return u * self.width, (1.0 - v) * self.height

    def pixel_to_uv(self, px: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """Continuous pixel coordinates → UV (inverse of :meth:`uv_to_pixel`)."""
        x, y = split_components(px, dim, 2, "px")
        return stack([x / self.width, 1.0 - y / self.height], dim)

    def view_to_pixel(self, p: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """View points → continuous pixel coordinates ``(px, py)``."""
        ndc = self.view_to_ndc(p, dim)
        return self.uv_to_pixel(self.ndc_to_uv(ndc.narrow(dim, 0, 2)), dim)

    def pixel_centers(self, dtype: torch.dtype = torch.float32, device=None) -> torch.Tensor:
        """``(2, H, W)`` pixel-centre coordinates: ``[0, j, i] = i + 0.5``, ``[1, j, i] = j + 0.5``."""
        ys = torch.arange(self.height, dtype=dtype, device=device) + 0.5
        xs = torch.arange(self.width, dtype=dtype, device=device) + 0.5
        gy, gx = torch.meshgrid(ys, xs, indexing="ij")
        return torch.stack([gx, gy], 0)

    def pixel_centers_at(self, index: torch.Tensor, dtype: torch.dtype = torch.float32) -> torch.Tensor:
        """``(2, N)`` centres of the flat pixel indices ``index = j·W + i`` :math:`(N,)`: the columns of
        :meth:`pixel_centers` at ``index``, the same values (``i + 0.5``, ``j + 0.5``), without the image-wide grid
        (for per-ray set-ups that run chunk by chunk). ``index`` must lie in ``[0, W·H)``.

        Example:
            >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 10.0)
            >>> cam.pixel_centers_at(torch.tensor([0, 5, 11])).tolist()
            [[0.5, 1.5, 3.5], [0.5, 1.5, 2.5]]
        """
        fits = self.width * self.height <= torch.iinfo(torch.int32).max     # int32 division: ~1.5x faster
        index = index.to(torch.int32) if fits else index
        row = torch.div(index, self.width, rounding_mode="floor")
        return torch.stack([(index - row * self.width).to(dtype) + 0.5, row.to(dtype) + 0.5], 0)

    def uv_grid(self, dtype: torch.dtype = torch.float32, device=None) -> torch.Tensor:
        """``(2, H, W)`` UV of every pixel centre (``v`` up, so ``v`` *decreases* down the rows)."""
        return self.pixel_to_uv(self.pixel_centers(dtype, device), dim=0)

    def pixel_rays(self, dtype: torch.dtype = torch.float32, device=None) -> torch.Tensor:
        """``(3, H, W)`` view-space directions through pixel centres, scaled so that ``z = −1``."""
        uv = self.uv_grid(dtype, device)
        return self.uv_to_view(uv, torch.full_like(uv[:1], -1.0), dim=0)

    # ------------------------------------------------------------------ depth encodings (SSAO article §2.2)
    def view_z_to_depth(self, view_z: torch.Tensor) -> torch.Tensor:
        """View z → GL depth buffer value in [0, 1] (three.js ``viewZToPerspectiveDepth``)."""
        n, f = self.near, self.far
        # three.js ((n + z) f) / ((f − n) z) with numerator and denominator negated (exact), so that
        # z = −near gives +0.0 rather than −0.0
        return ((-n - view_z) * f) / ((f - n) * -view_z)

    def depth_to_view_z(self, depth: torch.Tensor) -> torch.Tensor:
        """GL depth buffer value → view z (three.js ``perspectiveDepthToViewZ``)."""
        n, f = self.near, self.far
        return (n * f) / ((f - n) * depth - f)

    def view_z_to_orthographic_depth(self, view_z: torch.Tensor) -> torch.Tensor:
        """View z → linear depth ``(z + n) / (n − f)`` in [0, 1] (``viewZToOrthographicDepth``)."""
        return (view_z + self.near) / (self.near - self.far)

    def orthographic_depth_to_view_z(self, linear_depth: torch.Tensor) -> torch.Tensor:
        """Linear depth → view z (``orthographicDepthToViewZ``)."""
        return linear_depth * (self.near - self.far) - self.near

    # ------------------------------------------------------------------ position from depth (SSAO article's two ways)
    def uv_to_view_params(self) -> tuple[float, float, float, float]:
        """HBAO ``UvToViewParams`` (SSAO article §3.3): ``(−2/F₁, −2/F₂, 1/F₁, 1/F₂)``.

        ``F₁ = F · H / W`` and ``F₂ = F`` with ``F = 1 / tan(fovy / 2)``, derived from
        ``x_view = (2u − 1)·(−z) / (F / aspect)`` and ``y_view = (2v − 1)·(−z) / F``.
        """
        f1 = self.focal * self.height / self.width
        f2 = self.focal
        return (-2.0 / f1, -2.0 / f2, 1.0 / f1, 1.0 / f2)

    def uv_to_view(self, uv: torch.Tensor, view_z: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """HBAO ``uvToView``: ``xy = (A · uv + B) · z`` (SSAO article §3.3). ``view_z`` has size 1 on ``dim``."""
        a0, a1, b0, b1 = self.uv_to_view_params()
        u, v = split_components(uv, dim, 2, "uv")
        z = view_z.squeeze(dim) if view_z.dim() == uv.dim() else view_z
        u, v, z = torch.broadcast_tensors(u, v, z)             # e.g. a (1, 2, H, W) grid with (B, 1, H, W) z
        return stack([(a0 * u + b0) * z, (a1 * v + b1) * z, z], dim)

    def view_position_from_depth(self, uv: torch.Tensor, depth: torch.Tensor, dim: int = -3) -> torch.Tensor:
        """SSAO ``getViewPosition`` (SSAO article §2.2): un-project ``(uv, depth)`` with the inverse projection.

        ``clipW = P[3][2]·z + P[3][3]`` (three.js column-major ``[2][3]``), ``clip = (2·(uv, d) − 1, 1)·clipW``.
        """
        u, v = split_components(uv, dim, 2, "uv")
        d = depth.squeeze(dim) if depth.dim() == uv.dim() else depth
        view_z = self.depth_to_view_z(d)
        clip_w = -view_z                                       # P[3] = (0, 0, −1, 0)
        clip = [(u * 2 - 1) * clip_w, (v * 2 - 1) * clip_w, (d * 2 - 1) * clip_w, clip_w]
        m = self.inverse_projection_matrix(dtype=uv.dtype, device=uv.device)
        out = [sum(m[i, k] * clip[k] for k in range(4)) for i in range(3)]
        return stack(out, dim)

    # ------------------------------------------------------------------ Mitsuba (the one place)
    def mitsuba_sensor(self) -> dict:
        """Mitsuba ``perspective`` sensor parameters equal to this camera (no Mitsuba import here).

        NOTE: Mitsuba's camera-local frame has +x pointing to the image *left* and looks down +z, so its
        ``to_world`` is our view→world matrix times ``diag(−1, 1, −1, 1)`` (a 180° turn about y). Its ``fov``
        is horizontal unless ``fov_axis='y'``. Its rays start on the near plane, so ``si.t`` is not the eye
        distance: ssbench reads positions (``si.p``), never ``si.t``.
        """
        m = self.camera_to_world().tolist()
        for row in m:                           # right-multiply by diag(−1, 1, −1, 1): negate columns 0, 2
            row[0], row[2] = -row[0], -row[2]
        return {"type": "perspective", "fov": self.fovy_deg, "fov_axis": "y",
                "near_clip": self.near, "far_clip": self.far, "to_world": m,
                "width": self.width, "height": self.height}
