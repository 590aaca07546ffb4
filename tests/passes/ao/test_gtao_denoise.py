"""XeGTAO's edge-aware denoiser (ssbench.passes.ao.gtao_denoise) on synthetic and analytic G-buffers."""
import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.gbuffer import GBuffer
from ssbench.passes.ao.gtao import GTAOParams, gtao
from ssbench.passes.ao.gtao_denoise import GTAODenoise, gtao_denoise, gtao_edges

F64 = torch.float64


def flat(h=8, w=10, z=-2.0, dtype=F64):
    vz = torch.full((1, 1, h, w), z, dtype=dtype)
    return vz, torch.ones_like(vz, dtype=torch.bool)


def step(h=8, w=10):
    """Left half at z = −2, right half at z = −6 (a depth step between columns w/2 − 1 and w/2)."""
    vz, m = flat(h, w)
    vz[..., w // 2:] = -6.0
    return vz, m


def open_plane_gbuffer(w=64, h=48):
    """An infinite floor y = 0 seen from above at an angle: per-pixel ray/plane hit (as tests/passes/ao/test_gtao)."""
    cam = Camera.from_look_at((0, 4, 1), (0, 0, 0), (0, 1, 0), 30.0, w, h, 0.1, 100.0)
    rays = cam.pixel_rays(F64)                                          # (3, H, W), view z = -1
    d = cam.view_to_world_dir(rays)
    o = torch.tensor(cam.eye, dtype=F64).view(3, 1, 1)
    n = torch.tensor([0.0, 1.0, 0.0], dtype=F64).view(3, 1, 1)
    t = ((torch.zeros(3, 1, 1, dtype=F64) - o) * n).sum(0) / (d * n).sum(0)
    mask = (t > cam.near) & (t < cam.far)
    view_z = torch.where(mask, -t, torch.full_like(t, -cam.far))
    nv = cam.world_to_view_dir(n.expand(3, h, w))
    nv = torch.where((nv * rays).sum(0) > 0, -nv, nv)
    nv = torch.where(mask, nv, torch.zeros_like(nv))
    return GBuffer(cam, view_z=view_z[None, None], normal=nv[None], mask=mask[None, None])


def neighbourhood_bounds(ao):
    p = torch.nn.functional.pad(ao, (1, 1, 1, 1), mode="replicate")
    win = p.unfold(2, 3, 1).unfold(3, 3, 1)                            # (B, 1, H, W, 3, 3)
    return win.amin((-1, -2)), win.amax((-1, -2))


class TestEdges:
    def test_plane_and_step(self):
        vz, m = flat()
        vz = vz - 0.3 * torch.arange(10, dtype=F64)                     # a sloped plane: slope-adjusted Δ = 0
        e = gtao_edges(vz, m)
        assert e.shape == (1, 4, 8, 10)
        assert bool((e[..., 1:-1, 1:-1] == 1).all())
        assert bool((e[:, 0, :, 0] == 0).all()) and bool((e[:, 2, 0, :] == 0).all())   # off screen
        vz, m = step()
        e = gtao_edges(vz, m)
        assert bool((e[:, 1, :, 4] == 0).all()) and bool((e[:, 0, :, 5] == 0).all())
        assert bool((e[:, 0, :, 4] == 1).all()) and bool((e[:, 1, :, 5] == 1).all())
        assert set(torch.unique(gtao_edges(vz + 0.01 * torch.rand_like(vz), m)).tolist()) <= {0, 1 / 3, 2 / 3, 1}

    def test_background_neighbours(self):
        vz, m = flat()
        m[..., 3, 4] = False
        e = gtao_edges(vz, m)
        assert e[0, 1, 3, 3] == 0 and e[0, 0, 3, 5] == 0 and e[0, 3, 2, 4] == 0 and e[0, 2, 4, 4] == 0
        assert bool((e[0, :, 3, 4] == 0).all())


class TestDenoise:
    def test_constant_stays_constant(self):
        vz, m = step()
        ao = torch.full_like(vz, 0.37)
        assert torch.allclose(gtao_denoise(ao, vz, m), ao, atol=1e-12)
        assert torch.allclose(gtao_denoise(ao, vz, m, passes=3), ao, atol=1e-12)

    def test_no_bleeding_across_depth_step(self):
        vz, m = step()
        ao = torch.ones_like(vz)
        ao[..., 5:] = 0.2                                                 # the far side is dark
        for passes in (1, 3):
            out = gtao_denoise(ao, vz, m, passes=passes)
            assert torch.allclose(out, ao, atol=1e-12), passes

    def test_within_neighbourhood_bounds(self):
        torch.manual_seed(0)
        vz, m = flat(12, 14)
        vz = vz - 0.5 * torch.rand_like(vz)
        ao = torch.rand_like(vz)
        out = gtao_denoise(ao, vz, m)
        lo, hi = neighbourhood_bounds(ao)
        assert bool((out >= lo - 1e-12).all()) and bool((out <= hi + 1e-12).all())
        assert not torch.allclose(out, ao)

    def test_background_untouched(self):
        vz, m = flat()
        m[..., :, :3] = False
        ao = torch.full_like(vz, 0.5)
        ao[~m] = float("nan")
        out = gtao_denoise(ao, vz, m, passes=2)
        assert bool((out[~m] == 1).all())
        assert torch.allclose(out[m], torch.full_like(out[m], 0.5))      # background never leaks in

    def test_open_plane_gtao_high_hash(self):
        g = open_plane_gbuffer()
        ao = gtao(g, GTAOParams(quality="high", noise="hash", seed=3, denoise_passes=0)).ao
        raw = (ao[g.mask] >= 0.99).double().mean().item()
        den = gtao_denoise(ao, g.view_z, g.mask)
        after = (den[g.mask] >= 0.99).double().mean().item()
        print(f"open plane GTAO High hash: frac>=0.99 raw {raw:.4f} -> 1 pass {after:.4f}; "
              f"min {ao[g.mask].min().item():.4f} -> {den[g.mask].min().item():.4f}")
        assert after > raw
        assert den[g.mask].min() >= ao[g.mask].min()

    def test_module_and_gradcheck(self):
        vz, m = step(4, 5)
        m[..., 0, 0] = False
        ao = torch.rand(1, 1, 4, 5, dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(lambda a: gtao_denoise(a, vz, m, passes=2), (ao,))
        mod = GTAODenoise(passes=2, beta=0.8)
        assert torch.equal(mod(ao, vz, m), gtao_denoise(ao, vz, m, 2, 0.8))
        assert torch.equal(gtao_denoise(ao, vz, m, passes=0)[m], ao[m])

    @pytest.mark.parametrize("kwargs, name", [
        (dict(ao=torch.ones(1, 2, 8, 10)), "ao"),
        (dict(ao=torch.ones(8, 10)), "ao"),
        (dict(ao=torch.ones(1, 1, 8, 10, dtype=torch.int64)), "ao"),
        (dict(view_z=torch.ones(1, 1, 8, 9)), "view_z"),
        (dict(view_z=torch.ones(1, 3, 8, 10)), "view_z"),
        (dict(mask=torch.ones(1, 1, 7, 10, dtype=torch.bool)), "mask"),
        (dict(mask=torch.ones(1, 1, 8, 10)), "mask"),
        (dict(passes=-1), "passes"),
        (dict(passes=1.5), "passes"),
        (dict(beta=0.0), "beta"),
        (dict(beta=math.nan), "beta"),
    ])
    def test_bad_inputs(self, kwargs, name):
        vz, m = flat(dtype=torch.float32)
        args = dict(ao=torch.ones_like(vz), view_z=vz, mask=m)
        args.update(kwargs)
        with pytest.raises(ValueError, match=f"^{name}:"):
            gtao_denoise(**args)
        if name in ("view_z", "mask"):
            with pytest.raises(ValueError, match=name):
                gtao_edges(args["view_z"], args["mask"])


def test_denoise_inside_gtao_runs_before_the_clip():
    g = open_plane_gbuffer()
    raw = gtao(g, GTAOParams(noise="hash")).ao[g.mask]
    inside = gtao(g, GTAOParams(noise="hash", denoise_passes=1)).ao[g.mask]
    after = gtao_denoise(gtao(g, GTAOParams(noise="hash")).ao, g.view_z, g.mask)[g.mask]
    assert (inside >= 0.99).float().mean() >= (raw >= 0.99).float().mean()
    assert inside.mean() >= after.mean() - 1e-6            # overshoot above 1 is averaged, not clipped first
    assert float(inside.min()) >= 0.03 and float(inside.max()) <= 1.0
    with pytest.raises(ValueError, match="denoise_passes"):
        GTAOParams(denoise_passes=-1)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_the_compiled_denoise_gives_the_eager_bits(dtype):
    """Its kernels (edges, tap weights, one pass) use exact operations and divisions only: compiled, the same
    bits, background and image borders included, for several passes."""
    from ssbench.passes.compiled import compiling
    gen = torch.Generator().manual_seed(3)
    vz = -(1.0 + torch.rand(2, 1, 13, 17, generator=gen, dtype=dtype))
    vz[..., 4:9, 6:] -= 0.5                                                # a depth step: cut edges
    mask = torch.rand(2, 1, 13, 17, generator=gen) > 0.15
    ao = torch.rand(2, 1, 13, 17, generator=gen, dtype=dtype)
    for passes, beta in ((1, 1.2), (3, 0.7)):
        with compiling(False):
            eager = gtao_denoise(ao, vz, mask, passes=passes, beta=beta)
        with compiling(True):
            comp = gtao_denoise(ao, vz, mask, passes=passes, beta=beta)
        assert torch.equal(eager, comp) and not torch.equal(eager, torch.where(mask, ao, torch.ones_like(ao)))
