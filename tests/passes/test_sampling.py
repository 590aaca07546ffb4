"""Seeded SSAO kernels and the rotation-noise texture (ssbench/passes/sampling.py)."""
from __future__ import annotations

import pytest
import torch

from ssbench.camera import Camera
from ssbench.passes.sampling import hemisphere_kernel, noise_texel, noise_texture, sphere_kernel


def gen(seed: int) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


class TestHemisphereKernel:
    def test_smoke(self):
        k = hemisphere_kernel(16, gen(0))
        assert k.shape == (16, 3) and k.dtype == torch.float64

    def test_distribution(self):
        k = hemisphere_kernel(4096, gen(1))
        length = k.norm(dim=1)
        assert bool((k[:, 2] >= 0).all())
        assert bool((length <= 1).all())
        # lengths grow with i: lerp(0.1, 1, (i/n)^2) times a random factor; compare means of 8 bins
        means = length.reshape(8, -1).mean(1)
        assert bool((means[1:] > means[:-1]).all()), means
        # the first sample is at most 0.1 long, the last bin reaches near 1
        assert float(length[0]) <= 0.1 and float(length[-512:].max()) > 0.95

    def test_scale_formula(self):
        # the random length factor is <1, so |k_i| <= lerp(0.1, 1, (i/n)^2) exactly
        n = 64
        t = torch.arange(n, dtype=torch.float64) / n
        assert bool((hemisphere_kernel(n, gen(2)).norm(dim=1) <= 0.1 + 0.9 * t * t + 1e-15).all())

    def test_determinism(self):
        assert torch.equal(hemisphere_kernel(32, gen(5)), hemisphere_kernel(32, gen(5)))
        assert not torch.equal(hemisphere_kernel(32, gen(5)), hemisphere_kernel(32, gen(6)))
        assert torch.equal(hemisphere_kernel(8), hemisphere_kernel(8, gen(0)))     # None: seed 0

    @pytest.mark.parametrize("n", [0, -3, 2.5, True, "8"])
    def test_exception(self, n):
        with pytest.raises(ValueError, match="n:"):
            hemisphere_kernel(n, gen(0))


class TestSphereKernel:
    def test_pairs_and_ball(self):
        k = sphere_kernel(16, gen(0))
        assert k.shape == (16, 3) and k.dtype == torch.float64
        assert torch.equal(k[0::2], -k[1::2])
        assert bool((k.norm(dim=1) < 1).all())

    def test_uniform_in_ball(self):
        k = sphere_kernel(20000, gen(3))
        r = k.norm(dim=1)
        assert abs(float((r < 0.5).double().mean()) - 1 / 8) < 0.01     # volume fraction of the inner ball
        assert float(k.mean(0).abs().max()) < 1e-12                     # exact pairs: zero mean

    def test_odd(self):
        k = sphere_kernel(5, gen(0))
        assert k.shape == (5, 3) and torch.equal(k[:4], sphere_kernel(6, gen(0))[:4])

    def test_determinism(self):
        assert torch.equal(sphere_kernel(16, gen(9)), sphere_kernel(16, gen(9)))
        assert not torch.equal(sphere_kernel(16, gen(9)), sphere_kernel(16, gen(10)))

    def test_exception(self):
        with pytest.raises(ValueError, match="n:"):
            sphere_kernel(0, gen(0))


class TestNoise:
    def test_texture(self):
        t = noise_texture(4, gen(0))
        assert t.shape == (3, 4, 4) and t.dtype == torch.float64
        assert bool((t[2] == 0).all())
        torch.testing.assert_close(t.norm(dim=0), torch.ones(4, 4, dtype=torch.float64))
        assert torch.equal(t, noise_texture(4, gen(0))) and not torch.equal(t, noise_texture(4, gen(1)))
        assert noise_texture(8, gen(0)).shape == (3, 8, 8)

    def test_texture_exception(self):
        with pytest.raises(ValueError, match="size:"):
            noise_texture(0, gen(0))

    @pytest.mark.parametrize("w,h", [(8, 8), (12, 8), (6, 4)])
    def test_texel_tiles(self, w, h):
        cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, w, h, 0.1, 10.0)
        col, row = noise_texel(cam.uv_grid(torch.float64), w, h, 4)
        assert col.shape == (h, w)
        j, i = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
        assert torch.equal(col, i % 4) and torch.equal(row, j % 4)          # H a multiple of 4

    def test_texel_batched_float32(self):
        cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 640, 360, 0.1, 10.0)
        col, row = noise_texel(cam.uv_grid(torch.float32).unsqueeze(0), 640, 360, 4)
        assert col.shape == (1, 360, 640)
        assert torch.equal(col[0, 0], torch.arange(640) % 4)
        assert int(row.min()) == 0 and int(row.max()) == 3


def test_noise_lookup_reads_the_texels_advanced_indexing_reads():
    from ssbench.passes.sampling import noise_lookup
    g = torch.Generator().manual_seed(5)
    noise = torch.rand(4, 5, 7, generator=g, dtype=torch.float64)
    row, col = torch.randint(0, 5, (2, 3, 6), generator=g), torch.randint(0, 7, (2, 3, 6), generator=g)
    got = noise_lookup(noise, row, col)
    assert got.shape == (4, 2, 3, 6) and torch.equal(got, noise[:, row, col])
    rows, cols = torch.arange(6) % 5, torch.arange(9) % 7                     # a row and a column index that broadcast
    assert torch.equal(noise_lookup(noise, rows[:, None], cols), noise[:, rows][:, :, cols])
