"""Seeded sample kernels and the rotation-noise texture shared by the SSAO passes (SSAO article §1, §2.2).

Everything is drawn in float64 on the CPU from a ``torch.Generator`` so the same seed gives the same bits on
every device; callers cast with ``.to(dtype, device)``. The draw order is part of the contract: a pass and its
teaching twin (``ssbench.passes.teaching.ssao_basic``) call **kernel first, then noise** on one generator.

* :func:`hemisphere_kernel` — the article's non-uniform hemisphere kernel (Fig. 4): a random direction in the
  +z hemisphere, a random length in [0, 1), then ``scale = lerp(0.1, 1.0, (i / N)²)`` so samples crowd the
  centre (J. Chapman's construction, which three.js ``SSAOPass`` follows without the random length).
* :func:`sphere_kernel` — Crytek's sphere (Fig. 1): points in the unit ball, drawn as opposite pairs.
* :func:`noise_texture` — the 4×4 rotation noise: unit vectors in the xy plane (z = 0).
* :func:`noise_texel` — which noise texel a pixel reads: ``texture2D(NoiseSampler, vUv * noiseScale)``,
  ``NEAREST`` with ``REPEAT`` wrapping, ``noiseScale = Resolution / size``.
"""
from __future__ import annotations

from typing import Optional

import torch

from .common import check_count, make_generator, uv_to_texel


def _generator(generator: Optional[torch.Generator]) -> torch.Generator:
    """``generator``, or a fresh one seeded with 0 (so a call without one is still deterministic)."""
    return make_generator(0, generator)


def _normalize(v: torch.Tensor) -> torch.Tensor:
    """Unit rows of ``v`` :math:`(N, 3)`; an all-zero row stays zero instead of becoming NaN."""
    return v / v.norm(dim=-1, keepdim=True).clamp_min(torch.finfo(v.dtype).tiny)


def hemisphere_kernel(n: int, generator: Optional[torch.Generator] = None) -> torch.Tensor:
    r"""The article's hemisphere kernel: ``n`` points in the unit +z half-ball, denser near the centre.

    For sample ``i`` (four uniform draws ``u0..u3`` in [0, 1), in this order):

    .. math::
        k_i = \frac{(2u_0 - 1,\ 2u_1 - 1,\ u_2)}{\lVert\cdot\rVert}\ u_3\ \mathrm{lerp}(0.1, 1, (i/n)^2)

    The direction is a normalised point of the box [−1, 1]²×[0, 1] (not uniform in solid angle: it leans
    toward the box's corners), as in Chapman's tutorial and three.js.

    Args:
        n: number of samples (the shader's ``KERNEL_SIZE``; 8, 16, 32 or 64 are usual).
        generator: random source; ``None`` uses a generator seeded with 0.

    Returns:
        :math:`(n, 3)` float64, every row with ``z ≥ 0`` and length < 1.

    Example:
        >>> k = hemisphere_kernel(16, torch.Generator().manual_seed(0))
        >>> k.shape, bool((k[:, 2] >= 0).all()), bool((k.norm(dim=1) < 1).all())
        (torch.Size([16, 3]), True, True)
    """
    check_count(n, "n")
    u = torch.rand(n, 4, generator=_generator(generator), dtype=torch.float64)   # (n, 4): x, y, z, length
    direction = _normalize(torch.stack([u[:, 0] * 2 - 1, u[:, 1] * 2 - 1, u[:, 2]], 1))   # (n, 3)
    t = torch.arange(n, dtype=torch.float64) / n
    scale = 0.1 + (1.0 - 0.1) * t * t                                            # lerp(0.1, 1.0, (i/n)^2)
    return direction * (u[:, 3] * scale)[:, None]


