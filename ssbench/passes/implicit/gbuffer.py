r"""Implicit-surface hits as a :class:`~ssbench.gbuffer.GBuffer`, so the AO and SSR passes run on implicit
scenes, plus supersampling (progressive-tracing article, 補足: アンチエイリアシング, "内部的に最終出力よりも高い解像度で
レンダリングし、出力時にダウンサンプリング").

Channels (:func:`to_gbuffer`): ``view_z``, ``position`` (view space, ``view_dir · t`` with the eye at the
origin), ``normal`` (view space, turned to face the camera), ``mask``, ``shape_id`` (``object_index``),
``albedo``/``roughness``/``metallic`` from the materials (indexed by ``object_index``) and a simple ``color``.
Background pixels hold exactly :data:`ssbench.gbuffer.FILL`: ``view_z = −far``, ``position`` the far-plane
point ``uv_to_view(uv, −far)`` of the pixel centre, normal/albedo 0, roughness 1, metallic 0, shape_id −1,
colour the environment radiance (0 without an environment light). ``back_z`` is not produced.

Shading (the article leaves it open, シェーディング): Lambert ``albedo/π · E`` from ``point`` lights
(``E = I·cos/r²``) and ``directional`` lights (``E = irradiance·cos``), plus ``albedo·radiance`` of an
``environment`` light and ``ambient·albedo``; no shadows. Without lights a headlight along the view direction
gives ``albedo`` on a surface facing the camera. A hit whose gradient is 0 (no normal) gets the normal
``−view_dir`` so the G-buffer normals stay unit length.
"""
from __future__ import annotations

import math
from typing import Callable, Optional, Sequence

import torch
import torch.nn.functional as F

from ...camera import Camera
from ...gbuffer import GBuffer
from .common import CameraRays, ImplicitResult, camera_rays, safe_normal

__all__ = ["to_gbuffer", "supersample", "DEFAULT_MATERIAL"]

#: albedo, roughness, metallic of objects without a material (as ``ssbench.scenes.model.Material()``)
DEFAULT_MATERIAL = ((0.7, 0.7, 0.7), 1.0, 0.0)


def _get(obj, key: str, default=None):
    if isinstance(obj, dict):
        return obj.get(key, default)
    if hasattr(obj, "param") and not hasattr(obj, key):          # ssbench.scenes.model.Light
        try:
            return obj.param(key)
        except KeyError:
            return default
    return getattr(obj, key, default)


def _rgb(v, name: str) -> tuple[float, float, float]:
    v = (float(v),) * 3 if isinstance(v, (int, float)) else tuple(float(x) for x in v)
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise ValueError(f"{name}: expected a number or three finite numbers, got {v!r}")
    return v  # type: ignore[return-value]


def _material_tables(materials, n_obj: int, dtype, device):
    mats = list(materials) if materials is not None else []
    rows = []
    for i in range(max(n_obj, len(mats), 1)):
        if i < len(mats) and mats[i] is not None:
            m = mats[i]
            rows.append((_rgb(_get(m, "albedo", DEFAULT_MATERIAL[0]), f"materials[{i}].albedo"),
                         float(_get(m, "roughness", 1.0)), float(_get(m, "metallic", 0.0))))
        elif materials is not None and i < n_obj:
            raise ValueError(f"materials: object index {i} is hit but has no material ({len(mats)} given)")
        else:
            rows.append(DEFAULT_MATERIAL)
    alb = torch.tensor([r[0] for r in rows], dtype=dtype, device=device)          # (M, 3)
    rgh = torch.tensor([r[1] for r in rows], dtype=dtype, device=device)          # (M,)
    met = torch.tensor([r[2] for r in rows], dtype=dtype, device=device)
    return alb, rgh, met


