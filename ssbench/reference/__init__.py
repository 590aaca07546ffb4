"""Ground truth from Mitsuba 3 / Dr.Jit, rendered from the same scene at the same pixel centres.

Importing this package does not import Mitsuba; the variant is chosen on first use
(:mod:`ssbench.reference.backend`).
"""
from __future__ import annotations

from .color import color
from .gbuffer import DEFAULT_CHANNELS, gbuffer

__all__ = ["gbuffer", "color", "DEFAULT_CHANNELS"]
