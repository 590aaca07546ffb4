"""The one G-buffer contract (passes/gbuffer_checks.py) and the reliability findings that live in
the passes: each test here failed on the code before the fix."""
from __future__ import annotations

import math
from dataclasses import replace

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes import ao_method, ssr_method
from ssbench.passes.gbuffer_checks import check_gbuffer, normal_tolerance
from ssbench.passes.ssr.common import HIT, NO_RAY
from tests.passes.ssr_scenes import room

AO = ("crytek", "ssao", "hbao", "gtao")
SSR = ("linear", "dda", "dda_supercover")


def _input(g, method):
    fn, P, req = (ao_method if method in AO else ssr_method)(method)
    return fn, P, g.select(tuple(sorted(set(req) | {"mask"})))


# ------------------------------------------------------------------------------ finding 1: -inf depth
@pytest.mark.parametrize("method", AO + SSR)
@pytest.mark.parametrize("value", [-math.inf, math.inf, math.nan])
def test_non_finite_depth_is_a_value_error_naming_view_z(method, value):
    g = room(16, 12)
    z = g.view_z.clone()
    z[0, 0, 6, 8] = value                                  # a pixel on geometry (gtao crashed with IndexError)
    assert bool(g.mask[0, 0, 6, 8])
    fn, P, gg = _input(replace(g, view_z=z), method)
    with pytest.raises(ValueError, match=r"^view_z: must be finite"):
        fn(gg, P())


# ------------------------------------------------------------------------------ finding 2: extreme cameras
@pytest.mark.parametrize("near,far", [(1e-7, 100.0), (1e-30, 1e30), (1e-9, 1.0), (1.0, 1e9)])
@pytest.mark.parametrize("position_from", ["depth", "view_z"])
def test_linear_ssr_extreme_near_far_is_finite(near, far, position_from):
    from ssbench.passes.ssr.linear import LinearSSRParams, ssr_linear
    g = room(48, 36)
    cam = Camera.from_look_at((0, 1, 2), (0, 0.5, -3), (0, 1, 0), 60.0, 48, 36, near, far)
    r = ssr_linear(replace(g, camera=cam), LinearSSRParams(position_from=position_from))
    assert all(bool(torch.isfinite(t).all()) for t in (r.color, r.hit_pixel, r.hit_view, r.fade))
    # at 1e-30/1e30 the depth buffer cannot hold the scene: from depth those pixels start no ray (not a crash)
    if (near, far) == (1e-30, 1e30) and position_from == "depth":
        assert bool((r.termination[g.mask] == NO_RAY).all())


def test_linear_ssr_geometry_beyond_the_far_plane_is_finite():
    from ssbench.passes.ssr.linear import ssr_linear
    g = room(48, 36)
    z = torch.where(g.mask, torch.full_like(g.view_z, -1e30), g.view_z)
    r = ssr_linear(replace(g, view_z=z))
    assert bool(torch.isfinite(r.color).all())


# ------------------------------------------------------------------------------ finding 3: background hits
@pytest.mark.parametrize("method", SSR)
def test_ssr_never_hits_the_cleared_background(method):
    cam = Camera.from_look_at((0, 1, 2), (0, 0.5, -3), (0, 1, 0), 60.0, 48, 36, 0.1, 8.0)   # far cuts the floor
    from tests.passes.ssr_scenes import FLOOR, WALL, raycast
    low = lambda p: p[1] <= 0.4                                               # noqa: E731  a low wall
    g = raycast(cam, [(*FLOOR, None), (*WALL, low)])                          # sky above: the cleared buffer
    assert 0 < int((~g.mask).sum()) < g.mask.numel()
    fn, P, gg = _input(g, method)
    r = fn(gg, P(thickness=1.0) if method == "linear" else P())
    hit = r.termination == HIT
    px = r.hit_pixel.permute(0, 2, 3, 1)[hit[:, 0]].floor().long()
    assert px.numel() > 0
    assert bool(g.mask[0, 0, px[:, 1].clamp(0, 35), px[:, 0].clamp(0, 47)].all()), "a hit on background"


# ------------------------------------------------------------------------------ finding 9: dtype, meta, radius
@pytest.mark.parametrize("dtype", [torch.float16, torch.bfloat16])
def test_normal_tolerance_scales_with_dtype(dtype):
    g = room(16, 12)
    n = g.normal.to(dtype)                                # rounding alone: |n| − 1 up to a few eps
    err = float(((n.double() ** 2).sum(1).sqrt() - 1).abs()[g.mask[:, 0]].max())
    assert err <= normal_tolerance(dtype)
    fn, P, gg = _input(g.to(dtype=dtype), "gtao")
    assert bool(torch.isfinite(fn(gg, P()).ao.float()).all())
    bad = replace(gg, normal=gg.normal * 1.2)
    with pytest.raises(ValueError, match="^normal:"):
        fn(bad, P())


@pytest.mark.parametrize("method", AO)
def test_ao_passes_run_on_meta(method):
    fn, P, gg = _input(room(16, 12).to("meta"), method)
    ao = fn(gg, P()).ao
    assert ao.device.type == "meta" and tuple(ao.shape) == (1, 1, 12, 16)


@pytest.mark.parametrize("method", SSR)
def test_ssr_passes_refuse_meta_naming_view_z(method):
    fn, P, gg = _input(room(16, 12).to("meta"), method)
    with pytest.raises(ValueError, match="^view_z: on the meta device"):
        fn(gg, P())


@pytest.mark.parametrize("method,field", [("hbao", "radius"), ("gtao", "radius")])
def test_tensor_radius_is_accepted_and_differentiable(method, field):
    fn, P, gg = _input(room(16, 12), method)
    r = torch.tensor(0.5, dtype=torch.float64, requires_grad=True)
    fn(gg, P(**{field: r})).ao.sum().backward()
    assert r.grad is not None and math.isfinite(float(r.grad)) and float(r.grad) != 0.0
    with pytest.raises(ValueError, match=f"^{field}:"):
        P(**{field: torch.tensor(-1.0)})


def test_contract_messages_name_the_channel():
    g = room(8, 6)
    with pytest.raises(ValueError, match="^normal: dtype"):
        check_gbuffer(replace(g, normal=g.normal.float()), ("view_z", "normal", "mask"))
    with pytest.raises(ValueError, match="^view_z: must be < 0 on geometry"):
        check_gbuffer(replace(g, view_z=-g.view_z), ("view_z", "mask"))
    with pytest.raises(ValueError, match="^color: contains NaN"):
        check_gbuffer(replace(g, color=g.color * math.nan), ("view_z", "mask", "color"), finite=("color",))
    with pytest.raises(TypeError, match="^gbuffer:"):
        check_gbuffer("not a gbuffer", ("view_z",))


@pytest.mark.parametrize("method", SSR)
def test_ssr_starts_no_ray_from_geometry_nearer_than_the_near_plane(method):
    g = room(16, 12)
    z = g.view_z.clone()
    z[0, 0, 8:, :] = -0.5 * g.camera.near                                  # the bottom rows: in front of near
    fn, P, gg = _input(replace(g, view_z=z), method)
    r = fn(gg, P())
    assert bool((r.termination[0, 0, 8:, :] == NO_RAY).all())
    assert bool((r.termination[0, 0, :8, :][g.mask[0, 0, :8, :]] != NO_RAY).all())
