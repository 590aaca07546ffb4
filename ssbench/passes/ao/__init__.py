"""Ambient-occlusion passes, one method per module: ``(gbuffer, params, *, generator=None, debug=False) →
AOResult``.

Each method module ends with its :class:`~ssbench.passes.registry.Method` declaration; ``ssbench.passes``
re-exports every declared method's function, parameters and ``nn.Module`` (``from ssbench.passes import hbao,
HBAO, HBAOParams``), found by :func:`~ssbench.passes.registry.discover`. Helper modules (``gtao_parts``,
``gtao_denoise``) declare nothing.
"""
from ..registry import discover

#: the methods declared in this package, in their declared order
METHODS = discover(__name__, "ao")
__all__ = ["METHODS"]
