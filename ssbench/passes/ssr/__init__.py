"""Screen-space reflection marchers, one method per module: ``(gbuffer, params, *, generator=None, debug=False)
→ SSRResult``.

Each method module ends with its :class:`~ssbench.passes.registry.Method` declaration; ``ssbench.passes``
re-exports every declared method's function, parameters and ``nn.Module`` (``from ssbench.passes import ssr_dda,
DDASSR, DDASSRParams``), found by :func:`~ssbench.passes.registry.discover`. Helper modules (``common``, ``fade``,
``resolve``, ``visits``, ``dda_march``) declare nothing.
"""
from ..registry import discover

#: the methods declared in this package, in their declared order
METHODS = discover(__name__, "ssr")
__all__ = ["METHODS"]
