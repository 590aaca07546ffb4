"""Teaching twins of the SSAO passes: the article's fragment shader run one pixel at a time in plain Python.

*This module is not meant to be used in practice* (it is a few thousand times slower than
:func:`ssbench.passes.ao.ssao.hemisphere_ssao`); it exists to show the algorithm of SSAO article §2.2 line by line,
with the shader's own variable names, so the vectorised pass can be read against it. The tests check that both
give the same AO. Like the shader it works on scalars and 3-vectors; GLSL helpers (``dot``, ``cross``,
``normalize``, ``texture2D``) are written out below.

Both twins draw the kernel and then the noise from one generator, exactly like the passes, so they see the
same samples. Vectors are Python tuples; matrices are row-major lists (``M[row][col]``), so GLSL's
column-major ``CameraProjectionMatrix[2][3]`` (column 2, row 3) is ``P[3][2]`` here.
"""
from __future__ import annotations

import math
import sys
from typing import Optional

import torch

from ...gbuffer import GBuffer
from ..common import AOResult, make_generator
from ..sampling import hemisphere_kernel, noise_texture, sphere_kernel
from ..gbuffer_checks import check_gbuffer
from ..ao.ssao import REQUIRES, HemisphereSSAOParams
from ..ao.crytek import REQUIRES as CRYTEK_REQUIRES, CrytekSSAOParams

TINY = sys.float_info.min                      # the smallest normal float64, torch.finfo(float64).tiny


# ---------------------------------------------------------------- GLSL built-ins, on tuples
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    length = max(math.sqrt(dot(a, a)), TINY)   # GLSL gives NaN for a zero vector; we keep it zero
    return (a[0] / length, a[1] / length, a[2] / length)


def mat_mul(m, v):
    return tuple(sum(m[r][c] * v[c] for c in range(len(v))) for r in range(len(m)))


def texture2D(tex, uv, repeat=False):
    """``texture2D`` with ``NEAREST`` filtering on a ``[row][col]`` image whose row 0 is the top."""
    H, W = len(tex), len(tex[0])
    u, v = (min(max(0.0 if c != c else c, -sys.float_info.max), sys.float_info.max) for c in uv)  # NaN, inf
    if repeat:                                  # REPEAT wrapping: keep the fractional part
        u, v = u - math.floor(u), v - math.floor(v)
    col = math.floor(min(max(u * W, 0.0), W - 1.0))        # CLAMP_TO_EDGE
    row = math.floor(min(max((1.0 - v) * H, 0.0), H - 1.0))  # NOTE: v points up, rows point down
    return tex[row][col]


