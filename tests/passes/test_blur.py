"""AO blurs (ssbench.passes.blur): SSAO article §2.3 box blur, §3.2 cross-bilateral blur, kornia joint bilateral."""
import math

import pytest
import torch

from ssbench.passes.blur import (BoxBlur, CrossBilateralBlur, JointBilateralBlur, box_blur, cross_bilateral_blur,
                                 default_blur_falloff, joint_bilateral_blur)

F64 = torch.float64
E = math.exp(-1.0)


def rand(*shape, seed=0):
    return torch.rand(*shape, generator=torch.Generator().manual_seed(seed), dtype=F64)


def step_scene(h=6, w=10):
    """Left half: ao 0.2 at z = -2; right half: ao 0.9 at z = -5."""
    ao = torch.full((1, 1, h, w), 0.2, dtype=F64)
    z = torch.full((1, 1, h, w), -2.0, dtype=F64)
    ao[..., w // 2:], z[..., w // 2:] = 0.9, -5.0
    return ao, z


class TestBoxBlur:
    def test_constant_stays_constant(self):
        x = torch.full((2, 1, 7, 9), 0.37, dtype=F64)
        for border in ("replicate", "reflect", "circular"):
            assert torch.allclose(box_blur(x, border_type=border), x)

    def test_interior_is_5x5_mean_and_border_clamps(self):
        x = rand(2, 1, 9, 11)
        out = box_blur(x)
        for r, c in [(2, 2), (4, 5), (6, 8)]:
            assert torch.allclose(out[:, :, r, c], x[:, :, r - 2:r + 3, c - 2:c + 3].mean((-2, -1)))
        # the article's texture2D(vUv + offset) with CLAMP_TO_EDGE, every pixel
        H, W = 9, 11
        ref = torch.zeros_like(x)
        for i in range(-2, 3):
            for j in range(-2, 3):
                rows = (torch.arange(H) + j).clamp(0, H - 1)
                cols = (torch.arange(W) + i).clamp(0, W - 1)
                ref += x[:, :, rows][:, :, :, cols]
        assert torch.allclose(out, ref / 25.0)
        assert box_blur(x, 3).shape == x.shape

    def test_mask_keeps_background_out(self):
        ao, _ = step_scene()
        mask = torch.zeros_like(ao, dtype=torch.bool)
        mask[..., :5] = True                                # geometry on the left, background (ao 0.9) right
        out = box_blur(ao, mask=mask)
        assert torch.allclose(out[mask], ao[mask])
        assert torch.equal(out[~mask], ao[~mask])
        assert float(box_blur(ao)[0, 0, 0, 4]) > 0.2 + 0.1   # the unmasked article blur bleeds

    def test_module(self):
        x = rand(1, 1, 6, 7)
        assert torch.equal(BoxBlur(3)(x), box_blur(x, 3))

    def test_gradcheck(self):
        x = rand(1, 1, 5, 5).requires_grad_()
        m = torch.ones(1, 1, 5, 5, dtype=torch.bool)
        m[..., 0, 0] = False
        assert torch.autograd.gradcheck(lambda t: box_blur(t, 3), (x,))
        assert torch.autograd.gradcheck(lambda t: box_blur(t, 3, mask=m), (x,))

    def test_exceptions(self):
        x = rand(1, 1, 5, 5)
        with pytest.raises(ValueError, match="kernel_size"):
            box_blur(x, 4)
        with pytest.raises(ValueError, match="ao"):
            box_blur(x[0])
        with pytest.raises(ValueError, match="border_type"):
            box_blur(x, border_type="wrap")
        with pytest.raises(ValueError, match="mask"):
            box_blur(x, mask=torch.ones(1, 1, 5, 5))


class TestCrossBilateralBlur:
    def test_hand_computed_1d(self):
        ao = torch.tensor([0.0, 1.0, 0.0, 0.0, 1.0], dtype=F64).view(1, 1, 1, 5)
        z = torch.full_like(ao, -3.0)
        # article loop, KERNEL_RADIUS 1: taps i = -1, 0 plus the initial centre, falloff 1 => w(-1) = e^-1
        d = 2.0 + E
        expect = torch.tensor([0.0, 2.0 / d, E / d, 0.0, 2.0 / d], dtype=F64)
        out = cross_bilateral_blur(ao, z, 1, blur_falloff=1.0, threshold=1.0)
        assert torch.allclose(out.flatten(), expect)        # H = 1: the vertical pass is the identity
        # symmetric loop i = -1..1, centre once
        d = 1.0 + 2.0 * E
        expect = torch.tensor([E, 1.0, E, E, 1.0 + E], dtype=F64) / d
        out = cross_bilateral_blur(ao, z, 1, blur_falloff=1.0, threshold=1.0, article_loop=False)
        assert torch.allclose(out.flatten(), expect)
        # |Δz| >= threshold drops the tap: pixel 2's left neighbour is 5 units nearer
        z2 = torch.tensor([-3.0, -3.0, -8.0, -8.0, -8.0], dtype=F64).view(1, 1, 1, 5)
        out = cross_bilateral_blur(ao, z2, 1, blur_falloff=1.0, threshold=1.0)
        assert float(out.flatten()[2]) == 0.0

    def test_vertical_pass_and_box_limit(self):
        x = rand(1, 1, 9, 8)
        z = torch.full_like(x, -4.0)
        out = cross_bilateral_blur(x, z, 2, blur_falloff=0.0, threshold=1.0, article_loop=False)
        assert torch.allclose(out, box_blur(x, 5))          # flat Gaussian, no edges: a 5x5 box
        t = cross_bilateral_blur(x.transpose(-1, -2), z.transpose(-1, -2), 3, article_loop=True)
        assert torch.allclose(t.transpose(-1, -2), cross_bilateral_blur(x, z, 3))

    def test_no_blur_across_depth_step(self):
        ao, z = step_scene()
        out = cross_bilateral_blur(ao, z, 15, threshold=0.5)
        assert torch.allclose(out, ao)
        assert float(cross_bilateral_blur(ao, z, 15, threshold=5.0)[0, 0, 0, 4]) > 0.25

    def test_background_rejected_by_threshold(self):
        ao, z = step_scene()
        z[..., 5:] = -100.0                                 # background: view z = -far, ao 1
        ao[..., 5:] = 1.0
        out = cross_bilateral_blur(ao, z, 4)
        assert torch.allclose(out[..., :5], ao[..., :5])
        mask = z > -50
        assert torch.allclose(cross_bilateral_blur(ao, z, 4, threshold=1e3, mask=mask)[..., :5], ao[..., :5])

    def test_default_falloff(self):
        assert default_blur_falloff(15) == pytest.approx(1.0 / (2.0 * 8.0 ** 2))

    def test_module(self):
        x, z = rand(1, 1, 6, 7), -1.0 - rand(1, 1, 6, 7, seed=1)
        assert torch.equal(CrossBilateralBlur(3, 0.2, 0.5)(x, z), cross_bilateral_blur(x, z, 3, 0.2, 0.5))

    def test_gradcheck(self):
        x = rand(1, 1, 5, 5).requires_grad_()
        z = -1.0 - rand(1, 1, 5, 5, seed=1)
        assert torch.autograd.gradcheck(lambda t: cross_bilateral_blur(t, z, 2, threshold=0.5), (x,))
        assert torch.autograd.gradcheck(lambda t: cross_bilateral_blur(t, z, 2, article_loop=False), (x,))

    def test_exceptions(self):
        x, z = rand(1, 1, 5, 5), -torch.ones(1, 1, 5, 5, dtype=F64)
        with pytest.raises(ValueError, match="view_z"):
            cross_bilateral_blur(x, z[..., :4])
        with pytest.raises(ValueError, match="kernel_radius"):
            cross_bilateral_blur(x, z, 0)
        with pytest.raises(ValueError, match="threshold"):
            cross_bilateral_blur(x, z, threshold=-1.0)
        with pytest.raises(ValueError, match="blur_falloff"):
            cross_bilateral_blur(x, z, blur_falloff=float("inf"))


class TestJointBilateralBlur:
    def test_preserves_depth_edge(self):
        ao, z = step_scene()
        lin = (z + 0.1) / (0.1 - 100.0)                      # linear depth, step of 0.03
        out = joint_bilateral_blur(ao, lin, 5, sigma_color=0.002, sigma_space=(1.5, 1.5))
        assert torch.allclose(out, ao, atol=1e-6)
        assert float((box_blur(ao) - ao).abs().max()) > 0.2  # a box blur smears the same edge

    def test_mask_excludes_background_exactly(self):
        ao, z = step_scene()
        mask = torch.zeros_like(ao, dtype=torch.bool)
        mask[..., :5] = True
        lin = (z + 0.1) / (0.1 - 100.0)
        out = joint_bilateral_blur(ao, lin, 5, sigma_color=1.0, mask=mask)
        assert torch.allclose(out[mask], ao[mask]) and torch.equal(out[~mask], ao[~mask])

    def test_constant_and_module(self):
        x = torch.full((1, 1, 6, 7), 0.4, dtype=F64)
        g = rand(1, 1, 6, 7)
        assert torch.allclose(joint_bilateral_blur(x, g), x)
        y = rand(1, 1, 6, 7, seed=2)
        assert torch.equal(JointBilateralBlur(3, 0.1)(y, g), joint_bilateral_blur(y, g, 3, 0.1))

    def test_gradcheck(self):
        x = rand(1, 1, 5, 5).requires_grad_()
        g = rand(1, 1, 5, 5, seed=1)
        assert torch.autograd.gradcheck(lambda t: joint_bilateral_blur(t, g, 3, 0.5, (1.0, 1.0)), (x,))

    def test_exceptions(self):
        x = rand(1, 1, 5, 5)
        with pytest.raises(ValueError, match="guide_depth"):
            joint_bilateral_blur(x, x[:, :, :4])
        with pytest.raises(ValueError, match="sigma_color"):
            joint_bilateral_blur(x, x, sigma_color=0.0)
        with pytest.raises(ValueError, match="sigma_space"):
            joint_bilateral_blur(x, x, sigma_space=(1.0,))
        with pytest.raises(ValueError, match="kernel_size"):
            joint_bilateral_blur(x, x, kernel_size=2)


def _fd_check(f, value: float, h: float = 1e-6):
    """Autograd of ``f(0-d float64 tensor)`` at ``value`` and its float64 central difference."""
    x = torch.tensor(value, dtype=torch.float64, requires_grad=True)
    (g,) = torch.autograd.grad(f(x), x)
    fd = (float(f(torch.tensor(value + h, dtype=torch.float64)))
          - float(f(torch.tensor(value - h, dtype=torch.float64)))) / (2 * h)
    return float(g), fd


class TestTensorParameters:
    """A 0-d tensor parameter keeps its gradient, equal to a float64 central difference; the value matches the
    float path."""

    def _scene(self):
        gen = torch.Generator().manual_seed(3)
        ao = torch.rand(1, 1, 12, 14, generator=gen, dtype=torch.float64)
        z = -2.0 - 0.3 * torch.rand(1, 1, 12, 14, generator=gen, dtype=torch.float64)
        w = torch.linspace(0, 1, 12 * 14, dtype=torch.float64).view(1, 1, 12, 14)   # a non-uniform loss weight
        return ao, z, w

    @pytest.mark.parametrize("name, value", [("sigma_color", 0.02), ("sigma_space", 1.3)])
    def test_joint_bilateral_sigmas(self, name, value):
        ao, z, w = self._scene()
        guide = (-z - 2.0) / 0.3
        mask = torch.ones_like(ao, dtype=torch.bool)
        mask[..., 0, :3] = False
        f = lambda x: (w * joint_bilateral_blur(ao, guide, 5, mask=mask, **{name: x})).sum()   # noqa: E731
        g, fd = _fd_check(f, value, 1e-6)
        assert g != 0.0 and g == pytest.approx(fd, rel=1e-4)
        as_float = {name: value if name == "sigma_color" else (value, value)}
        assert float(f(torch.tensor(value, dtype=torch.float64))) == pytest.approx(
            float((w * joint_bilateral_blur(ao, guide, 5, mask=mask, **as_float)).sum()), rel=1e-8)

    @pytest.mark.parametrize("article_loop", [True, False])
    def test_cross_bilateral_falloff_and_threshold(self, article_loop):
        ao, z, w = self._scene()
        f = lambda x: (w * cross_bilateral_blur(ao, z, 3, x, 0.2, article_loop=article_loop)).sum()  # noqa: E731
        g, fd = _fd_check(f, 0.05)
        assert g != 0.0 and g == pytest.approx(fd, rel=1e-4)
        assert float(f(torch.tensor(0.05, dtype=torch.float64))) == pytest.approx(
            float((w * cross_bilateral_blur(ao, z, 3, 0.05, 0.2, article_loop=article_loop)).sum()), rel=1e-12)
        t = torch.tensor(0.2, dtype=torch.float64, requires_grad=True)
        assert not cross_bilateral_blur(ao, z, 3, 0.05, t).requires_grad        # a step: no autograd path

    def test_bad_tensor_parameters_are_rejected(self):
        ao, z, _ = self._scene()
        with pytest.raises(ValueError, match="blur_falloff"):
            cross_bilateral_blur(ao, z, 3, torch.tensor(-1.0))
        with pytest.raises(ValueError, match="sigma_color"):
            joint_bilateral_blur(ao, z, 5, torch.tensor([0.1, 0.2]))
        with pytest.raises(ValueError, match="sigma_space"):
            joint_bilateral_blur(ao, z, 5, 0.1, torch.tensor(0.0))
