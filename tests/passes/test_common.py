"""ssbench.passes.common: `length` (torch's vector norm to an ulp, faster over the channel dim, safe gradients),
`vector_norm` (torch's vector norm bit for bit, faster over the channel dim), `cross` (torch's cross bit for bit) and the row bands that bound the AO passes' working set (bit-identical to the whole image)."""
import math

import pytest
import torch

from ssbench.passes.common import cross, length, vector_norm
from ssbench.rays import cross_components


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("shape, dim", [((2, 3, 7, 9), 1), ((50, 3), -1), ((3, 40), 0)])
def test_length_equals_linalg_vector_norm_to_an_ulp(dtype, shape, dim):
    g = torch.Generator().manual_seed(0)
    x = torch.randn(*shape, generator=g, dtype=dtype) * 10.0 ** torch.randint(-3, 4, shape, generator=g)
    ref = torch.linalg.vector_norm(x, dim=dim, keepdim=True)
    got = length(x, dim=dim)
    assert got.shape == ref.shape and got.dtype == dtype
    assert torch.allclose(got, ref, rtol=4 * torch.finfo(dtype).eps, atol=0)
    assert length(x, dim=dim, keepdim=False).shape == torch.linalg.vector_norm(x, dim=dim).shape


def test_length_of_zero_vectors_is_zero_and_its_gradient_is_finite():
    x = torch.zeros(1, 3, 2, 2)
    x[0, :, 0, 0] = torch.tensor([3.0, 4.0, 0.0])
    assert length(x).flatten().tolist() == [5.0, 0.0, 0.0, 0.0]
    x.requires_grad_(True)
    length(x).sum().backward()                                  # sqrt'(0) would make NaN; the norm's is 0
    assert torch.isfinite(x.grad).all()
    assert torch.allclose(x.grad[0, :, 0, 0], torch.tensor([0.6, 0.8, 0.0]))
    assert (x.grad[0, :, 1, 1] == 0).all()


