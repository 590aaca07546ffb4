"""How a method declares itself, and how the package finds it.

A method is one module inside an effect package (``ssbench/passes/ao/``, ``ssr/``, ``implicit/``) that ends
with a :class:`Method` named ``METHOD``::

    METHOD = Method("hbao", hbao, HBAOParams, HBAO, order=30)

Nothing else lists it: :func:`discover` imports every module of the effect package and collects the
``METHOD`` declarations, so the registries (``ssbench.passes.AO_METHODS`` …), the CLI's ``--method`` choices,
sweeps, tuning and the report see a new method as soon as its module exists. The rest of what a method
declares (``REQUIRES``, ``FLAVOUR``, ``TUNABLE``, ``DEFAULTS_SOURCE`` …) sits beside ``METHOD`` in the same module
and is read with :func:`ssbench.passes.declared`; so are ``SPEED_GRIDS`` (the configurations the report's
speed sweeps run, per sweep purpose) and ``SPEED_PANELS`` (its artifact-vs-parameter plots, :class:`SpeedPanel`).

A method kept outside the package (your own, without forking ssbench) is one importable module whose ``METHOD``
names its effect, ``Method("mine", mine, MineParams, effect="ao")``; list it in the environment variable
``SSBENCH_METHODS`` (comma-separated module names, read once when ``ssbench.passes`` is imported:
:func:`plugins`), and every command sees it as if it were built in.
"""
from __future__ import annotations

import dataclasses
import importlib
import os
import pkgutil
from dataclasses import dataclass
from typing import Callable, Optional

__all__ = ["Method", "SpeedPanel", "EFFECTS", "discover", "plugins", "merged", "spec", "face"]

#: the effects a method can belong to (one package each under ``ssbench/passes/``)
EFFECTS = ("ao", "ssr", "implicit")
#: environment variable listing out-of-package method modules
PLUGINS_ENV = "SSBENCH_METHODS"


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
        effect: ``"ao"``, ``"ssr"`` or ``"implicit"``; set from the package for built-in methods, required
            for a module listed in ``SSBENCH_METHODS``.
        title: what the method is, in words, for people (reports, ``--help``): ``"horizon-based AO (HBAO)"``;
            empty: the name is used.
    """

    name: str
    function: Callable
    params: type
    module: Optional[type] = None
    order: int = 100
    effect: Optional[str] = None
    title: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"name: a method name must be an identifier, got {self.name!r}")
        if not callable(self.function):
            raise TypeError(f"function: expected a callable, got {type(self.function).__name__}")
        if not isinstance(self.params, type):
            raise TypeError(f"params: expected the parameter class, got {type(self.params).__name__}")
        if self.effect is not None and self.effect not in EFFECTS:
            raise ValueError(f"effect: expected one of {', '.join(EFFECTS)}, got {self.effect!r}")


@dataclass(frozen=True)
class SpeedPanel:
    """One artifact-vs-parameter small multiple a method asks the report's speed section for (declared in its
    module as ``SPEED_PANELS = (SpeedPanel(...), ...)``, beside ``SPEED_GRIDS``, the sweeps that feed it).

    Attributes:
        figure: which of the effect's artifact figures the panel joins (``"banding"``, ``"halos"`` for AO,
            ``"hits"`` for SSR, ``"punch"`` for implicit casters: :data:`ssbench.report.speed_section.SPECS`).
        param: the parameter (or row field, e.g. ``"frame"``) on the x axis.
        fix: ``(key, value)`` pairs a row must match to be drawn (e.g. ``(("blur", None),)``).
        metric: the row key on the y axis; ``None``: the figure's metric.

    Example:
        >>> SpeedPanel("banding", "kernel_size", (("blur", None),))
        SpeedPanel(figure='banding', param='kernel_size', fix=(('blur', None),), metric=None)
    """

    figure: str
    param: str
    fix: tuple = ()
    metric: Optional[str] = None


def _ordered(methods) -> list[Method]:
    return sorted(methods, key=lambda m: (m.order, m.name))


def discover(package: str, effect: str) -> list[Method]:
    """Every :class:`Method` declared by a module of ``package`` (imported here), of ``effect``, sorted by
    ``order``, then name; two modules declaring one name is a ``ValueError`` naming both."""
    pkg = importlib.import_module(package)
    found: dict[str, tuple[Method, str]] = {}
    for info in pkgutil.iter_modules(pkg.__path__):
        mod = importlib.import_module(f"{package}.{info.name}")
        m = getattr(mod, "METHOD", None)
        if not isinstance(m, Method):
            continue
        if m.effect not in (None, effect):
            raise ValueError(f"{mod.__name__}: METHOD declares effect {m.effect!r} inside the {effect!r} package")
        if m.name in found:
            raise ValueError(f"method {m.name!r} is declared by both {found[m.name][1]} and {mod.__name__}")
        found[m.name] = (dataclasses.replace(m, effect=effect), mod.__name__)
    return _ordered(m for m, _ in found.values())


def plugins(value: Optional[str] = None) -> list[Method]:
    """The methods of the modules listed in ``SSBENCH_METHODS`` (or ``value``): comma-separated importable
    module names, each ending with a ``METHOD`` whose ``effect`` is set. Errors name the variable and module."""
    value = os.environ.get(PLUGINS_ENV, "") if value is None else value
    found: dict[str, tuple[Method, str]] = {}
    for name in (n.strip() for n in value.split(",")):
        if not name:
            continue
        try:
            mod = importlib.import_module(name)
        except ImportError as e:
            raise ValueError(f"{PLUGINS_ENV}: cannot import {name!r} ({e})") from None
        m = getattr(mod, "METHOD", None)
        if not isinstance(m, Method):
            raise ValueError(f"{PLUGINS_ENV}: module {name!r} declares no METHOD = Method(...)")
        if m.effect is None:
            raise ValueError(f"{PLUGINS_ENV}: {name}.METHOD must name its effect ({', '.join(EFFECTS)})")
        if m.name in found:
            raise ValueError(f"{PLUGINS_ENV}: method {m.name!r} is declared by both {found[m.name][1]} and {name}")
        found[m.name] = (m, name)
    return _ordered(m for m, _ in found.values())


def merged(built_in: list[Method], extra: list[Method], effect: str) -> list[Method]:
    """``built_in`` plus the ``extra`` methods of ``effect``, in declared order; a name taken twice is an
    error."""
    names = {m.name for m in built_in}
    clash = [m.name for m in extra if m.effect == effect and m.name in names]
    if clash:
        raise ValueError(f"{PLUGINS_ENV}: {', '.join(clash)} already names a built-in {effect} method")
    return _ordered(built_in + [m for m in extra if m.effect == effect])


def spec(m: Method) -> str:
    """``"module:function:ParamsClass"``, the registry entry of ``m`` (what :func:`ssbench.passes.ao_method`
    resolves)."""
    return f"{m.function.__module__}:{m.function.__name__}:{m.params.__name__}"


def face(methods: list[Method]) -> dict:
    """The public names ``ssbench.passes`` re-exports for ``methods``: each one's function, parameter class
    and ``nn.Module`` by their own names; two methods offering one name is a ``ValueError``."""
    out: dict = {}
    for m in methods:
        for obj in (m.function, m.params, m.module):
            if obj is not None:
                if out.get(obj.__name__, obj) is not obj:
                    raise ValueError(f"method {m.name!r}: the public name {obj.__name__!r} is taken by another method")
                out[obj.__name__] = obj
    return out
