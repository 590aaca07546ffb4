"""How a method declares itself, and how the package finds it.

A method is one module inside an effect package (``ssbench/passes/ao/``, ``ssr/``, ``implicit/``) that ends
with a :class:`Method` named ``METHOD``::

    METHOD = Method("hbao", hbao, HBAOParams, HBAO, order=30)

Nothing else lists it: :func:`discover` imports every module of the effect package and collects the
``METHOD`` declarations, so the registries (``ssbench.passes.AO_METHODS`` …), the CLI's ``--method`` choices,
sweeps, tuning and the report see a new method as soon as its module exists. The rest of what a method
declares (``REQUIRES``, ``FLAVOUR``, ``TUNABLE``, ``DEFAULTS_SOURCE`` …) sits beside ``METHOD`` in the same module
and is read with :func:`ssbench.passes.declared`.
"""
from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass
from typing import Callable, Optional

__all__ = ["Method", "discover", "spec", "face"]


@dataclass(frozen=True)
class Method:
    """A method's declaration.

    Attributes:
        name: what the CLI, sweep files and rows call it (``"hbao"``).
        function: the pass, ``function(gbuffer, params, *, generator=None, debug=False)`` for AO and SSR,
            ``function(surface, camera, params, *, state=None, generator=None)`` for implicit casters.
        params: its frozen parameter dataclass (defaults = what its authors ship).
        module: its thin ``nn.Module`` wrapper, if any.
        order: its place in listings and report tables (smaller first).
    """

    name: str
    function: Callable
    params: type
    module: Optional[type] = None
    order: int = 100

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"name: a method name must be an identifier, got {self.name!r}")
        if not callable(self.function):
            raise TypeError(f"function: expected a callable, got {type(self.function).__name__}")


def discover(package: str) -> list[Method]:
    """Every :class:`Method` declared by a module of ``package`` (imported here), sorted by ``order``, then
    name; two modules declaring one name is a ``ValueError`` naming both."""
    pkg = importlib.import_module(package)
    found: dict[str, tuple[Method, str]] = {}
    for info in pkgutil.iter_modules(pkg.__path__):
        mod = importlib.import_module(f"{package}.{info.name}")
        m = getattr(mod, "METHOD", None)
        if not isinstance(m, Method):
            continue
        if m.name in found:
            raise ValueError(f"method {m.name!r} is declared by both {found[m.name][1]} and {mod.__name__}")
        found[m.name] = (m, mod.__name__)
    return [m for m, _ in sorted(found.values(), key=lambda mm: (mm[0].order, mm[0].name))]


def spec(m: Method) -> str:
    """``"module:function:ParamsClass"``, the registry entry of ``m`` (what :func:`ssbench.passes.ao_method`
    resolves)."""
    return f"{m.function.__module__}:{m.function.__name__}:{m.params.__name__}"


def face(methods: list[Method]) -> dict:
    """The public names an effect package re-exports for ``methods``: each one's function, parameter class
    and ``nn.Module`` by their own names."""
    out: dict = {}
    for m in methods:
        for obj in (m.function, m.params, m.module):
            if obj is not None:
                out[obj.__name__] = obj
    return out