def special_values(shape, dtype, seed=0):
    """Random vectors over 14 decades, with zeros, signed zeros, infinities, NaNs, subnormals and squares that
    overflow planted at the front."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(*shape, generator=g, dtype=dtype) * 10.0 ** torch.randint(-7, 8, shape, generator=g)
    tiny = torch.finfo(dtype).tiny
    planted = [0.0, -0.0, math.inf, -math.inf, math.nan, tiny / 8, -tiny / 3, 3e19, 1e155, -2e30, 1.0, 0.0]
    x.view(-1)[:len(planted)] = torch.tensor(planted, dtype=torch.float64).to(dtype)
    return x


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("shape, dim", [((1, 3, 96, 128), 1), ((2, 3, 5, 7, 9), 1), ((2, 3, 7, 9), -3),
                                        ((3, 2, 40), 0), ((2, 4, 1, 5), 1), ((50, 3), 1), ((4, 3, 1, 1), 1)])
def test_vector_norm_gives_the_bits_of_linalg_vector_norm(threads, dtype, shape, dim):
    # (1, 3, 96, 128): torch's vectorised sqrt would differ from the norm's in about 70 of these 12 288 roots
    x = special_values(shape, dtype)
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        for keepdim in (True, False):
            ref = torch.linalg.vector_norm(x, dim=dim, keepdim=keepdim)
            got = vector_norm(x, dim, keepdim)
            assert got.shape == ref.shape and got.dtype == ref.dtype
            assert torch.equal(got.isnan(), ref.isnan())
            assert torch.equal(got.nan_to_num(0.0), ref.nan_to_num(0.0))
    finally:
        torch.set_num_threads(before)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("shape, dim", [((1, 3, 96, 129), 1), ((2, 3, 5, 7, 9), 1), ((2, 3, 7, 9), -3),
                                        ((3, 40, 2), 0), ((51, 3), 1), ((4, 3, 1, 1), 1)])
def test_cross_gives_the_bits_of_linalg_cross(dtype, shape, dim):
    # ATen's CPU cross is one FMA per component; a cross written a₁b₂ − a₂b₁ differs in a third of these
    a, b = special_values(shape, dtype, seed=1), special_values(shape, dtype, seed=2).flip(dim)
    ref, got = torch.linalg.cross(a, b, dim=dim), cross(a, b, dim=dim)
    apart = torch.stack(cross_components(a.unbind(dim), b.unbind(dim)), dim)    # on components kept apart
    assert torch.equal(apart.nan_to_num(1e5), got.nan_to_num(1e5))
    assert got.shape == ref.shape and got.dtype == ref.dtype
    assert torch.equal(got.isnan(), ref.isnan())
    assert torch.equal(got.nan_to_num(0.0), ref.nan_to_num(0.0))
    if ref.numel() > 100:                                                     # the test tells the two apart
        plain = a.select(dim, 1) * b.select(dim, 2) - a.select(dim, 2) * b.select(dim, 1)
        x = ref.select(dim, 0)
        assert (plain != x)[x.isfinite()].any()


def test_cross_falls_back_to_torch_for_gradients_and_mixed_dtypes():
    a = torch.randn(2, 3, 4, 5, dtype=torch.float64, requires_grad=True)
    b = torch.randn(2, 3, 4, 5, dtype=torch.float64)
    cross(a, b).sum().backward()
    ref = a.detach().clone().requires_grad_(True)
    torch.linalg.cross(ref, b, dim=1).sum().backward()
    assert torch.equal(a.grad, ref.grad)
    assert torch.equal(cross(b.float(), b.float()), torch.linalg.cross(b.float(), b.float(), dim=1))
    assert cross(b.half(), b.half()).dtype == torch.float16
    apart = torch.stack(cross_components(a.unbind(1), b.unbind(1)), 1)             # the same fallback on components
    assert apart.requires_grad and torch.equal(apart, torch.linalg.cross(a, b, dim=1))
    h = b.half()
    assert torch.equal(torch.stack(cross_components(h.unbind(1), h.flip(2).unbind(1)), 1),
                       torch.linalg.cross(h, h.flip(2), dim=1))


@pytest.mark.slow
def test_cross_components_compiled_give_the_bits_of_compiled_linalg_cross():
    """Inside ``torch.compile`` the components are ``a₁b₂ − a₂b₁`` …, what inductor makes of ``torch.linalg.cross``,
    with no stacked operands."""
    g = torch.Generator().manual_seed(5)
    a = [torch.randn(4096, generator=g) * 10.0 for _ in range(3)]
    b = [torch.randn(4096, generator=g) for _ in range(3)]
    apart = torch.compile(lambda a, b: torch.stack(cross_components(a, b), 1))(a, b)
    stacked = torch.compile(lambda a, b: torch.linalg.cross(torch.stack(a, 1), torch.stack(b, 1), dim=1))(a, b)
    assert torch.equal(apart, stacked)
    eager = torch.stack(cross_components(a, b), 1)                                  # ATen's FMA bits eager
    assert not torch.equal(apart, eager) and torch.allclose(apart, eager, rtol=1e-5, atol=1e-5)


def test_vector_norm_falls_back_to_torch_for_strided_inputs_and_gradients():
    x = special_values((1, 3, 16, 20), torch.float32)[..., ::2].nan_to_num(0.0, 0.0, 0.0)   # not contiguous
    assert torch.equal(vector_norm(x), torch.linalg.vector_norm(x, dim=1, keepdim=True))
    x = x.clone().requires_grad_(True)
    vector_norm(x).sum().backward()
    assert torch.isfinite(x.grad).all()


@pytest.mark.parametrize("method", ["crytek", "ssao", "hbao", "gtao", "three_gtao", "sao"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_banded_ao_passes_equal_the_whole_image_bit_for_bit(method, dtype, monkeypatch):
    """The AO passes work on bands of rows (``row_bands``) to bound their working set; a band of one row and
    one band for the whole image give the same bits, debug buffers (and GTAO's bent normals) included."""
    import dataclasses

    import ssbench.passes.common as C
    from ssbench.passes import ao_method
    from tests.passes.ssr_scenes import room
    g = dataclasses.replace(room(40, 30, dtype, slat=True), color=None)
    fn, params_cls, _ = ao_method(method)
    kw = {"bent_normals": True} if method == "gtao" else {}

    def run(budget):
        monkeypatch.setattr(C, "BLOCK_BYTES", budget)
        return fn(g, params_cls(), generator=torch.Generator().manual_seed(3), debug=True, **kw)

    assert len(C.row_bands(30, 40, 8, 4, 1)) == 30                       # budget 1 byte: one row per band
    whole, banded = run(1 << 40), run(1)
    assert torch.equal(whole.ao, banded.ao) and 0 < float(whole.ao.mean()) < 1
    assert whole.debug.keys() == banded.debug.keys() and whole.debug
    for k, v in whole.debug.items():
        assert not isinstance(v, torch.Tensor) or torch.equal(v, banded.debug[k]), k
    if method == "gtao":
        assert torch.equal(whole.bent_normal, banded.bent_normal)


@pytest.mark.slow
@pytest.mark.parametrize("B, C", [(1, 1), (3, 2)])
def test_fetch_texels_compiled_reads_the_texels_of_fetch(B, C):
    """Inside ``torch.compile`` the read gathers at float-formed flat indices: the same texels as :func:`fetch`,
    batched, multi-channel and at the image's corners."""
    from ssbench.passes import compiled
    from ssbench.passes.common import fetch, fetch_texels
    g = torch.Generator().manual_seed(4)
    H, W = 7, 11
    tex = torch.randn(B, C, H, W, generator=g)
    col = torch.randint(0, W, (B, 2, 5, 4), generator=g)
    row = torch.randint(0, H, (B, 2, 5, 4), generator=g)
    col[..., 0, 0], row[..., 0, 0], col[..., 1, 1], row[..., 1, 1] = 0, 0, W - 1, H - 1
    read = compiled.kernel(lambda t, c, r: fetch_texels(t, c * 1.0, r * 1.0))
    with compiled.compiling(True):
        got = read(tex, col.float(), row.float())
    assert got.shape == (B, C, 2, 5, 4) and torch.equal(got, fetch(tex, col, row))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64, torch.bfloat16])
