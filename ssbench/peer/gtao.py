"""three.js ``GTAOShader`` (``examples/jsm/shaders/GTAOShader.js``) run on an ssbench G-buffer, against
:func:`ssbench.passes.ao.three_gtao.three_gtao` on the same inputs.

Inputs (float32): ``tDepth`` the GL depth buffer (1.0 on background texels, which the shader discards),
``tNormal`` the view normals packed ``n · 0.5 + 0.5`` (``NORMAL_VECTOR_TYPE`` 1), ``tNoise`` ``GTAOPass``'s magic-square
tile (:func:`~ssbench.passes.ao.three_gtao.noise_tile`, ``REPEAT``), the projection matrix and its inverse,
``radius``, ``distanceExponent``, ``thickness``, ``distanceFallOff``, ``scale``, ``SAMPLES``. No patch.

:mod:`ssbench.passes.ao.gtao` (Jimenez et al.'s screen-space slices, XeGTAO) is a different method by design; see
``ssbench/PARITY.md`` for what differs and by how much.
"""
from __future__ import annotations

import torch

from ..gbuffer import GBuffer
from ..passes.ao.three_gtao import ThreeGTAOParams, noise_tile, three_gtao
from .runtime import ShaderPass, Uniform, camera_uniforms, gbuffer_textures, run_pass

__all__ = ["three_gtao_shader", "MODULE", "PROOF"]

MODULE = "three/addons/shaders/GTAOShader.js"
PROOF = "three_gtao = three.js GTAOShader (3 and 5 directions, distance fall-off on and off)"


def three_gtao_shader(gbuffer: GBuffer, params: ThreeGTAOParams = ThreeGTAOParams(), *,
                      flip_rows: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
    """``(shader_ao, pass_ao)``, both :math:`(1, 1, H, W)` (the shader's background is 0: it discards there)."""
    g = gbuffer.to(dtype=torch.float32)
    cam = g.camera
    textures = gbuffer_textures(g)                                             # depth 1.0: discarded
    ours = three_gtao(g, params).ao
    tile = noise_tile(params.noise_size).to(torch.float32).flip(1)              # as an ssbench image (top first)
    shader = ShaderPass(
        MODULE, "GTAOShader", cam.width, cam.height,
        textures={**textures, "tNoise": tile.permute(1, 2, 0).numpy()}, repeat=("tNoise",),
        uniforms={**camera_uniforms(cam, "cameraProjectionMatrixInverse"),
                  "radius": Uniform("float", float(params.radius)),
                  "distanceExponent": Uniform("float", float(params.distance_exponent)),
                  "thickness": Uniform("float", float(params.thickness)),
                  "distanceFallOff": Uniform("float", float(params.distance_fall_off)),
                  "scale": Uniform("float", float(params.scale))},
        defines={"SAMPLES": int(params.samples)})
    out = run_pass(shader, flip_rows=flip_rows)
    return torch.from_numpy(out[..., 0].copy())[None, None], ours
