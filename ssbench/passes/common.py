"""Shared pieces of the screen-space passes: the result type, texture fetches and seeded generators.

Texture fetches follow GL semantics on ssbench images (row 0 at the top, see ``CONVENTIONS.md``): a shader
``texture2D(tex, uv)`` with ``NEAREST`` filtering and ``CLAMP_TO_EDGE`` reads texel
``(clamp(floor(u·W)), clamp(floor((1 − v)·H)))``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Optional

import torch

from .. import checks
from ..rays import component_dot, component_norm, cross, length, vector_norm  # noqa: F401  (re-exported)


@dataclass(frozen=True)
class AOResult:
    """Output of an ambient-occlusion pass.

    Attributes:
        ao: :math:`(B, 1, H, W)` ambient visibility in [0, 1] (1 = unoccluded; background pixels are 1).
        bent_normal: optional :math:`(B, 3, H, W)` unit view-space bent normals (GTAO).
        debug: named extra buffers, e.g. ``"samples"`` (per-pixel sample count) or ``"horizons"``.
    """

    ao: torch.Tensor
    bent_normal: Optional[torch.Tensor] = None
    debug: dict = field(default_factory=dict)


def make_generator(seed: int, generator: Optional[torch.Generator], device=None) -> torch.Generator:
    """``generator`` if given, else a CPU generator seeded with ``seed`` (same seed → same bits)."""
    if generator is not None:
        return generator
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed!r}")
    g = torch.Generator(device="cpu")
    g.manual_seed(seed)
    return g


def uv_to_texel(uv: torch.Tensor, height: int, width: int, dim: int = 1) -> tuple[torch.Tensor, torch.Tensor]:
    """Integer ``(col, row)`` of the ``NEAREST``/``CLAMP_TO_EDGE`` texel a shader reads at ``uv`` (v up)."""
    u, v = uv.unbind(dim)
    return texel_of(u, v, height, width)


def nan_to_zero(x: torch.Tensor) -> torch.Tensor:
    """``x`` with NaN replaced by 0 and everything else kept (infinities too): ``where(x != x, 0, x)``.

    Eager (and without gradients) it is one ``torch.nan_to_num(x, 0.0, inf, -inf)`` pass instead of two (crytek and
    hemisphere SSAO at 640×360: 13-20 % faster, measured side by side). Inside ``torch.compile`` it stays
    ``where``: inductor runs ``nan_to_num``'s NaN test one lane at a time, and four of those per sample made the
    compiled SSAO loop 2× slower. With gradients too (``nan_to_num``'s gradient is 0 at ±inf, ``where``'s is not).

    Example:
        >>> nan_to_zero(torch.tensor([float("nan"), -float("inf"), 2.0]))
        tensor([0., -inf, 2.])
    """
    if torch.compiler.is_compiling() or x.requires_grad:
        return torch.where(x != x, 0.0, x)
    return torch.nan_to_num(x, nan=0.0, posinf=math.inf, neginf=-math.inf)     # eager: one pass, not two


def texel_of(u: torch.Tensor, v: torch.Tensor, height: int, width: int, *,
             nan_free: bool = False, dtype: torch.dtype = torch.int64) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`uv_to_texel` of ``u`` and ``v`` given apart (nothing stacked: a compiled kernel fuses it).

    A NaN coordinate (a degenerate projection) reads index 0 of its axis, never ``INT64_MIN``; ``nan_free=True``
    says the caller already replaced NaNs and skips that test (one less select per sample in a compiled loop).
    ``dtype``: of the indices (:func:`index_dtype` of the flat indices the caller builds from them).
    """
    col, row = (u * width).floor_(), torch.rsub(v, 1.0).mul_(height).floor_()   # in place on their own temporaries
    if not nan_free:
        col, row = nan_to_zero(col), nan_to_zero(row)
    return col.clamp_(0, width - 1).to(dtype), row.clamp_(0, height - 1).to(dtype)


def index_dtype(texels: int) -> torch.dtype:
    """The dtype of flat texel indices into ``texels`` texels: int32 where they fit (half a compiled loop's integer
    work on AVX2, which has no 64-bit vector multiply), else int64."""
    return torch.int32 if texels < 2 ** 31 else torch.int64


