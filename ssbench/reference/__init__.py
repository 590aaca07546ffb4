"""Ground truth from Mitsuba 3 / Dr.Jit, rendered from the same scene at the same pixel centres.

Importing this package does not import Mitsuba; the variant is chosen on first use
(:mod:`ssbench.reference.backend`).
"""
from __future__ import annotations

from .color import color
from .gbuffer import DEFAULT_CHANNELS, gbuffer

__all__ = ["gbuffer", "color", "DEFAULT_CHANNELS"]

from .ao import WEIGHTINGS, AOReference, ambient_occlusion, screen_space_oracle  # noqa: E402

__all__ += ["ambient_occlusion", "screen_space_oracle", "AOReference", "WEIGHTINGS"]

from .reflections import ReflectionReference, reflections  # noqa: E402

__all__ += ["reflections", "ReflectionReference"]

from .implicit import ImplicitReference, implicit  # noqa: E402
from .implicit_dense import DenseMarch, dense_march  # noqa: E402

__all__ += ["implicit", "ImplicitReference", "dense_march", "DenseMarch"]