class _Shader:
    """The uniforms and helper functions of SSAO article §2.2, bound to one G-buffer image."""

    def __init__(self, gbuffer: GBuffer, b: int, position_from: str):
        cam = gbuffer.camera
        self.W, self.H = cam.width, cam.height                                     # Resolution
        self.cameraNear, self.cameraFar = cam.near, cam.far
        self.CameraProjectionMatrix = cam.projection_matrix().tolist()
        self.CameraInverseProjectionMatrix = cam.inverse_projection_matrix().tolist()
        view_z = gbuffer.view_z[b, 0].double()
        self.from_depth = position_from == "depth"
        buf = cam.view_z_to_depth(view_z) if self.from_depth else view_z           # tDepth (GL) or view z
        self.tDepth = buf.tolist()
        self.mask = gbuffer.mask[b, 0].tolist()
        self.normal = gbuffer.normal[b].double().permute(1, 2, 0).tolist() if gbuffer.normal is not None else None

    def perspectiveDepthToViewZ(self, depth):
        n, f = self.cameraNear, self.cameraFar
        return (n * f) / ((f - n) * depth - f)

    def viewZToOrthographicDepth(self, viewZ):
        n, f = self.cameraNear, self.cameraFar
        return (viewZ + n) / (n - f)

    def getDepth(self, screenPosition):
        return texture2D(self.tDepth, screenPosition)

    def getViewZ(self, depth):
        return self.perspectiveDepthToViewZ(depth) if self.from_depth else depth

    def getLinearDepth(self, screenPosition):
        return self.viewZToOrthographicDepth(self.getViewZ(self.getDepth(screenPosition)))

    def getViewPosition(self, screenPosition, depth, viewZ):
        if not self.from_depth:                                                    # exact: the pixel ray at z
            f1 = 1.0 / self.CameraInverseProjectionMatrix[0][0]
            f2 = 1.0 / self.CameraInverseProjectionMatrix[1][1]
            return ((-2.0 / f1 * screenPosition[0] + 1.0 / f1) * viewZ,
                    (-2.0 / f2 * screenPosition[1] + 1.0 / f2) * viewZ, viewZ)
        P = self.CameraProjectionMatrix
        clipW = P[3][2] * viewZ + P[3][3]                  # GLSL CameraProjectionMatrix[2][3]*viewZ + [3][3]
        clipPosition = [(screenPosition[0] - 0.5) * 2.0, (screenPosition[1] - 0.5) * 2.0,
                        (depth - 0.5) * 2.0, 1.0]
        clipPosition = [c * clipW for c in clipPosition]   # unprojection
        return mat_mul(self.CameraInverseProjectionMatrix, clipPosition)[:3]

    def getViewNormal(self, screenPosition):
        return texture2D(self.normal, screenPosition)      # stored in [-1, 1]: no 2*rgb - 1 unpacking

    def occludes(self, samplePoint, MinDistance, MaxDistance):
        """The body of the sample loop after ``samplePoint``: project, fetch, compare (§2.2)."""
        w_z = samplePoint[2] if samplePoint[2] != 0 else -TINY   # NOTE: w = 0 nudged, as in the pass
        samplePointNDC = mat_mul(self.CameraProjectionMatrix, (samplePoint[0], samplePoint[1], w_z, 1.0))
        samplePointNDC = [c / samplePointNDC[3] for c in samplePointNDC]
        samplePointUv = (samplePointNDC[0] * 0.5 + 0.5, samplePointNDC[1] * 0.5 + 0.5)
        realDepth = self.getLinearDepth(samplePointUv)
        sampleDepth = self.viewZToOrthographicDepth(samplePoint[2])
        delta = sampleDepth - realDepth
        return delta > MinDistance and delta < MaxDistance


def _run(gbuffer, params, generator, requires, make_kernel, fragment):
    check_gbuffer(gbuffer, requires)
    g = make_generator(params.seed, generator)
    Kernel = make_kernel(params.kernel_size, g).tolist()                  # drawn first ...
    NoiseSampler = noise_texture(params.noise_size, g).permute(1, 2, 0).tolist()   # ... then the noise
    B, H, W = gbuffer.batch_size, gbuffer.height, gbuffer.width
    ao = torch.ones(B, 1, H, W, dtype=torch.float64)
    count = torch.zeros(B, 1, H, W, dtype=torch.int64)
    position_from = getattr(params, "position_from", "view_z")
    for b in range(B):
        shader = _Shader(gbuffer, b, position_from)
        for j in range(H):
            for i in range(W):
                if not shader.mask[j][i]:
                    continue                                              # background: AO stays 1
                vUv = ((i + 0.5) / W, 1.0 - (j + 0.5) / H)                # pixel centre, v up
                occlusion = fragment(shader, vUv, Kernel, NoiseSampler, params)
                count[b, 0, j, i] = int(occlusion)
                occlusion = min(max(occlusion / float(params.kernel_size), 0.0), 1.0)
                ao[b, 0, j, i] = min(max(1.0 - occlusion * params.strength, 0.0), 1.0)  # 8-bit target clamps
    return AOResult(ao=ao, debug={"samples": count})


