"""Implicit-surface ray casters (progressive-tracing article), one method per module: ``(surface, camera, params, *, state=None,
generator=None) → ImplicitResult``.

Each method module ends with its :class:`~ssbench.passes.registry.Method` declaration; ``ssbench.passes``
re-exports every declared method's function, parameters and ``nn.Module`` (``from ssbench.passes import
sphere_trace, SphereTrace, SphereTraceParams``), found by :func:`~ssbench.passes.registry.discover`. Helper
modules (``common``, ``analytic``, ``gbuffer``) declare nothing.
"""
from ..registry import discover

#: the methods declared in this package, in their declared order
METHODS = discover(__name__, "implicit")
__all__ = ["METHODS"]
