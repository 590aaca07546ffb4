"""The effect registry: what a sweep of ``effect: ao|ssr|implicit`` may set and how one configuration is run and timed.

An :class:`Effect` names, as ``"module:attribute"`` strings imported on first use (so a Dask worker needs only
the names), the effect's method registry, its resolver, its evaluation function and its *bench* function
(the pass alone, its output and its sample count, for :mod:`ssbench.bench.timing`), plus what ``images: true`` draws (:mod:`ssbench.bench.pictures`) and the settings a sweep
file may give at top level (``rays``, ``spp``, ...) with their defaults. Adding an effect is one entry of
:data:`EFFECTS`; e.g. the implicit-surface effect::

    "implicit": Effect("implicit", methods="ssbench.passes:IMPLICIT_METHODS",
                       resolve="ssbench.bench.bench_inputs:implicit_resolve", evaluate="ssbench.evaluate:run_implicit",
                       bench="ssbench.bench.bench_inputs:implicit_bench", settings={...})

The evaluation function is called as ``evaluate(scene, method, params, width=, height=, seed=, repeats=,
**settings)`` and returns an object with ``.row`` (a flat dict); the bench function gets that object and
returns :class:`BenchInputs`.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
from typing import Any, Mapping, Optional, Union

from ..reference.ao import WEIGHTINGS as AO_WEIGHTINGS
from .bench_inputs import (BenchInputs, ao_bench, ao_samples, implicit_bench, implicit_resolve, implicit_run,
                           ssr_bench)

__all__ = ["Setting", "Effect", "BenchInputs", "EFFECTS", "COMMON_SETTINGS", "get_effect", "ao_samples",
           "ao_bench", "ssr_bench", "implicit_resolve", "implicit_run", "implicit_bench"]


def _load(ref: Union[str, Any]) -> Any:
    """``"pkg.module:attr"`` imported, or ``ref`` itself when it is already an object."""
    if not isinstance(ref, str):
        return ref
    mod, _, attr = ref.partition(":")
    return getattr(importlib.import_module(mod), attr)


@dataclasses.dataclass(frozen=True)
class Setting:
    """A top-level sweep setting: allowed ``types`` (``type(None)`` allows null), default, bounds, choices.

    Example:
        >>> Setting((int,), 64, lo=2).check(128)
        128
        >>> Setting((float,), 1.5).check(2)            # ints widen to float
        2.0
        >>> Setting((str, type(None)), None, choices=("box",)).check("disk")
        Traceback (most recent call last):
        ValueError: expected one of 'box' or null, got 'disk'
    """

    types: tuple
    default: Any
    lo: Optional[float] = None
    choices: Optional[tuple] = None
    help: str = ""

    def check(self, v: Any) -> Any:
        """``v`` validated and coerced (int → float for float settings); ``ValueError`` says what is wrong."""
        if v is None:
            if type(None) in self.types:
                return None
            raise ValueError("must not be null")
        if self.choices is not None:
            if v not in self.choices:
                opts = " or ".join([", ".join(map(repr, self.choices))] + (["null"] if type(None) in self.types
                                                                          else []))
                raise ValueError(f"expected one of {opts}, got {v!r}")
            return v
        if bool in self.types:
            if not isinstance(v, bool):
                raise ValueError(f"expected true or false, got {v!r}")
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float) if float in self.types else self.types):
            names = " or ".join("an integer" if t is int else "a number" if t is float else t.__name__
                                for t in self.types if t is not type(None))
            raise ValueError(f"expected {names}, got {v!r}")
        if float in self.types:
            v = float(v)
            if not math.isfinite(v):
                raise ValueError(f"must be finite, got {v!r}")
        if self.lo is not None and v < self.lo:
            raise ValueError(f"must be >= {self.lo:g}, got {v!r}")
        return v


#: settings every effect has: torch threads (fixed per configuration, recorded, a sweepable axis) and the
#: evaluation's own timed repeats behind its ``seconds`` field
COMMON_SETTINGS: dict[str, Setting] = {
    "threads": Setting((int,), 1, lo=1, help="torch.set_num_threads for the configuration"),
    "repeats": Setting((int,), 1, lo=1, help="timed runs behind the evaluation's own 'seconds'"),
}


@dataclasses.dataclass(frozen=True)
class Effect:
    """One effect a sweep can run (see the module docstring); references are ``"module:attr"`` or objects."""

    name: str
    methods: Any          # the method registry: name -> "module:function:ParamsClass"
    resolve: Any          # name -> (function, ParamsClass, REQUIRES)
    evaluate: Any         # evaluate(scene, method, params, **kwargs) -> object with .row
    bench: Any            # bench(evaluation, method, params, seed) -> BenchInputs
    settings: Mapping[str, Setting] = dataclasses.field(default_factory=dict)
    help: str = ""
    scene_names: Any = "ssbench.scenes.catalog:names"   # () -> built-in scene names
    load_scene: Any = "ssbench.scenes:load"              # name or file -> scene (raises on a bad file)
    pictures: Any = None  # a ssbench.bench.pictures.Pictures: what `images: true` draws per configuration

    def picture_spec(self):
        """The effect's :class:`ssbench.bench.pictures.Pictures` (``None`` when it draws nothing)."""
        return None if self.pictures is None else _load(self.pictures)

    def method_names(self) -> list[str]:
        """Names of the effect's methods, in registry order."""
        return list(_load(self.methods))

    def method(self, name: str) -> tuple:
        """``(function, ParamsClass, REQUIRES)`` of a method (``KeyError`` listing the known ones)."""
        return _load(self.resolve)(name)

    def builtin_scenes(self) -> list[str]:
        """Names of the built-in scenes this effect runs on."""
        return list(_load(self.scene_names)())

    def check_scene_file(self, path: str) -> None:
        """Load the scene file ``path`` once (its own ``file:line`` error when invalid)."""
        _load(self.load_scene)(path)

    def all_settings(self) -> dict[str, Setting]:
        """:data:`COMMON_SETTINGS` plus the effect's own."""
        return {**COMMON_SETTINGS, **self.settings}

    def run(self, scene, method: str, params: Mapping, *, width: int, height: int, seed: int,
            settings: Mapping[str, Any]):
        """Run the evaluation of one configuration; ``settings`` minus ``threads`` become keyword arguments."""
        kwargs = {k: v for k, v in settings.items() if k != "threads"}
        return _load(self.evaluate)(scene, method, dict(params), width=width, height=height, seed=seed, **kwargs)

    def bench_inputs(self, evaluation, method: str, params: Mapping, seed: int) -> BenchInputs:
        return _load(self.bench)(evaluation, method, params, seed)


