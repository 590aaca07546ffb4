"""Analytic SSR test scenes (ray/plane intersections, no Mitsuba), shared by the DDA and supercover DDA tests."""
from __future__ import annotations

import math

import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes.ssr.common import reflection_rays

F64 = torch.float64


def raycast(cam: Camera, planes, dtype=F64) -> GBuffer:
    """First hit of each pixel-centre ray with world planes ``(point, normal, keep(world) -> bool)``.

    Fills view_z, normal (facing the camera), position, mask, shape_id (plane index), roughness 0 (mirrors) and
    a smooth colour of the world position; background: view_z = −far, normal 0, colour 0.
    """
    ray = cam.pixel_rays(F64)                                             # (3, H, W), view z = −1
    H, W = ray.shape[1:]
    best, sid, nrm = torch.full((H, W), math.inf, dtype=F64), torch.full((H, W), -1), torch.zeros(3, H, W, dtype=F64)
    for s, (point, normal, keep) in enumerate(planes):
        p = cam.world_to_view(torch.tensor(point, dtype=F64), dim=-1)
        n = cam.world_to_view_dir(torch.tensor(normal, dtype=F64), dim=-1)
        n = n / n.norm()
        t = (p @ n) / (ray * n.view(3, 1, 1)).sum(0)                      # hit = t·ray, view z = −t
        t = torch.where(torch.isfinite(t) & (t >= cam.near) & (t <= cam.far), t, math.inf)
        if keep is not None:
            t = torch.where(keep(cam.view_to_world(ray * torch.where(torch.isfinite(t), t, 0.0))), t, math.inf)
        closer = t < best
        facing = torch.where((ray * n.view(3, 1, 1)).sum(0) > 0, -1.0, 1.0) * n.view(3, 1, 1)
        best, sid, nrm = torch.where(closer, t, best), torch.where(closer, s, sid), torch.where(closer, facing, nrm)
    mask = torch.isfinite(best)
    view_z = torch.where(mask, -best, torch.tensor(-cam.far, dtype=F64))
    pos = ray * -view_z
    w = cam.view_to_world(pos)
    color = torch.stack([0.5 + 0.5 * torch.sin(3 * w[0]), 0.5 + 0.5 * torch.cos(2 * w[1]), 0.5 + 0.5 * torch.sin(w[2])])
    return GBuffer(cam, view_z=view_z[None, None].to(dtype), normal=nrm[None].to(dtype), position=pos[None].to(dtype),
                   mask=mask[None, None], color=(color * mask)[None].to(dtype), shape_id=sid[None, None].int(),
                   roughness=torch.zeros(1, 1, H, W, dtype=dtype))


FLOOR = ((0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
WALL = ((0.0, 0.0, -4.0), (0.0, 0.0, 1.0))


def room(w=48, h=36, dtype=F64, slat=False) -> GBuffer:
    """A mirror floor y = 0 and a wall z = −4 facing the camera (``slat``: the wall at z = −6 behind a thin bar
    at z = −4, y ∈ [0.9, 1.05])."""
    cam = Camera.from_look_at((0, 1, 2), (0, 0.5, -3), (0, 1, 0), 60.0, w, h, 0.1, 50.0)
    if not slat:
        return raycast(cam, [(*FLOOR, None), (*WALL, None)], dtype)
    bar = lambda p: (p[1] >= 0.9) & (p[1] <= 1.05)                        # noqa: E731
    return raycast(cam, [(*FLOOR, None), ((0.0, 0.0, -6.0), (0.0, 0.0, 1.0), None), (*WALL, bar)], dtype)


def with_second_layer(g: GBuffer) -> GBuffer:
    """``room(slat=True)``'s G-buffer with ``second_z``: the wall behind the bar where the bar is in front, −inf
    elsewhere (the planes are open surfaces with nothing behind them)."""
    import dataclasses
    cam = g.camera
    behind = raycast(cam, [(*FLOOR, None), ((0.0, 0.0, -6.0), (0.0, 0.0, 1.0), None)], g.view_z.dtype)
    bar = g.shape_id == 2
    return dataclasses.replace(g, second_z=torch.where(bar & behind.mask, behind.view_z, -math.inf))


def analytic(g: GBuffer, planes) -> tuple[torch.Tensor, torch.Tensor]:
    """View-space first hit of every pixel's exact mirror ray with ``planes`` (world ``(point, normal)``)."""
    cam, pos = g.camera, g.position
    R = reflection_rays(pos, g.normal)
    best = torch.full_like(pos[:, :1], math.inf)
    for point, normal in planes:
        p = cam.world_to_view(torch.tensor(point, dtype=F64), dim=-1).view(1, 3, 1, 1)
        n = cam.world_to_view_dir(torch.tensor(normal, dtype=F64), dim=-1).view(1, 3, 1, 1)
        t = ((p - pos) * n).sum(1, keepdim=True) / (R * n).sum(1, keepdim=True)
        best = torch.minimum(best, torch.where(t > 1e-9, t, math.inf))
    hit = pos + R * torch.where(torch.isfinite(best), best, 0.0)
    return hit, torch.isfinite(best) & (hit[:, 2:] < -cam.near)


def one_ray(R=None, w=33, h=25, z=-5.0, pixel=None, near=0.1, normal=None) -> GBuffer:
    """A single ``mask`` pixel at view z ``z`` whose normal reflects the eye ray into view direction ``R``."""
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 45.0, w, h, near, 100.0)
    x, y = pixel if pixel is not None else (w // 2, h // 2)
    view_z = torch.full((1, 1, h, w), -100.0, dtype=F64)
    view_z[0, 0, y, x] = z
    pos = cam.uv_to_view(cam.uv_grid(F64)[None], view_z)
    I = pos[0, :, y, x] / pos[0, :, y, x].norm()
    N = torch.tensor(normal, dtype=F64) if normal is not None else torch.tensor(R, dtype=F64) / math.hypot(*R) - I
    nrm = torch.zeros(1, 3, h, w, dtype=F64)
    nrm[0, :, y, x] = N / N.norm()
    mask = torch.zeros(1, 1, h, w, dtype=torch.bool)
    mask[0, 0, y, x] = True
    return GBuffer(cam, view_z=view_z, normal=nrm, mask=mask, color=torch.rand(1, 3, h, w, dtype=F64) * mask)