def _shade(p, n, albedo, lights, ambient: float, view_dir_world):
    """Lambert radiance (B, 3, H, W) at world points p with facing world normals n."""
    inv_pi = 1.0 / math.pi
    if lights is None:                                            # headlight: E = π·cos → L = albedo·cos
        cos = (n * -view_dir_world).sum(1, keepdim=True).clamp_min(0)
        return albedo * cos + ambient * albedo
    out = ambient * albedo
    for i, light in enumerate(lights):
        kind = _get(light, "type")
        if kind == "point":
            pos = torch.tensor(_rgb(_get(light, "position"), f"lights[{i}].position"), dtype=p.dtype,
                               device=p.device).view(1, 3, 1, 1)
            inten = torch.tensor(_rgb(_get(light, "intensity", 1.0), f"lights[{i}].intensity"), dtype=p.dtype,
                                 device=p.device).view(1, 3, 1, 1)
            v = pos - p
            r2 = (v * v).sum(1, keepdim=True).clamp_min(torch.finfo(p.dtype).tiny)
            cos = (n * v).sum(1, keepdim=True).clamp_min(0) / r2.sqrt()
            out = out + albedo * inv_pi * inten * cos / r2
        elif kind == "directional":
            dirn = torch.tensor(_rgb(_get(light, "direction"), f"lights[{i}].direction"), dtype=p.dtype,
                                device=p.device).view(1, 3, 1, 1)
            dirn = dirn / dirn.norm().clamp_min(torch.finfo(p.dtype).tiny)
            irr = torch.tensor(_rgb(_get(light, "irradiance", 1.0), f"lights[{i}].irradiance"), dtype=p.dtype,
                               device=p.device).view(1, 3, 1, 1)
            out = out + albedo * inv_pi * irr * (n * -dirn).sum(1, keepdim=True).clamp_min(0)
        elif kind == "environment":
            rad = torch.tensor(_rgb(_get(light, "radiance", 1.0), f"lights[{i}].radiance"), dtype=p.dtype,
                               device=p.device).view(1, 3, 1, 1)
            out = out + albedo * rad
        else:
            raise ValueError(f"lights[{i}]: unknown light type {kind!r} (point, directional, environment)")
    return out


def _environment(lights, dtype, device):
    for light in lights or ():
        if _get(light, "type") == "environment":
            return torch.tensor(_rgb(_get(light, "radiance", 1.0), "radiance"), dtype=dtype,
                                device=device).view(1, 3, 1, 1)
    return torch.zeros(1, 3, 1, 1, dtype=dtype, device=device)


