"""The passes, grouped by effect: ``ao/`` (ambient occlusion), ``ssr/`` (screen-space reflections) and
``implicit/`` (implicit-surface ray casters), plus what they share (``common``, ``gbuffer_checks``,
``sampling``, ``blur``, ``composite``) and the per-pixel teaching twins (``teaching/``).

Screen-space passes are pure functions ``(gbuffer, params, *, generator=None, debug=False)`` with thin
``nn.Module`` wrappers; implicit casters take ``(surface, camera, params, …)``. No Mitsuba import and no file I/O
here. A method is one module that ends with its :class:`~ssbench.passes.registry.Method` declaration (and
declares the G-buffer channels it reads in ``REQUIRES``); nothing here lists method names. :data:`AO_METHODS`,
:data:`SSR_METHODS` and :data:`IMPLICIT_METHODS` map each declared name to ``"module:function:ParamsClass"`` (in
the methods' declared ``order``); :func:`ao_method`, :func:`ssr_method` and :func:`implicit_method` resolve one.
Every declared method's function, parameters and module are also public here
(``from ssbench.passes import hbao, HBAO, HBAOParams``).
"""
from __future__ import annotations

import importlib

from . import ao as _ao
from . import implicit as _implicit
from . import ssr as _ssr
from .common import AOResult
from .registry import Method, SpeedPanel, face, merged, plugins, spec

_PLUGINS = plugins()                # modules listed in SSBENCH_METHODS (ssbench.passes.registry.plugins)
_ALL = {e: merged(pkg.METHODS, _PLUGINS, e) for e, pkg in (("ao", _ao), ("ssr", _ssr), ("implicit", _implicit))}

AO_METHODS: dict[str, str] = {m.name: spec(m) for m in _ALL["ao"]}


def ao_method(name: str):
    """``(function, ParamsClass, REQUIRES)`` of an AO method by name."""
    if name not in AO_METHODS:
        raise KeyError(f"method: unknown AO method {name!r}; known: {', '.join(AO_METHODS)}")
    mod, fn, params = AO_METHODS[name].split(":")
    m = importlib.import_module(mod)
    return getattr(m, fn), getattr(m, params), getattr(m, "REQUIRES")


SSR_METHODS: dict[str, str] = {m.name: spec(m) for m in _ALL["ssr"]}


def ssr_method(name: str):
    """``(function, ParamsClass, REQUIRES)`` of an SSR method by name (the module may also declare
    ``REQUIRES_BACKFACE``, the extra channels its back-face depth option reads)."""
    if name not in SSR_METHODS:
        raise KeyError(f"method: unknown SSR method {name!r}; known: {', '.join(SSR_METHODS)}")
    mod, fn, params = SSR_METHODS[name].split(":")
    m = importlib.import_module(mod)
    return getattr(m, fn), getattr(m, params), getattr(m, "REQUIRES")


IMPLICIT_METHODS: dict[str, str] = {m.name: spec(m) for m in _ALL["implicit"]}


def implicit_method(name: str):
    """``(function, ParamsClass)`` of an implicit-surface ray caster by name (progressive-tracing article). The progressive method
    also takes and returns a ``ProgressiveState``; the others are stateless."""
    if name not in IMPLICIT_METHODS:
        raise KeyError(f"method: unknown implicit method {name!r}; known: {', '.join(IMPLICIT_METHODS)}")
    mod, fn, params = IMPLICIT_METHODS[name].split(":")
    m = importlib.import_module(mod)
    return getattr(m, fn), getattr(m, params)


def title(name: str) -> str:
    """What method ``name`` is, in words (its declared ``Method.title``), else ``name`` itself.

    Example:
        >>> title("hbao")
        'horizon-based AO, HBAO (Bavoil et al. 2008)'
    """
    m = next((m for ms in _ALL.values() for m in ms if m.name == name), None)
    return m.title if m is not None and m.title else name


def declared(fn, name: str, default=None):
    """What the module of pass ``fn`` declares as ``name``: the metadata a method keeps next to its code
    (``FLAVOUR``, ``TUNABLE``, ``EQUAL_SETTINGS``, ``DEFAULTS_SOURCE``, ``FRAME_PARAM``, …), else ``default``.

    Example:
        >>> declared(ao_method("gtao")[0], "FLAVOUR")
        'cosine'
    """
    return getattr(importlib.import_module(fn.__module__), name, default)


_FACE = face(_ALL["ao"] + _ALL["ssr"] + _ALL["implicit"])   # every method's function, params and module
globals().update(_FACE)

__all__ = ["AOResult", "Method", "SpeedPanel", "AO_METHODS", "ao_method", "SSR_METHODS", "ssr_method", "IMPLICIT_METHODS",
           "implicit_method", "declared", "title", *_FACE]
