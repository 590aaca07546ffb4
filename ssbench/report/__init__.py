"""HTML report of reference renders: ``build_report`` (also ``ssbench report`` and ``make report``)."""
from __future__ import annotations

from .build import build_report, environment, git_state, render_scene

__all__ = ["build_report", "environment", "git_state", "render_scene"]