def _hemisphere_fragment(s: _Shader, vUv, Kernel, NoiseSampler, p: HemisphereSSAOParams) -> float:
    # ---- §2.2: this pixel's view-space position and normal
    depth = s.getDepth(vUv)
    viewZ = s.getViewZ(depth)
    viewPosition = s.getViewPosition(vUv, depth, viewZ)
    viewNormal = s.getViewNormal(vUv)
    # ---- §2.2: random rotation from the noise texture, Gram–Schmidt, kernelMatrix = mat3(t, b, n)
    noiseScale = (s.W / p.noise_size, s.H / p.noise_size)
    random = texture2D(NoiseSampler, (vUv[0] * noiseScale[0], vUv[1] * noiseScale[1]), repeat=True)
    d = dot(random, viewNormal)
    tangent = normalize((random[0] - viewNormal[0] * d, random[1] - viewNormal[1] * d,
                         random[2] - viewNormal[2] * d))
    bitangent = cross(viewNormal, tangent)
    # ---- §2.2: the sample loop
    occlusion = 0.0
    for i in range(p.kernel_size):
        k = Kernel[i]                                                     # kernelMatrix * Kernel[i]
        sampleVector = tuple(tangent[c] * k[0] + bitangent[c] * k[1] + viewNormal[c] * k[2] for c in range(3))
        samplePoint = tuple(viewPosition[c] + sampleVector[c] * p.kernel_radius for c in range(3))
        if s.occludes(samplePoint, p.min_distance, p.max_distance):
            occlusion += 1.0
    return occlusion


def _crytek_fragment(s: _Shader, vUv, Kernel, NoiseSampler, p: CrytekSSAOParams) -> float:
    viewZ = s.getViewZ(s.getDepth(vUv))
    viewPosition = s.getViewPosition(vUv, None, viewZ)                    # no normal: Crytek needs none
    noiseScale = (s.W / p.noise_size, s.H / p.noise_size)
    random = texture2D(NoiseSampler, (vUv[0] * noiseScale[0], vUv[1] * noiseScale[1]), repeat=True)
    occlusion = 0.0
    for i in range(p.kernel_size):
        k = Kernel[i]
        d = dot(k, random)
        sampleVector = tuple(k[c] - 2.0 * d * random[c] for c in range(3))   # reflect(Kernel[i], random)
        samplePoint = tuple(viewPosition[c] + sampleVector[c] * p.kernel_radius for c in range(3))
        if s.occludes(samplePoint, p.min_distance, p.max_distance):
            occlusion += 1.0
    return occlusion


def hemisphere_ssao_basic(gbuffer: GBuffer, params: HemisphereSSAOParams = HemisphereSSAOParams(),
                          generator: Optional[torch.Generator] = None) -> AOResult:
    """Per-pixel twin of :func:`ssbench.passes.ao.ssao.hemisphere_ssao` (same AO, float64, very slow).

    Example:
        >>> from ssbench.camera import Camera
        >>> cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, 4, 3, 0.1, 100.0)
        >>> n = torch.zeros(1, 3, 3, 4); n[:, 2] = 1
        >>> g = GBuffer(cam, view_z=torch.full((1, 1, 3, 4), -2.0), normal=n,
        ...             mask=torch.ones(1, 1, 3, 4, dtype=torch.bool))
        >>> hemisphere_ssao_basic(g).ao.shape
        torch.Size([1, 1, 3, 4])
    """
    return _run(gbuffer, params, generator, REQUIRES, hemisphere_kernel, _hemisphere_fragment)


def crytek_ssao_basic(gbuffer: GBuffer, params: CrytekSSAOParams = CrytekSSAOParams(),
                      generator: Optional[torch.Generator] = None) -> AOResult:
    """Per-pixel twin of :func:`ssbench.passes.ao.crytek.crytek_ssao` (positions from ``view_z``)."""
    return _run(gbuffer, params, generator, CRYTEK_REQUIRES, sphere_kernel, _crytek_fragment)