@pytest.mark.parametrize("B, C", [(1, 1), (2, 1), (1, 3), (3, 2)])
def test_fetch_texels_reads_the_texels_of_fetch(dtype, B, C):
    """The float-index read (one conversion, ``index_select``) returns exactly :func:`fetch`'s texels, batched,
    multi-channel and at the image's corners; ``gl_texel`` picks the texel of GL's rounding in int64."""
    from ssbench.passes.common import fetch, fetch_texels, gl_texel
    g = torch.Generator().manual_seed(3)
    H, W = 7, 11
    tex = torch.randn(B, C, H, W, generator=g, dtype=torch.float64)
    col = torch.randint(0, W, (B, 2, 5, 4), generator=g)
    row = torch.randint(0, H, (B, 2, 5, 4), generator=g)
    col[..., 0, 0], row[..., 0, 0], col[..., 1, 1], row[..., 1, 1] = 0, 0, W - 1, H - 1
    got = fetch_texels(tex, col.to(dtype), row.to(dtype))
    assert got.shape == (B, C, 2, 5, 4) and torch.equal(got, fetch(tex, col, row))
    u = torch.tensor([[-1.0, 0.0, 0.5 / W, 0.3, 1.0, 2.0, float("nan"), float("inf")]], dtype=dtype)
    v = torch.tensor([[0.2, 1.0, float("nan"), -float("inf"), 0.0, 0.99, 0.5, 0.7]], dtype=dtype)
    c, r = gl_texel(u, v, H, W)
    col = torch.floor(u * W).nan_to_num(0.0).clamp(0, W - 1).long()        # GL: row ⌊v·H⌋ from the bottom
    gl_row = torch.floor(v * H).nan_to_num(0.0).clamp(0, H - 1).long()
    assert torch.equal((r * W + c).long(), (H - 1 - gl_row) * W + col)


@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16])
def test_flat_texel_is_exact_past_the_floats_integers(dtype):
    """``row·W + col`` in int32: formed in floats where exact, in int64 past 2/eps texels (bfloat16: 256; a 20×20
    image's indices up to 399 are not all bfloat16 integers, its coordinates are)."""
    from ssbench.passes.common import flat_texel
    H, W = 20, 20
    row, col = torch.meshgrid(torch.arange(H), torch.arange(W), indexing="ij")
    got = flat_texel(col.to(dtype), row.to(dtype), (H, W), torch.int32)
    assert got.dtype == torch.int32 and torch.equal(got.long(), row * W + col)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_nan_to_zero_keeps_everything_but_nan_bit_for_bit(dtype):
    """Eager ``nan_to_num`` form against the ``where`` form: NaN → +0, and ±inf, ±0, subnormals and the largest
    finite values keep their bits; with gradients (the ``where`` form) the gradient passes through ±inf too."""
    from ssbench.passes.common import nan_to_zero
    tiny, big = torch.finfo(dtype).tiny, torch.finfo(dtype).max
    x = torch.tensor([float("nan"), -float("nan"), math.inf, -math.inf, 0.0, -0.0, tiny / 4, -tiny / 4, big, -big,
                      1.5], dtype=dtype)
    got, want = nan_to_zero(x), torch.where(x != x, 0.0, x)
    assert torch.equal(got.view(torch.int64 if dtype == torch.float64 else torch.int32),
                       want.view(torch.int64 if dtype == torch.float64 else torch.int32))
    xg = x.clone().requires_grad_(True)
    nan_to_zero(xg).sum().backward()
    assert xg.grad.tolist() == [0.0, 0.0] + [1.0] * 9


@pytest.mark.parametrize("nan_free", [True, False])
def test_texel_of_leaves_its_inputs_and_reads_the_texels_of_floor_and_clamp(nan_free):
    """``texel_of`` works in place on its own temporaries only: ``u`` and ``v`` keep their values (and a gradient
    still reaches them); the texels are ``clamp(floor(u·W))``, ``clamp(floor((1 − v)·H))``."""
    from ssbench.passes.common import texel_of
    g = torch.Generator().manual_seed(4)
    u, v = (torch.rand(500, generator=g, dtype=torch.float64) * 1.4 - 0.2 for _ in range(2))
    if not nan_free:
        u[::7], v[::11] = math.nan, math.inf
    u0, v0 = u.clone(), v.clone()
    col, row = texel_of(u, v, 30, 40, nan_free=nan_free)
    assert torch.equal(u, u0) if nan_free else torch.equal(u.nan_to_num(9.0), u0.nan_to_num(9.0))
    assert torch.equal(v, v0)
    want_col = torch.floor(u0 * 40).nan_to_num(0.0).clamp(0, 39).long()
    want_row = torch.floor((1.0 - v0) * 30).nan_to_num(0.0).clamp(0, 29).long()
    assert torch.equal(col, want_col) and torch.equal(row, want_row)
    ug = u0.nan_to_num(0.5).requires_grad_(True)
    texel_of(ug * 2.0, v0.nan_to_num(0.5), 30, 40, dtype=ug.dtype)[0].sum().backward()
    assert ug.grad is not None and torch.equal(ug.grad, torch.zeros_like(ug))
