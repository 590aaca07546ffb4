r"""One physical thickness, four "thickness" knobs: what each anchor's knob would have to be set to.

SSR implementations all expose a knob called *thickness*, but they measure different things
(McGuire & Mara 2014's ``zThickness``, kode80's ``pixelZSize``, three.js ``SSRShader``'s ``thickness``, HDRP's
relative thickness; ``ssbench/REFERENCES.md``). Given one physical slab thickness :math:`T` (view / scene
units: how far behind the front surface a ray still counts as inside the object), at view depth
:math:`|z|`, the knobs are

==================================== ================================ ==========================================
knob (anchor)                        meaning                          value for a slab of thickness :math:`T`
==================================== ================================ ==========================================
``pixelZSize`` (kode80; also the     constant view-space depth slab   :math:`T` (identity)
SSR article's ``Thickness``, G3D
``csZThickness``, mebiusbox)
``depthBufferThickness`` (HDRP)      *relative*: the surface spans    :math:`t = T / |z|`
                                     linear depth :math:`[|z|,
                                     (1+t)|z|]`
``depth_buffer_thickness``           soft *Euclidean* band along the  :math:`T \sec\theta` (confidence reaches 0
(FidelityFX SSSR)                    pixel's eye ray: confidence      at depth :math:`T`); the band in front of
                                     :math:`(1-\mathrm{smoothstep}(0,  the surface counts too
                                     \tau, d))^2`
``thickness`` (Unity PPv2)           not a thickness: a **pixel       :math:`T f_\text{px} / |z| \,/\,
                                     stride** of the march (the depth (1 - \min(1, |z_0|/100))` in trace-buffer
                                     test itself is infinitely       texels
                                     thick)
==================================== ================================ ==========================================

* **HDRP** (``ScreenSpaceReflections.compute``): the Hi-Z *base* is ``b = d·k_s + k_b`` with
  ``k_s = 1/(1+t)``, ``k_b = −n/(f−n)·t/(1+t)``, derived there from ``b = DeviceDepth((1 + t)·LinearDepth(d))``.
  With reversed-Z ``LinearDepth(d) = n·f/((f−n)·d + n)`` that is exactly linear depth ``(1+t)|z|``, so one
  knob value means a slab that grows linearly with distance (default 0.01: 1 cm at 1 m, 1 m at 100 m).
* **FidelityFX** (``ffx_sssr_intersect.h``): ``distance = length(vs_surface − vs_hit)`` between two view
  points at the *same* screen position, i.e. along the eye ray through that pixel, so a depth difference
  :math:`\Delta z` is a distance :math:`\Delta z \sec\theta` with :math:`\sec\theta = |P|/|z|` (1 at the image
  centre). The confidence is soft: :func:`fidelityfx_band` gives the distance where it falls to a level.
  Default 0.015.
* **PPv2** (``ScreenSpaceReflections.hlsl``): ``stride = (1 − min(1, −z₀·0.01))·_Bandwidth`` with
  ``_Bandwidth`` = the *thickness* setting (range 1–64, presets 8–32), in texels of a square power-of-two
  trace buffer (:func:`ppv2_trace_size`); the hit test is ``z.y < depth`` (any depth behind the surface). The
  only "thickness" is therefore the smallest object a stride cannot skip: an object of size :math:`T` at depth
  :math:`|z|` spans :math:`T f_\text{px}/|z|` texels with :math:`f_\text{px} = \tfrac{s}{2} \min(F/a, F)`
  (``s`` the trace size, ``F = 1/\tan(\text{fovy}/2)``, ``a`` the aspect: the square buffer squeezes the
  wider axis). At :math:`|z_0| \ge 100` the stride is 0 whatever the knob (the known PPv2 z-cutoff bug), so
  no value maps: ``inf``.

:func:`thickness_knobs` returns all four for one ``T`` and depth, :func:`physical_thickness` inverts a knob,
:func:`thickness_table` / :func:`thickness_table_md` tabulate them over depths (the report shows one).
"""
from __future__ import annotations