def gl_texel(u: torch.Tensor, v: torch.Tensor, height: int, width: int) -> tuple[torch.Tensor, torch.Tensor]:
    """``(col, row)`` (row 0 at the top) of the ``NEAREST``/``CLAMP_TO_EDGE`` texel at ``uv`` (v up), as
    integer-valued floats, rounded as GL rounds it: row ``⌊v·H⌋`` counted from the bottom. (:func:`texel_of`'s
    ``⌊(1 − v)·H⌋`` from the top picks the same texel except exactly on a texel edge; the three.js
    transliterations need GL's side.) NaN reads texel 0 of its axis."""
    col = nan_to_zero(torch.floor(u * width)).clamp(0, width - 1)
    gl_row = nan_to_zero(torch.floor(v * height)).clamp(0, height - 1)
    return col, (height - 1) - gl_row


def flat_texel(col: torch.Tensor, row: torch.Tensor, size: tuple[int, int], dtype: torch.dtype) -> torch.Tensor:
    """``row·W + col`` of integer-valued floating ``col``/``row`` inside an image of ``size`` ``(H, W)``, as ``dtype``
    (an :func:`index_dtype`). On the CPU a float → int64 conversion and int64 arithmetic have no AVX2 vector form
    (4× and 4× slower than in int32, measured), so where the index is exact in the floats' dtype (at most 2/eps
    texels: :math:`2^{24}` for float32) it is formed in floating point and converted once; elsewhere in int64.

    Example:
        >>> flat_texel(torch.tensor([3.0, 0.0]), torch.tensor([0.0, 2.0]), (3, 4), torch.int32)
        tensor([3, 8], dtype=torch.int32)
    """
    H, W = size
    if H * W <= 2 / torch.finfo(col.dtype).eps:
        return torch.add(col, row, alpha=W).to(dtype)                          # col + W·row: one pass, exact
    return (row.long() * W + col.long()).to(dtype)


def fetch(tex: torch.Tensor, col: torch.Tensor, row: torch.Tensor) -> torch.Tensor:
    """Gather texels of ``tex`` :math:`(B, C, H, W)` at integer ``col``/``row`` of shape :math:`(B, *S)`.

    Returns :math:`(B, C, *S)`.
    """
    return _gather_flat(tex, row * tex.shape[-1] + col)


def _gather_flat(tex: torch.Tensor, flat: torch.Tensor) -> torch.Tensor:
    """The texels of ``tex`` :math:`(B, C, H, W)` at int64 flat indices ``row·W + col`` :math:`(B, *S)`:
    :math:`(B, C, *S)`."""
    B, C, H, W = tex.shape
    index = flat.reshape(B, 1, -1).expand(B, C, -1)                               # (B, C, N)
    return tex.reshape(B, C, H * W).gather(2, index).reshape(B, C, *flat.shape[1:])


def channel_rows(t: torch.Tensor) -> torch.Tensor:
    """:math:`(B, C, H, W)` → :math:`(C, B·H·W)`, pixels in row-major order: a view for ``B = 1`` (a copy
    otherwise). ``channel_rows(x).index_select(1, rows)`` gathers the pixels ``rows`` as :math:`(C, N)` rows,
    3-4× faster than transposing to :math:`(B·H·W, C)` and gathering pixel rows (measured at 640×360).

    Example:
        >>> x = torch.arange(8.0).reshape(2, 1, 2, 2).expand(2, 2, 2, 2)
        >>> channel_rows(x)
        tensor([[0., 1., 2., 3., 4., 5., 6., 7.],
                [0., 1., 2., 3., 4., 5., 6., 7.]])
    """
    B, C = t.shape[:2]
    return t.reshape(B, C, -1).transpose(0, 1).reshape(C, -1)