def to_gbuffer(result: ImplicitResult, rays: Optional[CameraRays], camera: Camera,
               materials: Optional[Sequence] = None, lights: Optional[Sequence] = None, shade: bool = True,
               ambient: float = 0.05) -> GBuffer:
    r"""A :class:`~ssbench.gbuffer.GBuffer` of an implicit ray caster's hits (background as ``FILL``).

    Args:
        result: :class:`ImplicitResult` of camera rays, :math:`(B, C, H, W)` tensors.
        rays: the :class:`CameraRays` the result was cast with (None: pixel-centre rays of ``camera``).
        camera: the camera (its resolution must match the result).
        materials: per object index: ``Material``-like objects or dicts with ``albedo``, ``roughness``,
            ``metallic`` (None: :data:`DEFAULT_MATERIAL` for all).
        lights: ``ssbench.scenes.model.Light``-like objects or dicts (``type`` point / directional /
            environment); None: a headlight.
        shade: compute ``color``.
        ambient: ambient term ``ambient·albedo`` added on hits.

    Example:
        >>> from ssbench.passes.implicit.analytic import analytic_sphere
        >>> cam = Camera.from_look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 45.0, 8, 6, 0.1, 10.0)
        >>> rays = camera_rays(cam, dtype=torch.float64)
        >>> g = to_gbuffer(analytic_sphere(rays, (0, 0, 0), 1.0), rays, cam)
        >>> g.channels, float(g.view_z.min())
        (('view_z', 'normal', 'position', 'albedo', 'roughness', 'metallic', 'shape_id', 'mask', 'color'), -10.0)
    """
    if not isinstance(result, ImplicitResult):
        raise TypeError(f"result: expected an ImplicitResult, got {type(result).__name__}")
    if not isinstance(camera, Camera):
        raise TypeError(f"camera: expected a Camera, got {type(camera).__name__}")
    B, _, H, W = result.t.shape
    if (H, W) != (camera.height, camera.width):
        raise ValueError(f"camera: resolution {camera.width}x{camera.height} differs from the result's {W}x{H}")
    dt, dev = result.t.dtype, result.t.device
    if rays is None:
        rays = camera_rays(camera, batch=B, dtype=dt, device=dev)
    hit = result.hit
    far_pos = camera.uv_to_view(camera.uv_grid(dt, dev), torch.full((1, H, W), -camera.far, dtype=dt, device=dev),
                                dim=0).unsqueeze(0)                              # (1, 3, H, W)
    vdir = rays.view_dir.to(dt)
    position = torch.where(hit, vdir * result.t, far_pos)
    view_z = position[:, 2:3].contiguous()
    n_view = safe_normal(camera.world_to_view_dir(result.normal).permute(0, 2, 3, 1)).permute(0, 3, 1, 2)
    n_view = torch.where((n_view.abs().sum(1, keepdim=True) > 0), n_view, -vdir)       # zero gradient
    n_view = torch.where((n_view * vdir).sum(1, keepdim=True) > 0, -n_view, n_view)     # face the camera
    normal = torch.where(hit, n_view, torch.zeros_like(n_view))
    shape_id = torch.where(hit, result.object_index, -1).to(torch.int32)
    n_obj = int(shape_id.max().item()) + 1 if bool(hit.any()) else 0
    alb_t, rgh_t, met_t = _material_tables(materials, n_obj, dt, dev)
    idx = shape_id.clamp_min(0).long().squeeze(1)                                  # (B, H, W)
    albedo = torch.where(hit, alb_t[idx].permute(0, 3, 1, 2), torch.zeros(1, 3, 1, 1, dtype=dt, device=dev))
    roughness = torch.where(hit, rgh_t[idx].unsqueeze(1), torch.ones(1, 1, 1, 1, dtype=dt, device=dev))
    metallic = torch.where(hit, met_t[idx].unsqueeze(1), torch.zeros(1, 1, 1, 1, dtype=dt, device=dev))
    color = None
    if shade:
        d = rays.direction.to(dt)
        p = rays.origin.to(dt) + result.t * d
        n_w = torch.where((result.normal * d).sum(1, keepdim=True) > 0, -result.normal, result.normal)
        n_w = torch.where(n_w.abs().sum(1, keepdim=True) > 0, n_w, -d)
        lit = _shade(p, n_w, albedo, lights, float(ambient), d)
        color = torch.where(hit, lit, _environment(lights, dt, dev).expand(B, 3, H, W))
    return GBuffer(camera, view_z=view_z, normal=normal, position=position, albedo=albedo, roughness=roughness,
                   metallic=metallic, shape_id=shape_id, mask=hit.clone(), color=color)


def supersample(cast: Callable[[Camera], ImplicitResult], camera: Camera, factor: int,
                materials: Optional[Sequence] = None, lights: Optional[Sequence] = None
                ) -> tuple[torch.Tensor, torch.Tensor, GBuffer]:
    r"""Supersampling anti-aliasing (補足: アンチエイリアシング): cast at ``factor``× the resolution
    (:meth:`Camera.with_resolution`, same vertical fov, so each output pixel is tiled by ``factor²`` samples),
    shade with :func:`to_gbuffer` and average-pool.

    Args:
        cast: ``camera → ImplicitResult`` for that camera's pixel-centre rays (any method; a stateful
            progressive renderer keeps its own high-resolution state).
        factor: ``k ≥ 1``.

    Returns:
        ``(color (B, 3, H, W), coverage (B, 1, H, W), high-resolution GBuffer)``; coverage is the fraction of
        sub-samples that hit.
    """
    if isinstance(factor, bool) or not isinstance(factor, int) or factor < 1:
        raise ValueError(f"factor: must be an integer >= 1, got {factor!r}")
    hi = camera.with_resolution(camera.width * factor, camera.height * factor)
    res = cast(hi)
    rays = res.debug.get("rays") if isinstance(res.debug.get("rays"), CameraRays) else None
    g = to_gbuffer(res, rays, hi, materials, lights)
    color = F.avg_pool2d(g.color, factor)
    coverage = F.avg_pool2d(g.mask.to(g.color.dtype), factor)
    return color, coverage, g
