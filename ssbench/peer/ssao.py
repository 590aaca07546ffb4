"""three.js ``SSAOShader`` (``examples/jsm/shaders/SSAOShader.js``) run on an ssbench G-buffer, against
:func:`ssbench.passes.ao.ssao.hemisphere_ssao` on the same inputs.

Inputs, exactly as the pass reads them (float32): ``tDepth`` the GL depth buffer ``view_z_to_depth(view_z)``
(exactly 1.0 on background texels, the shader's ``depthThreshold``), ``tNormal`` the view normals packed as
``n · 0.5 + 0.5`` (the shader's ``unpackRGBToNormal``), ``tNoise`` the pass's own noise texture (``REPEAT``),
``kernel`` its own kernel, the camera's projection matrix and closed-form inverse, ``kernelRadius``,
``minDistance``, ``maxDistance``, ``cameraNear``/``cameraFar`` and ``resolution``.

Differences by design (:data:`DIFFERENCES`): the shader hard-codes a 4×4 noise tile (``resolution / 4.0``), so
``noise_size`` must be 4; it reads the noise's red channel only (``noise_channels="r"`` in the pass; the
article's ``.xyz`` is the shader with :data:`ARTICLE_NOISE` applied); it has no ``Strength`` (the pass's
``strength`` must be 1); it rebuilds the view position from depth (the pass's ``position_from="depth"``).
What is left is float rounding: the shader multiplies by the projection matrix where the pass uses its closed
form, and unpacks the normal, so a sample can land on the other side of a texel edge or of a range-check bound —
a count off by one, ``1/K`` of AO, in a few pixels.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import torch

from ..gbuffer import GBuffer
from ..passes.ao.ssao import HemisphereSSAOParams, hemisphere_ssao
from .runtime import ShaderPass, Uniform, camera_uniforms, gbuffer_textures, run_pass

__all__ = ["three_ssao", "ARTICLE_NOISE", "DIFFERENCES", "MODULE", "PROOF"]

MODULE = "three/addons/shaders/SSAOShader.js"
#: the article's noise read (SSAO article §2.2: ``texture(NoiseSampler, …).xyz``) patched into the shader
ARTICLE_NOISE = ("vec3( texture2D( tNoise, vUv * noiseScale ).r )", "texture2D( tNoise, vUv * noiseScale ).xyz")
DIFFERENCES = ("three.js reads the noise's red channel only, vec3(texture2D(tNoise, …).r); the article reads .xyz "
               "(noise_channels='r' vs 'xyz'; the article's form is the shader with ARTICLE_NOISE patched in)",
               "the noise tile is fixed at 4×4 in the shader (noiseScale = resolution / 4.0): noise_size=4",
               "no Strength uniform: strength=1",
               "view position from the depth buffer only: position_from='depth'")


#: what ``tests/peer/test_ssao_parity.py`` proves (equal on every valid pixel, 4 scenes, K = 16 and 32)
PROOF = ("ssao (hemisphere) = three.js SSAOShader, as shipped (noise_channels='r') and with the article's .xyz "
         "noise patched in (noise_channels='xyz')")



def three_ssao(gbuffer: GBuffer, params: HemisphereSSAOParams = HemisphereSSAOParams(), *, flip_rows: bool = True,
               article_noise: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """``(shader_ao, pass_ao)``, both :math:`(1, 1, H, W)`: three.js ``SSAOShader`` and the torch pass on the same
    G-buffer, kernel and noise. ``article_noise`` patches the shader to read ``.xyz`` (the pass then runs with
    ``noise_channels="xyz"``); otherwise the shader is as shipped and the pass runs with ``"r"``.
    ``flip_rows=False`` uploads the images top row first, as ssbench stores them: the control that must differ.

    Raises:
        ValueError: naming the parameter, for settings the shader cannot express (see :data:`DIFFERENCES`).
    """
    p = dataclasses.replace(params, noise_channels="xyz" if article_noise else "r")
    for name, want in (("noise_size", 4), ("strength", 1.0), ("position_from", "depth")):
        if getattr(p, name) != want:
            raise ValueError(f"{name}: SSAOShader has no such setting; use {want!r}")
    g = gbuffer.to(dtype=torch.float32)
    cam = g.camera
    textures = gbuffer_textures(g)                                             # depth 1.0: depthThreshold
    ours = hemisphere_ssao(g, p, debug=True)
    noise = ours.debug["noise"].permute(1, 2, 0).numpy()                      # (S, S, 3), row 0 at the top
    shader = ShaderPass(
        MODULE, "SSAOShader", cam.width, cam.height, textures={**textures, "tNoise": noise}, repeat=("tNoise",),
        uniforms={**camera_uniforms(cam), "kernel": Uniform("vec3[]", ours.debug["kernel"].tolist()),
                  "kernelRadius": Uniform("float", float(p.kernel_radius)),
                  "minDistance": Uniform("float", float(p.min_distance)),
                  "maxDistance": Uniform("float", float(p.max_distance))},
        defines={"KERNEL_SIZE": int(p.kernel_size)}, patches=(ARTICLE_NOISE,) if article_noise else ())
    out = run_pass(shader, flip_rows=flip_rows)
    return torch.from_numpy(np.ascontiguousarray(out[..., 0]))[None, None], ours.ao
