"""Hemisphere SSAO: the normal-oriented kernel of SSAO article §1–§2.2 (Chapman / three.js ``SSAOShader``).

Per pixel (the article's fragment shader, vectorised over pixels *and* samples as ``(B, K, H, W)``):

1. ``viewPosition`` from the depth buffer with ``getViewPosition`` (inverse projection), or straight from
   ``view_z`` (``position_from="view_z"``); ``viewNormal`` from the normal buffer (ssbench stores floats in
   [−1, 1], so the shader's ``2·rgb − 1`` unpacking is not needed).
2. ``random`` from the 4×4 noise texture (``NEAREST``, ``REPEAT``); Gram–Schmidt gives
   ``tangent = normalize(random − n·(random·n))``, ``bitangent = n × tangent`` and ``kernelMatrix = (t, b, n)``.
3. For each kernel point ``samplePoint = viewPosition + kernelMatrix·Kernel[i]·KernelRadius`` is projected
   (view → NDC → uv with the :class:`~ssbench.camera.Camera`), the depth texel under it is fetched
   (``NEAREST``, ``CLAMP_TO_EDGE``) and both are compared in linear depth
   ``viewZToOrthographicDepth`` ∈ [0, 1]: ``delta = sampleDepth − realDepth``.
4. A sample occludes if ``MinDistance < delta < MaxDistance``; ``occlusion = clamp(count / K, 0, 1)`` and
   ``AO = 1 − occlusion·Strength`` (clamped to [0, 1], as an 8-bit render target would).

**Which AO it estimates.** Counting kernel points that lie behind the depth buffer is a *volumetric*
estimate: as ``K`` grows and the noise turns the kernel, the count converges to the fraction of the kernel's
point law (the half-ball of radius ``KernelRadius``, denser near the centre through ``lerp(0.1, 1, (i/N)²)``)
that lies inside geometry. That is the ``"volume_hemisphere"`` flavour of :mod:`ssbench.reference.ao_volume`,
which this pass is scored against — not a visibility integral over directions: a crease is darker in the
``"uniform"`` or ``"cosine"`` flavour than in this one (a wall blocks a whole cone of directions but holds
only a small slice of the half-ball's volume).

**Edge cases, as the shader behaves.** Samples off screen read the edge texel (``CLAMP_TO_EDGE``), which
can darken or lighten the border. Samples behind the camera (``z > 0``) flip through the perspective divide
and read an arbitrary texel, but their ``sampleDepth < 0`` so ``delta < 0 ≤ MinDistance``: they never count.
A sample exactly on the camera plane (``w = 0``) is nudged to ``z = −tiny`` and non-finite uvs are clamped
(the GPU result is undefined; ours is finite). Background pixels (``mask`` False) get AO 1. ``MinDistance``
is the article's Fig. 10 bias: it hides the false occlusion that nearest-texel depth quantisation gives
samples lying just above a surface; the error it hides grows with distance and grazing angle (half a texel
of depth slope), so far floors still self-occlude a little. ``MaxDistance`` rejects occluders far in front
of the sample (halos), but at grazing angles the depth gap *behind* a surface grows as ``1/sin(elevation)``
and real occlusion is rejected too. Distances are in normalised linear depth, so they scale with
``far − near``; the defaults suit the catalog cameras (near 0.1, far 100: 0.01 ≈ one scene unit).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import torch
from torch import nn

from ...camera import Camera
from ...gbuffer import GBuffer
from ..common import AOResult, component_dot, cross, make_generator
from ..compiled import enabled, kernel
from ..compiled_samples import sample_blocks, sample_groups
from ..gbuffer_checks import check_gbuffer, half_in_float32
from ..inference import autograd_free
from ..sampling import hemisphere_kernel, noise_lookup, noise_texel, noise_texture
from ..registry import Method, SpeedPanel
from .ssao_common import (band_result, banded_ao, check_ssao_params, kernel_components, range_check_count,
                          real_depth_texture, ssao_result, view_position)

FLAVOUR = "volume_hemisphere"  # the ground truth this pass estimates (ssbench.reference.ao_volume)
#: continuous parameters ``ssbench tune`` may fit: name -> (lo, hi, relative); relative ranges are multiples of the
#: ground-truth radius (discrete ones — sample counts, noise — set the cost and stay fixed)
TUNABLE = {"kernel_radius": (0.25, 4.0, True), "min_distance": (0.0, 0.005, False),
           "max_distance": (0.002, 0.1, False), "strength": (0.5, 2.0, False)}
#: where the defaults come from (shown by the report next to the parameters)
DEFAULTS_SOURCE = ('three.js SSAOPass (32-sample kernel, 4×4 noise; https://github.com/mrdoob/three.js); distances '
                   'scaled to the catalog scenes')
REQUIRES = ("view_z", "normal", "mask")
POSITION_FROM = ("depth", "view_z")
NOISE_CHANNELS = ("xyz", "r")


@dataclass(frozen=True)
class HemisphereSSAOParams:
    """Settings of :func:`hemisphere_ssao`, named after the article's uniforms.

    Defaults: what three.js ``SSAOPass`` ships (mrdoob et al., three.js, ``examples/jsm/postprocessing/SSAOPass.js``,
    https://github.com/mrdoob/three.js; the pass the article's demo builds on): a 32-sample kernel and a 4×4 noise
    texture. Its distances are scene-scaled and do not carry over (``kernelRadius`` 8 and min/max distance
    0.005/0.1 of a camera with near 100, far 700); ours suit the catalog scenes (unit-sized objects, near 0.1,
    far 100): ``kernel_radius`` 0.5, and the range check as tight in linear depth as the article's Fig. 9.

    Args:
        kernel_size: ``KERNEL_SIZE``, samples per pixel (8, 16, 32, 64 are usual).
        kernel_radius: ``KernelRadius``, the half-ball radius in view-space units.
        min_distance: ``MinDistance``, smallest counted ``delta`` in linear depth (self-occlusion bias).
        max_distance: ``MaxDistance``, largest counted ``delta`` in linear depth (range check against halos).
        strength: ``Strength``, ``AO = 1 − occlusion · strength``.
        noise_size: side of the rotation noise texture (the article's 4).
        seed: seeds the kernel and the noise when no generator is passed.
        position_from: ``"depth"`` (the article: ``getViewPosition`` from the GL depth buffer, and the
            depth buffer is what ``getLinearDepth`` reads) or ``"view_z"`` (exact positions and depths).
        noise_channels: how ``random`` reads the noise texel: ``"xyz"`` (the article, §2.2: a random 3-vector)
            or ``"r"`` (three.js ``SSAOShader`` as shipped: ``vec3(texture2D(tNoise, …).r)``, one value in all
            three components, so the kernel turns about the fixed diagonal (1, 1, 1) only).
    """

    kernel_size: int = 32
    kernel_radius: float = 0.5
    min_distance: float = 0.0005
    max_distance: float = 0.02
    strength: float = 1.0
    noise_size: int = 4
    seed: int = 0
    position_from: str = "depth"
    noise_channels: str = "xyz"

    def __post_init__(self) -> None:
        check_ssao_params(self)
        if self.position_from not in POSITION_FROM:
            raise ValueError(f"position_from: expected one of {POSITION_FROM}, got {self.position_from!r}")
        if self.noise_channels not in NOISE_CHANNELS:
            raise ValueError(f"noise_channels: expected one of {NOISE_CHANNELS}, got {self.noise_channels!r}")


@kernel
def hemisphere_count(cam: Camera, position: torch.Tensor, tbn: tuple, kernel: torch.Tensor, real_depth: torch.Tensor,
                     p: "HemisphereSSAOParams", count: Optional[torch.Tensor]) -> torch.Tensor:
    """The sample loop of SSAO article §2.2 on a band of rows: ``samplePoint = viewPosition + (kernelMatrix ·
    Kernel[i]) · KernelRadius`` for a group of the samples, then :func:`range_check_count`.

    Args:
        position: :math:`(B, 3, h, W)` ``viewPosition``; ``tbn``: tangent, bitangent, normal :math:`(B, 3, h, W)`;
        kernel: :math:`(k, 3)` the group's ``Kernel[i]`` (:func:`~ssbench.passes.compiled_samples.sample_groups`);
        real_depth: :math:`(B, 1, H, W)` ``getLinearDepth`` of every texel (:func:`~.ssao_common.real_depth_texture`);
        count: :math:`(B, 1, h, W)` the count so far (``None``: none).

    Returns:
        ``count`` plus the group's count of samples that pass the range check. The pass's compilable kernel
        (:mod:`ssbench.passes.compiled`; in :func:`~ssbench.passes.compiled_samples.sample_blocks`).
    """
    t, b, n = tbn
    for ks in sample_blocks(kernel.shape[0]):
        kx, ky, kz = kernel_components(kernel[ks], 2)                             # Kernel[i]: (1, 1, k, 1, 1)

        def component(c: int) -> torch.Tensor:                                       # (B, 1, k, h, W)
            # (t·kx + b·ky) + n·kz, then position + sample_vector·radius: accumulated in place in one buffer (the
            # same operations in the same order; sums commute bit for bit), which eager fills once instead of 4 times
            sample_vector = t[:, c:c + 1].unsqueeze(2) * kx
            sample_vector.add_(b[:, c:c + 1].unsqueeze(2) * ky).add_(n[:, c:c + 1].unsqueeze(2) * kz)
            return sample_vector.mul_(p.kernel_radius).add_(position[:, c:c + 1].unsqueeze(2))
        block = range_check_count(cam, (component(0), component(1), component(2)), real_depth, p.min_distance,
                                  p.max_distance, 2)
        count = block if count is None else count + block
    return count


#: the count → AO step of a band (:func:`~.ssao_common.band_result`), a compilable kernel of its own: the counting
#: kernel runs once per group of samples
count_to_ao = kernel(band_result)


@autograd_free
@half_in_float32
def hemisphere_ssao(gbuffer: GBuffer, params: HemisphereSSAOParams = HemisphereSSAOParams(), *,
                    generator: torch.Generator | None = None, debug: bool = False) -> AOResult:
    r"""Hemisphere SSAO of SSAO article §2.2 (see the module docstring for the algorithm and edge cases).

    .. math::
        \mathrm{AO} = 1 - \mathrm{Strength}\cdot\frac{1}{K}\sum_{i<K}
        [\mathrm{MinDistance} < \ell(s_i) - \ell_{\mathrm{buf}}(\mathrm{uv}(s_i)) < \mathrm{MaxDistance}]

    with :math:`s_i = P + R\,(t, b, n)\,k_i` and :math:`\ell` the linear depth.

    Args:
        gbuffer: needs ``view_z`` :math:`(B, 1, H, W)`, unit ``normal`` :math:`(B, 3, H, W)` and ``mask``
            :math:`(B, 1, H, W)` (bool). Computation runs in ``view_z``'s dtype and device.
        params: :class:`HemisphereSSAOParams`.
        generator: draws the kernel, then the noise; default: a CPU generator seeded with ``params.seed``.
        debug: also return ``debug["samples"]`` (:math:`(B, 1, H, W)` samples that passed the range
            check), ``debug["noise_index"]`` (:math:`(B, 1, H, W)` noise texel ``row · size + col`` used
            for the TBN frame), ``debug["kernel"]`` and ``debug["noise"]``.

    Returns:
        :class:`~ssbench.passes.common.AOResult` with ``ao`` :math:`(B, 1, H, W)` in [0, 1].

    Raises:
        ValueError: naming the argument, for missing channels, wrong shapes or dtypes, non-unit normals.

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 8, 6, 0.1, 100.0)
        >>> z = torch.full((1, 1, 6, 8), -2.0)
        >>> n = torch.zeros(1, 3, 6, 8); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=z, normal=n, mask=torch.ones(1, 1, 6, 8, dtype=torch.bool))
        >>> out = hemisphere_ssao(g)
        >>> out.ao.shape, float(out.ao.min())
        (torch.Size([1, 1, 6, 8]), 1.0)
    """
    fr = hemisphere_frame(gbuffer, params, generator)
    cam, p, n = gbuffer.camera, params, fr.normal

    # ---- §2.2 sample loop on bands of rows, in groups of samples (the working set stays cache-sized) ----
    groups = sample_groups(fr.kernel)                               # eager: one group of every sample

    def run(rs: slice) -> tuple:
        tbn = (fr.tangent[..., rs, :], fr.bitangent[..., rs, :], n[..., rs, :])
        count = None if len(groups) == 1 else torch.zeros(gbuffer.mask[..., rs, :].shape, dtype=torch.int64,
                                                          device=n.device)   # one graph for every group compiled
        for kernel_group in groups:
            count = hemisphere_count(cam, fr.position[..., rs, :], tbn, kernel_group, fr.real_depth, p, count)
        return count_to_ao(count, p, gbuffer.mask[..., rs, :], n.dtype, debug)
    stored = 0 if enabled() else p.kernel_size                      # compiled, no block per sample: one band
    ao, count = banded_ao(run, gbuffer.mask.shape, n.dtype, n.device, stored, debug)
    return ssao_result(ao, count, p, gbuffer.mask, row=fr.row, col=fr.col, kernel=fr.kernel, noise=fr.noise)


@dataclass(frozen=True)
class HemisphereFrame:
    """What the sample loop reads (SSAO article §2.2 up to the loop), from :func:`hemisphere_frame`.

    Attributes:
        position: :math:`(B, 3, H, W)` ``viewPosition``; texture: :math:`(B, 1, H, W)` the buffer
            ``getLinearDepth`` samples; real_depth: :math:`(B, 1, H, W)` what it returns for each texel
            (:func:`~.ssao_common.real_depth_texture`); tangent, bitangent, normal: :math:`(B, 3, H, W)`
            ``kernelMatrix``;
        kernel: :math:`(K, 3)` ``Kernel[i]``; noise: :math:`(3, S, S)`; row, col: :math:`(H, W)` noise texel.
    """

    position: torch.Tensor
    texture: torch.Tensor
    real_depth: torch.Tensor
    tangent: torch.Tensor
    bitangent: torch.Tensor
    normal: torch.Tensor
    kernel: torch.Tensor
    noise: torch.Tensor
    row: torch.Tensor
    col: torch.Tensor


def hemisphere_frame(gbuffer: GBuffer, params: HemisphereSSAOParams,
                     generator: torch.Generator | None = None) -> HemisphereFrame:
    """Checks, draws (the kernel, then the noise, from ``generator`` or ``params.seed``) and the per-pixel frame
    of SSAO article §2.2: ``viewPosition``, the noise ``random``, Gram–Schmidt ``tangent``, ``bitangent``."""
    if not isinstance(params, HemisphereSSAOParams):
        raise TypeError(f"params: expected HemisphereSSAOParams, got {type(params).__name__}")
    check_gbuffer(gbuffer, REQUIRES)
    cam, p = gbuffer.camera, params
    n = gbuffer.normal.to(gbuffer.view_z.dtype)
    dtype, device = n.dtype, n.device
    g = make_generator(p.seed, generator)
    kernel = hemisphere_kernel(p.kernel_size, g).to(dtype=dtype, device=device)    # (K, 3) Kernel[i]
    noise = noise_texture(p.noise_size, g).to(dtype=dtype, device=device)          # (3, S, S)
    position, texture, real_depth, tangent, bitangent, row, col = frame_tensors(cam, gbuffer.view_z, n, noise, p)
    return HemisphereFrame(position, texture, real_depth, tangent, bitangent, n, kernel, noise, row, col)


@kernel
def frame_tensors(cam: Camera, view_z: torch.Tensor, n: torch.Tensor, noise: torch.Tensor,
                  p: HemisphereSSAOParams) -> tuple:
    """The per-pixel part of :func:`hemisphere_frame` (a compilable kernel, :mod:`ssbench.passes.compiled`):
    ``viewPosition``, the buffer ``getLinearDepth`` samples and its ``realDepth`` per texel, the noise texel
    ``random`` (``(row, col)``) and the Gram–Schmidt ``tangent`` and ``bitangent`` of ``kernelMatrix`` from
    ``view_z`` :math:`(B, 1, H, W)`, the unit normal ``n`` :math:`(B, 3, H, W)` and the noise texture
    :math:`(3, S, S)`."""
    uv = cam.uv_grid(n.dtype, n.device)                                            # (2, H, W) vUv
    position, texture = view_position(cam, view_z, p.position_from, uv)           # (B, 3, H, W) viewPosition
    col, row = noise_texel(uv, cam.width, cam.height, p.noise_size)                # (H, W)
    texel = noise_lookup(noise, row, col)                                          # (3, H, W) random
    random = [texel[0]] * 3 if p.noise_channels == "r" else texel.unbind(0)       # three.js: vec3(noise.r)
    normal = n.unbind(1)                                                           # 3 × (B, H, W)
    # Gram–Schmidt on components (the channel sums' bits, in order; compiled, no per-channel loops)
    tangent = [r - nc * component_dot(random, normal) for r, nc in zip(random, normal)]
    norm = component_dot(tangent, tangent).sqrt().clamp_min(torch.finfo(n.dtype).tiny)
    tangent = torch.stack([t / norm for t in tangent], 1)                          # (B, 3, H, W)
    real_depth = real_depth_texture(cam, texture, p.position_from == "depth")
    return position, texture, real_depth, tangent, cross(n, tangent, dim=1), row, col


class HemisphereSSAO(nn.Module):
    """Module form of :func:`hemisphere_ssao`; ``forward(gbuffer)`` returns an :class:`AOResult`.

    Shape:
        - Input: a :class:`~ssbench.gbuffer.GBuffer` with ``view_z``, ``normal``, ``mask``.
        - Output: ``ao`` :math:`(B, 1, H, W)`.

    Example:
        >>> HemisphereSSAO(HemisphereSSAOParams(kernel_size=8)).params.kernel_size
        8
    """

    def __init__(self, params: HemisphereSSAOParams = HemisphereSSAOParams(), debug: bool = False) -> None:
        super().__init__()
        self.params, self.debug = params, debug

    def forward(self, gbuffer: GBuffer, generator: torch.Generator | None = None) -> AOResult:
        return hemisphere_ssao(gbuffer, self.params, generator=generator, debug=self.debug)


def samples_per_pixel(params) -> int:
    """Depth texels the main loop reads per pixel (one depth texel per kernel point): the floor's gather count
    (:func:`ssbench.bench.effects.ao_samples`)."""
    return int(params.kernel_size)


#: this module's declaration: ssbench.passes finds the method here (ssbench.passes.registry)
METHOD = Method("ssao", hemisphere_ssao, HemisphereSSAOParams, HemisphereSSAO, order=20,
                title="normal-oriented hemisphere SSAO (Chapman; three.js SSAOPass)")

#: the report's speed sweeps (``grids:`` purposes of ssbench/report/sweeps/*.yaml) and artifact plots
SPEED_GRIDS = {"cost": [{"kernel_radius": 0.5, "kernel_size": [8, 32], "noise_size": [2, 4]},
                        {"kernel_radius": 0.5, "kernel_size": 16, "noise_size": 4, "max_distance": [0.005, 0.02, 1.0]}],
               "blur": [{"kernel_radius": 0.5, "kernel_size": 16, "noise_size": 4, "max_distance": [0.02, 1.0]}]}
SPEED_PANELS = (SpeedPanel("banding", "kernel_size", (("blur", None), ("max_distance", 0.02))),
                SpeedPanel("banding", "noise_size", (("blur", None), ("max_distance", 0.02))),
                SpeedPanel("halos", "max_distance", (("kernel_size", 16), ("noise_size", 4))),
                SpeedPanel("halos", "blur", (("kernel_size", 16), ("noise_size", 4))))