def sphere_kernel(n: int, generator: Optional[torch.Generator] = None) -> torch.Tensor:
    r"""Crytek's sphere kernel: ``n`` points uniform in the unit ball, in opposite pairs ``(p, −p)``.

    Point ``2j`` is ``d_j · u_j^{1/3}`` (``d_j`` a normalised Gaussian triple, ``u_j`` uniform: uniform in
    the ball) and point ``2j + 1`` is its mirror ``−p_{2j}``; an odd ``n`` drops the last mirror. The pairs
    mean every plane through the centre halves the kernel exactly, so an open plane shows Crytek's grey
    level 0.5 without sampling noise (the cube-corner kernel of the Crysis shader pairs opposite corners the
    same way). Draws per pair, in order: three normals, then one uniform.

    Args:
        n: number of samples.
        generator: random source; ``None`` uses a generator seeded with 0.

    Returns:
        :math:`(n, 3)` float64 points with length < 1.

    Example:
        >>> k = sphere_kernel(16, torch.Generator().manual_seed(0))
        >>> k.shape, torch.allclose(k[0::2], -k[1::2])
        (torch.Size([16, 3]), True)
    """
    check_count(n, "n")
    g = _generator(generator)
    m = (n + 1) // 2
    d = torch.randn(m, 3, generator=g, dtype=torch.float64)                     # (m, 3)
    r = torch.rand(m, generator=g, dtype=torch.float64) ** (1.0 / 3.0)          # (m,) radius, uniform volume
    p = _normalize(d) * r[:, None]
    return torch.stack([p, -p], 1).reshape(2 * m, 3)[:n]                        # p0, -p0, p1, -p1, ...


def noise_texture(size: int = 4, generator: Optional[torch.Generator] = None) -> torch.Tensor:
    """The rotation noise texture: random unit vectors in the xy plane, ``z = 0`` (SSAO article §2.2).

    Texel ``(row, col)`` (row 0 at the top, as every ssbench image) draws ``x, y`` uniform in [−1, 1] in
    row-major order and is normalised.

    Args:
        size: texture side (the article's 4).
        generator: random source; ``None`` uses a generator seeded with 0.

    Returns:
        :math:`(3, size, size)` float64.

    Example:
        >>> t = noise_texture(4, torch.Generator().manual_seed(0))
        >>> t.shape, bool((t[2] == 0).all()), torch.allclose(t.norm(dim=0), torch.ones(4, 4, dtype=t.dtype))
        (torch.Size([3, 4, 4]), True, True)
    """
    check_count(size, "size")
    u = torch.rand(size * size, 2, generator=_generator(generator), dtype=torch.float64) * 2 - 1   # (S*S, 2)
    v = _normalize(torch.cat([u, torch.zeros(size * size, 1, dtype=torch.float64)], 1))          # (S*S, 3)
    return v.T.reshape(3, size, size)


def noise_texel(uv: torch.Tensor, width: int, height: int, size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """``(col, row)`` of the noise texel a pixel at ``uv`` reads (``NEAREST``, ``REPEAT``).

    The shader reads ``texture2D(NoiseSampler, vUv * noiseScale)`` with ``noiseScale = Resolution / size``;
    ``REPEAT`` keeps the fractional part, then the texel is picked like any ssbench image (row 0 at the
    top). At pixel centres, with ``H`` a multiple of ``size``, this is ``(i mod size, j mod size)``.

    Args:
        uv: :math:`(*, 2, H, W)` UV (v up), e.g. ``camera.uv_grid()``.
        width, height: the image resolution (``Resolution``).
        size: the noise texture side.

    Returns:
        Two integer tensors of shape :math:`(*, H, W)`.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 8, 0.1, 10.0)
        >>> col, row = noise_texel(cam.uv_grid(torch.float64), 8, 8, 4)
        >>> col[0].tolist(), row[:, 0].tolist()
        ([0, 1, 2, 3, 0, 1, 2, 3], [0, 1, 2, 3, 0, 1, 2, 3])
    """
    scale = torch.tensor([width / size, height / size], dtype=uv.dtype, device=uv.device)
    shape = [1] * uv.dim()
    shape[-3] = 2
    t = uv * scale.reshape(shape)                                               # vUv * noiseScale
    return uv_to_texel(t - torch.floor(t), size, size, dim=uv.dim() - 3)        # REPEAT: fract()


def noise_lookup(noise: torch.Tensor, row: torch.Tensor, col: torch.Tensor) -> torch.Tensor:
    """``noise[:, row, col]``: the texels of a :math:`(C, S, S')` noise texture at the integer ``row``/``col``
    (:func:`noise_texel`; shapes that broadcast to ``S_px``), as :math:`(C, *S_px)`. Read with ``index_select`` of
    flat indices, the same values: eager, advanced indexing took 3-4× the time (4.7 against 1.2 ms for four
    channels at 640×360).

    Example:
        >>> noise = torch.arange(8.0).reshape(2, 2, 2)
        >>> noise_lookup(noise, torch.tensor([[1, 0]]), torch.tensor([[0, 1]])).tolist()
        [[[2.0, 1.0]], [[6.0, 5.0]]]
    """
    channels, _, width = noise.shape
    flat = row * width + col
    return noise.reshape(channels, -1).index_select(1, flat.reshape(-1)).view(channels, *flat.shape)
