"""three.js ``SSRShader`` (``examples/jsm/shaders/SSRShader.js``) run on an ssbench G-buffer, against
:func:`ssbench.passes.ssr.three_ssr.ssr_three` on the same inputs.

Inputs (float32): ``tDepth`` the GL depth buffer (exactly 1.0 on background texels, which the shader skips as
``-viewZ >= cameraFar``), ``tNormal`` the view normals packed ``n · 0.5 + 0.5``, ``tDiffuse`` the colour buffer,
the projection matrix and its closed-form inverse, ``maxDistance``, ``thickness``, ``opacity``, ``MAX_STEP``.
One patch, which changes no pixel the shader writes: ``gl_FragColor = vec4(0.0)`` first in ``main`` (the shader
``return``s without writing where it finds nothing, which GLSL leaves undefined).

The article's linear march (:mod:`ssbench.passes.ssr.linear`) is *not* this shader — the SSR article predates it and
ships its own (view-space steps, a depth-interval thickness, bisection); :data:`DIFFERENCES` lists what differs.
"""
from __future__ import annotations

import math

import numpy as np
import torch

from ..gbuffer import GBuffer
from ..passes.ssr.three_ssr import ThreeSSRParams, ssr_three
from .runtime import ShaderPass, Uniform, camera_uniforms, gbuffer_textures, run_pass

__all__ = ["three_ssr_shader", "DIFFERENCES", "MODULE", "PROOF", "ZERO_FIRST"]

MODULE = "three/addons/shaders/SSRShader.js"
#: the harness's one patch: a defined output where the shader writes none
ZERO_FIRST = ("void main(){", "void main(){ gl_FragColor = vec4( 0.0 );")
PROOF = "three_ssr = three.js SSRShader (defaults; infinite_thick and distance_attenuation/fresnel toggles)"
DIFFERENCES = ("SSRShader marches a pixel DDA (one texel per step along the major axis) with perspective-correct "
               "depth; the article's linear march takes Iterations equal view-space steps and bisects",
               "SSRShader's thickness is a distance to the ray's line, at least 3 texel widths; the article's is a "
               "depth interval behind the depth buffer",
               "SSRShader stops at back faces and weights by distance attenuation and a Fresnel-like term; the "
               "article fades at screen edges, vignette and distance",
               "after a background texel SSRShader skips its depth step (continue before s += sStep): its ray's "
               "depth lags its pixel from then on")


def three_ssr_shader(gbuffer: GBuffer, params: ThreeSSRParams = ThreeSSRParams(), *,
                     flip_rows: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
    """``(shader_rgba, pass_rgba)``, both :math:`(1, 4, H, W)`: three.js ``SSRShader``'s output (reflected colour,
    alpha ``op``; 0 where it finds nothing) and the same from :func:`ssr_three` (``raw_color``, ``fade``)."""
    g = gbuffer.to(dtype=torch.float32)
    cam = g.camera
    textures = gbuffer_textures(g)
    max_step = params.max_step or int(math.sqrt(cam.width ** 2 + cam.height ** 2))
    ours = ssr_three(g, params)
    shader = ShaderPass(
        MODULE, "SSRShader", cam.width, cam.height,
        textures={**textures, "tDiffuse": np.concatenate([g.color[0].permute(1, 2, 0).numpy(),
                                                          np.ones((cam.height, cam.width, 1), np.float32)], -1)},
        uniforms={**camera_uniforms(cam), "opacity": Uniform("float", float(params.opacity)),
                  "maxDistance": Uniform("float", float(params.max_distance)),
                  "thickness": Uniform("float", float(params.thickness))},
        defines={"MAX_STEP": max_step, "DISTANCE_ATTENUATION": params.distance_attenuation,
                 "FRESNEL": params.fresnel, "INFINITE_THICK": params.infinite_thick},
        patches=(ZERO_FIRST,))
    out = torch.from_numpy(run_pass(shader, flip_rows=flip_rows)).permute(2, 0, 1)[None]
    hit = ours.hit.to(torch.float32)
    return out, torch.cat([ours.raw_color * hit, ours.fade * hit], 1)