import math
from typing import Iterable, Optional, Sequence

__all__ = ["KNOBS", "kode80_pixel_z_size", "hdrp_relative_thickness", "fidelityfx_depth_buffer_thickness",
           "fidelityfx_confidence", "fidelityfx_band", "ppv2_trace_size", "ppv2_thickness", "secant",
           "thickness_knobs", "physical_thickness", "thickness_table", "thickness_table_md"]

#: knob name → (anchor, unit, what it measures)
KNOBS: dict[str, tuple[str, str, str]] = {
    "kode80_pixel_z_size": ("kode80 pixelZSize (= seed Thickness, G3D csZThickness)", "view units",
                            "constant depth slab behind the front surface"),
    "hdrp_relative": ("HDRP depthBufferThickness", "fraction of linear depth",
                      "slab (1 + t)·|z|: grows with distance"),
    "fidelityfx_band": ("FidelityFX SSSR depth_buffer_thickness", "view units along the eye ray",
                        "soft confidence band (1 − smoothstep(0, τ, d))², both sides of the surface"),
    "ppv2_stride": ("Unity PPv2 thickness", "trace-buffer texels per step (before the z-cutoff)",
                    "a march stride; the depth test itself is infinitely thick"),
}
_RESOLUTIONS = {"downsampled": -1, "fullsize": 0, "full": 0, "supersampled": 1}


