"""Evaluate one screen-space pass on one scene against its ground truth: one tidy row per run.

* :func:`ao` / :func:`run_ao` (:mod:`ssbench.evaluate._ao`) — an AO pass against ray-traced AO in three targets
  (cosine, the pass's own flavour, the screen-space oracle);
* :func:`ssr` / :func:`run_ssr` (:mod:`ssbench.evaluate._ssr`) — an SSR pass against the exact mirror
  reflection (``ssbench.reference.reflections``): per-pixel classes, hit error, colour error, timings;
* :func:`ssr_glossy` / :func:`run_glossy` (:mod:`ssbench.evaluate._glossy`) — an SSR pass on rough surfaces
  against the path-traced specular lobe (``ssbench.reference.glossy``), the error split into information loss,
  marcher and resolve, per roughness bin;
* :func:`implicit` / :func:`run_implicit` (:mod:`ssbench.evaluate._implicit`) — an implicit-surface ray caster
  over frames against the certified first hit (``ssbench.reference.implicit``): per-frame punch-through, the
  h/w prediction, classes, cost, the λ diagnostic.

Shared helpers (:func:`resolve_params`, timing) live in :mod:`ssbench.evaluate._common`. No files are written
here (the reference's disk cache aside: ``use_cache=False`` turns it off).
"""
from __future__ import annotations

from ._ao import (BLUR_NAMES, GT_CHANNELS, RADIUS_NAMES, TARGET_METRICS, TARGETS, AOEvaluation, ao, blur_fn,
                  flavour, radius_param, run_ao, score)
from ._ao_beyond import ao_beyond, has_bent_normals
from ._common import resolve_params
from ._glossy import GLOSSY_GT_CHANNELS, ROUGHNESS_EDGES, GlossyEvaluation, run_glossy, ssr_glossy
from ._frames import MOVING_BAND, FramePlan
from ._temporal import EDGE_BAND, EDGE_JUMP, AOFrames, ao_frames, orbit
from ._temporal_ssr import SSRFrames, ssr_frames
from ._temporal_implicit import LATE_FRAMES, TXAA, ImplicitFrames, implicit_frames
from ._implicit import ImplicitEvaluation, implicit, lipschitz_diagnostic, run_implicit, steps_param
from ._ssr import (EQUAL_RAY_LENGTH, EQUAL_THICKNESS, SSR_GT_CHANNELS, SSREvaluation, equal_roles, equal_settings,
                   pass_channels, run_ssr, scene_scale, ssr)

__all__ = ["ao", "run_ao", "ao_beyond", "has_bent_normals", "AOEvaluation", "resolve_params", "radius_param", "flavour", "score", "blur_fn",
           "RADIUS_NAMES", "GT_CHANNELS", "TARGET_METRICS", "TARGETS", "BLUR_NAMES",
           "ssr", "run_ssr", "SSREvaluation", "pass_channels", "SSR_GT_CHANNELS", "equal_settings", "equal_roles",
           "scene_scale", "EQUAL_RAY_LENGTH", "EQUAL_THICKNESS",
           "ssr_glossy", "run_glossy", "GlossyEvaluation", "GLOSSY_GT_CHANNELS", "ROUGHNESS_EDGES",
           "ao_frames", "AOFrames", "orbit", "EDGE_BAND", "EDGE_JUMP", "MOVING_BAND", "FramePlan",
           "ssr_frames", "SSRFrames", "implicit_frames", "ImplicitFrames", "TXAA", "LATE_FRAMES",
           "implicit", "run_implicit", "ImplicitEvaluation", "steps_param", "lipschitz_diagnostic"]
