"""The layout copies give exactly the values of ``Tensor.contiguous`` and ``torch.stack(…, 1)``, eager and inside
``torch.compile``, for every layout the marchers hand them; bad columns are errors that name the column."""
import pytest
import torch

from ssbench import layout
from ssbench.layout import contiguous, stack, stack_columns


@pytest.fixture(autouse=True, params=["copies", "plain calls"])
def path(request, monkeypatch):
    """Every test runs the copies (no size threshold) and the plain calls they stand in for below it."""
    if request.param == "copies":
        monkeypatch.setattr(layout, "MIN_NUMEL", 0)
    return request.param


def _views() -> dict:
    g = torch.Generator().manual_seed(3)
    img = torch.randn(2, 3, 5, 7, generator=g, dtype=torch.float64)
    rows = torch.randn(11, 3, generator=g)
    return {
        "rows transposed": rows.T,                                       # (3, N) → the component rows
        "components transposed": torch.randn(3, 13, generator=g).T,      # (N, 3) from component rows
        "image to pixel rows": img.permute(0, 2, 3, 1),                  # (B, H, W, C)
        "channels first, batch second": img.transpose(0, 1),
        "int64 pairs": torch.randint(-9, 9, (2, 17), generator=g).T,
        "bool mask": (torch.randn(4, 6, generator=g) > 0).T,
        "column slice": rows[:, 1:3],
        "broadcast": torch.randn(1, 1, 1, 7, generator=g).expand(2, 1, 5, 7),
        "every other": torch.randn(20, generator=g)[::2],
        "empty": torch.zeros(0, 3).T,
    }


@pytest.mark.parametrize("name", list(_views()))
def test_contiguous_copies_every_layout_to_the_values_of_tensor_contiguous(name):
    x = _views()[name]
    y = contiguous(x)
    assert y.is_contiguous() and y.shape == x.shape and y.dtype == x.dtype
    assert torch.equal(y, x.contiguous())
    assert y.data_ptr() != x.data_ptr() or x.numel() == 0              # a copy: writing it leaves x alone


def test_the_threshold_picks_the_plain_call_for_small_tensors_and_the_copy_for_large_ones(path, monkeypatch):
    calls = []
    monkeypatch.setattr(torch, "stack", lambda *a, **k: calls.append(1) or torch.cat([c[:, None] for c in a[0]], 1))
    small, large = [torch.zeros(3)] * 2, [torch.zeros(layout.MIN_NUMEL)] * 2
    stack_columns(small), stack_columns(large)
    assert len(calls) == (0 if path == "copies" else 1)                 # only the small one, below the threshold


def test_contiguous_hands_back_a_contiguous_tensor_itself():
    x = torch.arange(6.0).view(2, 3)
    assert contiguous(x) is x


def test_contiguous_keeps_the_gradient_path():
    x = torch.randn(4, 3, requires_grad=True)
    contiguous(x.T).sum().backward()
    assert torch.equal(x.grad, torch.ones(4, 3))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64, torch.int32, torch.int64])
def test_stack_columns_gives_the_rows_of_torch_stack(dtype):
    g = torch.Generator().manual_seed(5)
    cols = [(torch.randn(9, generator=g) * 100).to(dtype) for _ in range(3)]
    y = stack_columns(cols)
    assert y.is_contiguous() and torch.equal(y, torch.stack(cols, 1)) and y.dtype == dtype
    assert torch.equal(stack_columns(cols[:1]), torch.stack(cols[:1], 1))


def test_both_compile_to_the_plain_calls():
    def f(a, b, c):
        return contiguous(torch.stack([a, b, c]).T), stack_columns([a, b, c * 2])

    a, b, c = torch.randn(3, 8).unbind(0)
    eager = f(a, b, c)
    compiled = torch.compile(f)(a, b, c)
    assert all(torch.equal(x, y) for x, y in zip(eager, compiled))
    assert torch.equal(eager[0], torch.stack([a, b, c], 1)) and torch.equal(eager[1], torch.stack([a, b, c * 2], 1))


def test_stack_columns_keeps_the_gradient_path():
    a = torch.randn(5, requires_grad=True)
    stack_columns([a, a * 3]).sum().backward()
    assert torch.equal(a.grad, torch.full((5,), 4.0))


@pytest.mark.parametrize("cols, match", [
    ([], r"^columns: expected at least one tensor"),
    ([torch.zeros(3), torch.zeros(4)], r"^columns\[1\]: expected a 1-D tensor like columns\[0\]"),
    ([torch.zeros(3), torch.zeros(3, dtype=torch.float64)], r"^columns\[1\]: .*torch.float64"),
    ([torch.zeros(3, 1)], r"^columns\[0\]: expected a 1-D tensor"),
])
def test_stack_columns_names_the_bad_column(cols, match):
    with pytest.raises(ValueError, match=match):
        stack_columns(cols)


@pytest.mark.parametrize("shape, dim", [((7,), -1), ((7,), 1), ((7,), 0), ((2, 5, 4), -3), ((2, 5, 4), -1), ((0,), 1)])
def test_stack_gives_torch_stack_on_every_axis(shape, dim):
    g = torch.Generator().manual_seed(7)
    parts = [torch.randn(shape, generator=g, dtype=torch.float64) for _ in range(3)]
    y = stack(parts, dim)
    assert y.is_contiguous() and torch.equal(y, torch.stack(parts, dim))


def test_stack_leaves_torch_to_refuse_mismatched_parts():
    with pytest.raises(RuntimeError):                                    # torch.stack's own error
        stack([torch.zeros(3), torch.zeros(4)], -1)


def test_a_size_dynamic_kernel_compiles_once_on_both_sides_of_the_threshold():
    from torch._dynamo.utils import counters

    f = torch.compile(lambda a, b: stack_columns([a, b * 2]), dynamic=True)
    small, large = torch.arange(5.0), torch.arange(float(layout.MIN_NUMEL + 3))
    assert torch.equal(f(small, small), torch.stack([small, small * 2], 1))
    graphs = counters["stats"]["unique_graphs"]
    assert torch.equal(f(large, large), torch.stack([large, large * 2], 1))
    assert counters["stats"]["unique_graphs"] == graphs                  # no guard on the size: no new graph
