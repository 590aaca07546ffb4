"""ssbench: screen-space rendering effects compared against Mitsuba 3 ground truth."""
from __future__ import annotations

__version__ = "0.1.0"

from .camera import Camera  # noqa: E402
from .gbuffer import GBuffer  # noqa: E402

__all__ = ["Camera", "GBuffer", "__version__"]