def fetch_texels(tex: torch.Tensor, col: torch.Tensor, row: torch.Tensor) -> torch.Tensor:
    """:func:`fetch` of integer-valued floating ``col``/``row`` of shape :math:`(B, *S)`, already within the image:
    the same texels, :math:`(B, C, *S)`.

    ``gather`` needs int64 indices, which are slow on the CPU: this reads with ``index_select`` (of
    :func:`channel_rows` for several channels) at :func:`flat_texel` indices in :func:`index_dtype`, plus each
    image's offset ``b·H·W``. Inside ``torch.compile``, where the index arithmetic fuses anyway, it gathers at the
    :func:`flat_texel` indices in int64: formed in floating point and converted once, not ``col`` and ``row``
    converted apart and multiplied in int64 as :func:`fetch` does (the same texels; compiled at 640×360, 0.91× the
    time of Crytek, 0.96× of hemisphere SSAO, 0.97–0.99× of the GTAOs and the visibility bitmask).

    Example:
        >>> tex = torch.arange(12.0).reshape(1, 1, 3, 4)
        >>> fetch_texels(tex, torch.tensor([[0.0, 3.0]]), torch.tensor([[2.0, 0.0]]))
        tensor([[[8., 3.]]])
    """
    B, C, H, W = tex.shape
    if torch.compiler.is_compiling():
        return _gather_flat(tex, flat_texel(col, row, (H, W), torch.int64))
    index = flat_texel(col, row, (H, W), index_dtype(B * H * W))
    if B > 1:
        index = index + (torch.arange(B, dtype=index.dtype, device=index.device) * (H * W)).view(
            B, *(1,) * (col.dim() - 1))
    index = index.reshape(-1)
    if C == 1:
        return tex.reshape(-1).index_select(0, index).view(B, 1, *col.shape[1:])
    rows = channel_rows(tex).index_select(1, index).view(C, B, *col.shape[1:])   # (C, B, *S)
    return rows.transpose(0, 1).contiguous() if B > 1 else rows.view(1, C, *col.shape[1:])


def fetch_uv(tex: torch.Tensor, uv: torch.Tensor, dim: int = 1) -> torch.Tensor:
    """``texture2D(tex, uv)`` with nearest filtering; ``uv`` :math:`(B, 2, *S)` → :math:`(B, C, *S)`."""
    u, v = uv.unbind(dim)
    col, row = texel_of(u, v, tex.shape[-2], tex.shape[-1], dtype=u.dtype)
    return fetch_texels(tex, col, row)


def check_radius(value, name: str = "radius") -> None:
    """A length > 0: a Python number, or a one-element floating tensor (the passes are differentiable in their
    radii, so ``torch.tensor(0.5, requires_grad=True)`` is accepted; its value is not read on ``meta``)."""
    if not checks.checks_enabled():
        return
    if isinstance(value, torch.Tensor):
        if value.numel() != 1 or not value.is_floating_point():
            raise ValueError(f"{name}: a tensor must be a floating scalar, got shape {tuple(value.shape)} "
                             f"{value.dtype}")
        if value.device.type == "meta" or bool(value.detach() > 0):
            return
        raise ValueError(f"{name}: must be > 0, got {float(value)}")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
        raise ValueError(f"{name}: must be a number > 0, got {value!r}")


def check_count(value: int, name: str) -> None:
    if not checks.checks_enabled():
        return
    if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
        raise ValueError(f"{name}: must be a positive integer, got {value!r}")


def check_positive(value: float, name: str, allow_zero: bool = False) -> None:
    """A finite Python number > 0 (``>= 0`` with ``allow_zero``); the error names ``name``."""
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and value == value and value != float("inf")
    if not ok or value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name}: must be a finite number {bound}, got {value!r}")


#: bytes of the per-sample blocks a pass may hold at once (about a core's L2): the AO passes work on a band of
#: image rows at a time, so their working set is bounded and their time per pixel does not jump once an
#: image's blocks would leave the cache
BLOCK_BYTES = 1 << 20


def row_bands(height: int, width: int, samples: int, itemsize: int, budget: Optional[int] = None, *,
              batch: int = 1, multiple: int = 1) -> list[slice]:
    """Slices of image rows whose ``(batch, 3, samples, rows, width)`` sample blocks fit in ``budget`` bytes
    (default :data:`BLOCK_BYTES`, read at each call), in whole ``multiple`` of rows (at least one ``multiple``: a pass
    whose noise repeats every ``multiple`` rows reuses one period's work in every band, :mod:`.noise_tiles`). Every
    pixel's arithmetic is the same in any band, so a banded pass is bit-identical to the whole-image one.

    Example:
        >>> row_bands(10, 100, 16, 4, budget=4 * 3 * 16 * 100 * 4)
        [slice(0, 4, None), slice(4, 8, None), slice(8, 10, None)]
        >>> row_bands(10, 100, 16, 4, budget=5 * 3 * 16 * 100 * 4, multiple=4)
        [slice(0, 4, None), slice(4, 8, None), slice(8, 10, None)]
    """
    budget = BLOCK_BYTES if budget is None else budget
    rows = max(1, budget // max(1, 3 * batch * samples * width * itemsize))
    rows = max(multiple, rows - rows % multiple)
    return [slice(r0, min(height, r0 + rows)) for r0 in range(0, height, rows)]