def _pos(x, name: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not (math.isfinite(x) and x > 0):
        raise ValueError(f"{name}: must be a finite number > 0, got {x!r}")
    return float(x)


def _depth(depth) -> float:
    """|z| from a view z (negative) or a positive distance."""
    if isinstance(depth, bool) or not isinstance(depth, (int, float)) or not math.isfinite(depth) or depth == 0:
        raise ValueError(f"depth: must be a finite non-zero number (view z < 0 or a distance > 0), got {depth!r}")
    return abs(float(depth))


# ------------------------------------------------------------------------------------------ the four knobs
def kode80_pixel_z_size(thickness: float) -> float:
    """kode80 ``pixelZSize`` (and the SSR article's ``Thickness``): the depth slab itself, in view units.

    Example:
        >>> kode80_pixel_z_size(0.1)
        0.1
    """
    return _pos(thickness, "thickness")


def hdrp_relative_thickness(thickness: float, depth: float) -> float:
    r"""HDRP ``depthBufferThickness`` :math:`t = T/|z|` (the surface spans linear depth :math:`[|z|, (1+t)|z|]`).

    Example:
        >>> hdrp_relative_thickness(0.1, -10.0)
        0.01
    """
    return _pos(thickness, "thickness") / _depth(depth)


def secant(camera=None, pixel: Optional[Sequence[float]] = None) -> float:
    r""":math:`\sec\theta = |P|/|z|` of the eye ray through ``pixel`` (continuous ``(px, py)``; 1 at the centre
    or without a camera)."""
    if camera is None or pixel is None:
        return 1.0
    px, py = float(pixel[0]), float(pixel[1])
    x_ndc = 2.0 * px / camera.width - 1.0
    y_ndc = 1.0 - 2.0 * py / camera.height
    F = camera.focal
    return math.sqrt(1.0 + (x_ndc * camera.aspect / F) ** 2 + (y_ndc / F) ** 2)


def fidelityfx_depth_buffer_thickness(thickness: float, camera=None, pixel: Optional[Sequence[float]] = None
                                      ) -> float:
    r"""FidelityFX ``depth_buffer_thickness`` :math:`\tau = T\sec\theta` whose confidence reaches 0 exactly at a
    depth :math:`T` behind the surface, for the pixel ``pixel`` (default: the image centre, :math:`\sec = 1`).

    Example:
        >>> fidelityfx_depth_buffer_thickness(0.015)
        0.015
    """
    return _pos(thickness, "thickness") * secant(camera, pixel)


def _smoothstep(e0: float, e1: float, x: float) -> float:
    t = min(max((x - e0) / (e1 - e0), 0.0), 1.0)
    return t * t * (3.0 - 2.0 * t)


def fidelityfx_confidence(distance: float, depth_buffer_thickness: float) -> float:
    """FidelityFX hit confidence ``(1 − smoothstep(0, τ, distance))²`` (``ffx_sssr_intersect.h``).

    Example:
        >>> fidelityfx_confidence(0.0, 0.015), fidelityfx_confidence(0.015, 0.015)
        (1.0, 0.0)
    """
    c = 1.0 - _smoothstep(0.0, _pos(depth_buffer_thickness, "depth_buffer_thickness"), abs(float(distance)))
    return c * c


def fidelityfx_band(depth_buffer_thickness: float, confidence: float = 0.5) -> float:
    r"""Distance at which the FidelityFX confidence falls to ``confidence`` (closed form).

    :math:`(1 - s(x))^2 = c \Rightarrow s(x) = 1 - \sqrt c`, and the inverse of
    :math:`s(x) = 3x^2 - 2x^3` on [0, 1] is :math:`x = \tfrac12 - \sin\!\big(\tfrac13\arcsin(1 - 2s)\big)`,
    so :math:`d_c = \tau\,\big(\tfrac12 - \sin(\tfrac13 \arcsin(2\sqrt c - 1))\big)`.

    Example:
        >>> round(fidelityfx_band(1.0, 0.5), 6)
        0.358121
    """
    tau = _pos(depth_buffer_thickness, "depth_buffer_thickness")
    if isinstance(confidence, bool) or not isinstance(confidence, (int, float)) or not 0 <= confidence <= 1:
        raise ValueError(f"confidence: must be in [0, 1], got {confidence!r}")
    return tau * (0.5 - math.sin(math.asin(2.0 * math.sqrt(confidence) - 1.0) / 3.0))


def ppv2_trace_size(width: int, height: int, resolution: str = "downsampled") -> int:
    """Side of PPv2's square trace buffer: ``Mathf.ClosestPowerOfTwo(min(W, H))``, halved when downsampled
    (the default), doubled when supersampled (ties go to the larger power).

    Example:
        >>> ppv2_trace_size(320, 240), ppv2_trace_size(1920, 1080, "fullsize")
        (128, 1024)
    """
    for n, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
            raise ValueError(f"{n}: must be a positive integer, got {v!r}")
    if resolution not in _RESOLUTIONS:
        raise ValueError(f"resolution: expected one of {', '.join(_RESOLUTIONS)}, got {resolution!r}")
    m = min(width, height)
    up = 1 << (m - 1).bit_length()
    down = up >> 1
    size = down if down and (m - down) < (up - m) else up
    shift = _RESOLUTIONS[resolution]
    return max(1, size >> 1) if shift < 0 else size << shift


def _ppv2_scale(camera, resolution: str) -> float:
    """Trace-buffer texels per view unit at depth 1 (the tighter of the two axes)."""
    s = ppv2_trace_size(camera.width, camera.height, resolution)
    F = camera.focal
    return 0.5 * s * min(F / camera.aspect, F)


def _ppv2_cutoff(origin_depth: float) -> float:
    return 1.0 - min(1.0, abs(origin_depth) * 0.01)


def ppv2_thickness(thickness: float, depth: float, camera, *, origin_depth: Optional[float] = None,
                   resolution: str = "downsampled") -> float:
    r"""PPv2 *thickness* (a stride) such that one step spans the projected size of ``thickness`` at ``depth``.

    :math:`\text{knob} = T f_\text{px}/|z| \,/\, (1 - \min(1, |z_0|/100))`, ``inf`` when :math:`|z_0| \ge 100`
    (``origin_depth`` :math:`z_0` defaults to ``depth``). PPv2's UI range is 1–64; values are not clamped.
    """
    T, z = _pos(thickness, "thickness"), _depth(depth)
    z0 = z if origin_depth is None else _depth(origin_depth)
    cut = _ppv2_cutoff(z0)
    return math.inf if cut <= 0 else T * _ppv2_scale(camera, resolution) / z / cut


# ------------------------------------------------------------------------------------------ tables
def thickness_knobs(thickness: float, depth: float, camera=None, *, pixel: Optional[Sequence[float]] = None,
                    origin_depth: Optional[float] = None, resolution: str = "downsampled") -> dict[str, float]:
    """All four knobs (keys of :data:`KNOBS`) for one physical ``thickness`` at view ``depth``.

    ``camera`` is needed for ``ppv2_stride`` (``nan`` without one) and, with ``pixel``, for the FidelityFX
    off-axis secant.

    Example:
        >>> k = thickness_knobs(0.1, -5.0)
        >>> k["kode80_pixel_z_size"], k["hdrp_relative"], k["fidelityfx_band"], k["ppv2_stride"]
        (0.1, 0.02, 0.1, nan)
    """
    return {"kode80_pixel_z_size": kode80_pixel_z_size(thickness),
            "hdrp_relative": hdrp_relative_thickness(thickness, depth),
            "fidelityfx_band": fidelityfx_depth_buffer_thickness(thickness, camera, pixel),
            "ppv2_stride": (ppv2_thickness(thickness, depth, camera, origin_depth=origin_depth,
                                           resolution=resolution) if camera is not None else math.nan)}


def physical_thickness(knob: str, value: float, depth: float, camera=None, *,
                       pixel: Optional[Sequence[float]] = None, origin_depth: Optional[float] = None,
                       resolution: str = "downsampled") -> float:
    """The physical thickness (view units, at ``depth``) that knob ``knob`` set to ``value`` stands for: the
    inverse of :func:`thickness_knobs` (for ``fidelityfx_band``: the depth where the confidence reaches 0;
    for ``ppv2_stride``: the object size one stride spans, 0 beyond the z-cutoff).

    Example:
        >>> physical_thickness("hdrp_relative", 0.01, -100.0)
        1.0
    """
    if knob not in KNOBS:
        raise ValueError(f"knob: unknown knob {knob!r}; known: {', '.join(KNOBS)}")
    v, z = _pos(value, "value"), _depth(depth)
    if knob == "kode80_pixel_z_size":
        return v
    if knob == "hdrp_relative":
        return v * z
    if knob == "fidelityfx_band":
        return v / secant(camera, pixel)
    if camera is None:
        raise ValueError("camera: ppv2_stride needs the camera (fov, size) to convert texels")
    z0 = z if origin_depth is None else _depth(origin_depth)
    return v * _ppv2_cutoff(z0) * z / _ppv2_scale(camera, resolution)


def thickness_table(thickness: float, depths: Iterable[float], camera=None, **kwargs) -> list[dict]:
    """One row per depth: ``{"depth": |z|, <knob>: value, ...}`` (see :func:`thickness_knobs`)."""
    return [{"depth": _depth(d), **thickness_knobs(thickness, d, camera, **kwargs)} for d in depths]


def thickness_table_md(thickness: float, depths: Iterable[float], camera=None, **kwargs) -> str:
    """:func:`thickness_table` as a Markdown table (docs, notes).

    Example:
        >>> print(thickness_table_md(0.1, [1.0, 10.0]).splitlines()[2])
        | 1 | 0.1 | 0.1 | 0.1 | – |
    """
    rows = thickness_table(thickness, depths, camera, **kwargs)
    head = "| depth |z| | " + " | ".join(KNOBS[k][0] for k in KNOBS) + " |"
    lines = [head, "|" + "---:|" * (len(KNOBS) + 1)]
    for r in rows:
        cells = [_g(r["depth"])] + [_g(r[k]) for k in KNOBS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _g(x: float) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    if math.isinf(x):
        return "∞"
    return f"{x:.4g}"
