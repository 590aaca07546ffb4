"""ssbench.indices.flat_nonzero against torch's own nonzero."""
import pytest
import torch

from ssbench.indices import flat_nonzero


def reference(mask: torch.Tensor) -> torch.Tensor:
    return mask.nonzero().squeeze(1)


@pytest.mark.parametrize("dtype", [torch.bool, torch.uint8, torch.int8, torch.int32, torch.int64, torch.float16,
                                   torch.float32, torch.float64, torch.bfloat16])
@pytest.mark.parametrize("density", [0.0, 0.1, 0.75, 1.0])
def test_the_positions_are_torch_nonzeros_for_every_dtype_and_density(dtype, density):
    g = torch.Generator().manual_seed(3)
    values = (torch.rand(5000, generator=g) < density).to(dtype)
    got, want = flat_nonzero(values), reference(values)
    assert got.dtype == torch.int64 and torch.equal(got, want)


def test_nan_counts_and_negative_zero_does_not():
    x = torch.tensor([float("nan"), -0.0, 0.0, 2.0, float("-inf")])
    assert torch.equal(flat_nonzero(x), reference(x))
    assert flat_nonzero(x).tolist() == [0, 3, 4]


def test_a_strided_view_and_an_empty_mask():
    base = torch.rand(40, 9, generator=torch.Generator().manual_seed(0)) > 0.5
    column = base[:, 4]                                                     # stride 9
    assert not column.is_contiguous()
    assert torch.equal(flat_nonzero(column), reference(column))
    empty = torch.zeros(0, dtype=torch.bool)
    assert flat_nonzero(empty).shape == (0,) and flat_nonzero(empty).dtype == torch.int64


def test_the_result_owns_its_memory():
    mask = torch.tensor([True, False, True])
    idx = flat_nonzero(mask)
    mask[0] = False
    assert idx.tolist() == [0, 2]
    idx += 1                                                                # writable, like torch's
    assert idx.tolist() == [1, 3]


def test_a_mask_that_is_not_1d_is_refused_by_name():
    with pytest.raises(ValueError, match="mask: expected a 1-D tensor"):
        flat_nonzero(torch.ones(2, 2, dtype=torch.bool))


def test_it_runs_inside_torch_compile():
    compiled = torch.compile(lambda m: flat_nonzero(m) * 2, backend="eager", fullgraph=False)
    mask = torch.tensor([False, True, True, False, True])
    assert compiled(mask).tolist() == [2, 4, 8]
