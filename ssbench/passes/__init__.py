"""Screen-space passes: pure functions of (GBuffer, params, generator) with thin ``nn.Module`` wrappers.

No Mitsuba import and no file I/O here. Every pass module declares the G-buffer channels it reads in
``REQUIRES``. :data:`AO_METHODS` and :data:`SSR_METHODS` map a method name to ``"module:function:ParamsClass"``;
use :func:`ao_method` / :func:`ssr_method` to resolve it; :data:`IMPLICIT_METHODS` / :func:`implicit_method` do
the same for the implicit-surface ray casters (which take a surface and a camera, not a G-buffer).
"""
from __future__ import annotations

import importlib

from .common import AOResult

AO_METHODS: dict[str, str] = {
    "crytek": "ssbench.passes.ssao_crytek:crytek_ssao:CrytekSSAOParams",
    "ssao": "ssbench.passes.ssao:hemisphere_ssao:HemisphereSSAOParams",
    "hbao": "ssbench.passes.hbao:hbao:HBAOParams",
    "gtao": "ssbench.passes.gtao:gtao:GTAOParams",
}


def ao_method(name: str):
    """``(function, ParamsClass, REQUIRES)`` of an AO method by name."""
    if name not in AO_METHODS:
        raise KeyError(f"method: unknown AO method {name!r}; known: {', '.join(AO_METHODS)}")
    mod, fn, params = AO_METHODS[name].split(":")
    m = importlib.import_module(mod)
    return getattr(m, fn), getattr(m, params), getattr(m, "REQUIRES")


SSR_METHODS: dict[str, str] = {
    "linear": "ssbench.passes.ssr_linear:ssr_linear:LinearSSRParams",
    "dda": "ssbench.passes.ssr_dda:ssr_dda:DDASSRParams",
    "dda_supercover": "ssbench.passes.ssr_dda_supercover:ssr_dda_supercover:SupercoverDDASSRParams",
}


def ssr_method(name: str):
    """``(function, ParamsClass, REQUIRES)`` of an SSR method by name (the module may also declare
    ``REQUIRES_BACKFACE``, the extra channels its back-face depth option reads)."""
    if name not in SSR_METHODS:
        raise KeyError(f"method: unknown SSR method {name!r}; known: {', '.join(SSR_METHODS)}")
    mod, fn, params = SSR_METHODS[name].split(":")
    m = importlib.import_module(mod)
    return getattr(m, fn), getattr(m, params), getattr(m, "REQUIRES")


IMPLICIT_METHODS: dict[str, str] = {
    "fixed": "ssbench.passes.implicit_fixed:fixed_step:FixedStepParams",
    "sphere": "ssbench.passes.implicit_sphere:sphere_trace:SphereTraceParams",
    "progressive": "ssbench.passes.implicit_progressive:progressive:ProgressiveParams",
}


def implicit_method(name: str):
    """``(function, ParamsClass)`` of an implicit-surface ray caster by name (seed 004). The progressive method
    also takes and returns a ``ProgressiveState``; the others are stateless."""
    if name not in IMPLICIT_METHODS:
        raise KeyError(f"method: unknown implicit method {name!r}; known: {', '.join(IMPLICIT_METHODS)}")
    mod, fn, params = IMPLICIT_METHODS[name].split(":")
    m = importlib.import_module(mod)
    return getattr(m, fn), getattr(m, params)


def declared(fn, name: str, default=None):
    """What the module of pass ``fn`` declares as ``name``: the metadata a method keeps next to its code
    (``FLAVOUR``, ``TUNABLE``, ``EQUAL_SETTINGS``, ``DEFAULTS_SOURCE``, ``FRAME_PARAM``, …), else ``default``.

    Example:
        >>> declared(ao_method("gtao")[0], "FLAVOUR")
        'cosine'
    """
    return getattr(importlib.import_module(fn.__module__), name, default)


__all__ = ["AOResult", "AO_METHODS", "ao_method", "SSR_METHODS", "ssr_method", "IMPLICIT_METHODS",
           "implicit_method", "declared"]