_NULL = type(None)

#: effect name -> :class:`Effect`; the sweep file's ``effect:`` picks one
EFFECTS: dict[str, Effect] = {
    "ao": Effect(
        "ao", methods="ssbench.passes:AO_METHODS", resolve="ssbench.passes:ao_method",
        evaluate="ssbench.evaluate:run_ao", bench="ssbench.bench.bench_inputs:ao_bench",
        pictures="ssbench.bench.pictures:AO_PICTURES",
        settings={"rays": Setting((int,), 256, lo=2, help="ground-truth rays per pixel"),
                  "blur": Setting((str, _NULL), None, choices=("box", "cross_bilateral", "joint_bilateral")),
                  "weighting": Setting((str, _NULL), None, choices=AO_WEIGHTINGS),
                  "oracle": Setting((bool,), True, help="trace the screen-space oracle"),
                  "flip": Setting((bool,), True, help="compute FLIP")},
        help="ambient occlusion vs ray-traced AO (ssbench.evaluate.ao)"),
    "ssr": Effect(
        "ssr", methods="ssbench.passes:SSR_METHODS", resolve="ssbench.passes:ssr_method",
        evaluate="ssbench.evaluate:run_ssr", bench="ssbench.bench.bench_inputs:ssr_bench",
        pictures="ssbench.bench.pictures:SSR_PICTURES",
        settings={"spp": Setting((int,), 16, lo=1, help="colour samples per pixel"),
                  "k_px": Setting((float,), 1.5, lo=0.0, help="hit tolerance in pixels"),
                  "reflective": Setting((str, _NULL), None, choices=("marched", "specular")),
                  "flip": Setting((bool,), True, help="compute FLIP")},
        help="screen-space reflections vs exact mirror reflections (ssbench.evaluate.ssr)"),
    "implicit": Effect(
        "implicit", methods="ssbench.passes:IMPLICIT_METHODS", resolve="ssbench.bench.bench_inputs:implicit_resolve",
        evaluate="ssbench.bench.bench_inputs:implicit_run", bench="ssbench.bench.bench_inputs:implicit_bench",
        pictures="ssbench.bench.pictures:IMPLICIT_PICTURES",
        settings={"frames": Setting((int,), 1, lo=1, help="frames cast per configuration (progressive state "
                                                          "carries across them)"),
                  "truth_frames": Setting((str,), "all", choices=("all", "last", "none"),
                                          help="frames scored against the certified reference")},
        scene_names="ssbench.implicit.catalog:names", load_scene="ssbench.implicit:load",
        help="implicit-surface ray casting vs the certified first hit (ssbench.evaluate.implicit)"),
}


def get_effect(name: str) -> Effect:
    """The registered :class:`Effect` called ``name`` (``KeyError`` listing the known effects)."""
    if name not in EFFECTS:
        raise KeyError(f"effect: unknown effect {name!r}; known: {', '.join(EFFECTS)}")
    return EFFECTS[name]
