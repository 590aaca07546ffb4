"""The effect registry: what a sweep of ``effect: ao|ssr|implicit`` may set and how one configuration is run and timed.

An :class:`Effect` names, as ``"module:attribute"`` strings imported on first use (so a Dask worker needs only
the names), the effect's method registry, its resolver, its evaluation function and its *bench* function
(the pass alone, its output and its sample count, for :mod:`ssbench.bench.timing`), plus the settings a sweep
file may give at top level (``rays``, ``spp``, ...) with their defaults. Adding an effect is one entry of
:data:`EFFECTS`; e.g. the implicit-surface effect::

    "implicit": Effect("implicit", methods="ssbench.passes:IMPLICIT_METHODS",
                       resolve="ssbench.bench.effects:implicit_resolve", evaluate="ssbench.evaluate:run_implicit",
                       bench="ssbench.bench.effects:implicit_bench", settings={...})

The evaluation function is called as ``evaluate(scene, method, params, width=, height=, seed=, repeats=,
**settings)`` and returns an object with ``.row`` (a flat dict); the bench function gets that object and
returns :class:`BenchInputs`.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
from typing import Any, Callable, Mapping, Optional, Union

import torch

from ..reference.ao import WEIGHTINGS as AO_WEIGHTINGS

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
class BenchInputs:
    """What :func:`ssbench.bench.timing.time_pass` needs: the pass alone and what to check and gather.

    Attributes:
        call: one run of the pass on prepared inputs (no scoring, no ground truth).
        output: :math:`(B, C, H, W)` the pass output already computed by the evaluation (checked for NaN/Inf).
        valid: :math:`(B, 1, H, W)` bool, the pixels whose output must be finite.
        samples: texel reads per pixel of the pass (the gather floor reads as many).
        texture: :math:`(B, C, H, W)` the texture the gather floor reads (the depth buffer).
    """

    call: Callable[[], Any]
    output: torch.Tensor
    valid: torch.Tensor
    samples: int
    texture: torch.Tensor


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


# ------------------------------------------------------------------------------------------ AO
def ao_samples(method: str, params, module=None) -> int:
    """Depth texels an AO pass reads per pixel in its main loop (small constant extras ignored).

    The method's module declares it as ``samples_per_pixel(params)`` (``module``: the pass module; ``None``
    looks the method up). A module without one falls back on its parameter names: ``num_directions ×
    num_steps``, else ``kernel_size``.

    Example:
        >>> from ssbench.passes.ao.hbao import HBAOParams
        >>> ao_samples("hbao", HBAOParams(num_directions=4, num_steps=3))
        12
    """
    if module is None:
        from ..passes import AO_METHODS, ao_method
        module = importlib.import_module(ao_method(method)[0].__module__) if method in AO_METHODS else None
    hook = getattr(module, "samples_per_pixel", None)
    if callable(hook):
        return int(hook(params))
    names = {f.name for f in dataclasses.fields(params)}
    if {"num_directions", "num_steps"} <= names:
        return params.num_directions * params.num_steps
    if "kernel_size" in names:
        return params.kernel_size
    raise ValueError(f"method: no sample count known for AO method {method!r}; define "
                     f"samples_per_pixel(params) in its module")


def ao_bench(evaluation, method: str, params: Mapping, seed: int) -> BenchInputs:
    """:class:`BenchInputs` of an AO evaluation (:class:`ssbench.evaluate.AOEvaluation`)."""
    from ..evaluate import resolve_params
    from ..passes import ao_method
    fn, params_cls, requires = ao_method(method)
    p = resolve_params(params_cls, params, method)
    g = evaluation.gbuffer.select(tuple(dict.fromkeys(requires)))

    def call():
        return fn(g, p, generator=torch.Generator().manual_seed(seed))

    return BenchInputs(call, evaluation.result.ao.detach().cpu(), evaluation.gbuffer.mask.cpu(),
                       ao_samples(method, p, importlib.import_module(fn.__module__)), evaluation.gbuffer.view_z)


# ------------------------------------------------------------------------------------------ SSR
def ssr_bench(evaluation, method: str, params: Mapping, seed: int) -> BenchInputs:
    """:class:`BenchInputs` of an SSR evaluation; the sample count is the mean ``steps`` of its hit buffer
    over all pixels (total depth reads / pixels, at least 1)."""
    from ..evaluate import pass_channels, resolve_params
    from ..evaluate._ssr import accepted_kwargs
    from ..passes import ssr_method
    fn, params_cls, _ = ssr_method(method)
    p = resolve_params(params_cls, params, method)
    g = evaluation.gbuffer.select(pass_channels(importlib.import_module(fn.__module__), p))

    def call():
        return fn(g, p, **accepted_kwargs(fn, generator=torch.Generator().manual_seed(seed)))

    steps = evaluation.result.steps.float()
    return BenchInputs(call, evaluation.result.color.detach().cpu(), evaluation.gbuffer.mask.cpu(),
                       max(1, round(float(steps.mean()))), evaluation.gbuffer.view_z)


# ------------------------------------------------------------------------------------------ implicit
def implicit_resolve(name: str) -> tuple:
    """``(function, ParamsClass, ())`` of an implicit ray caster (it needs a surface and camera, no G-buffer)."""
    from ..passes import implicit_method
    return (*implicit_method(name), ())


def implicit_run(scene, method: str, params: Mapping, *, width: int, height: int, seed: int, repeats: int = 1,
                 frames: int = 1, truth_frames: str = "all"):
    """:func:`ssbench.evaluate.run_implicit` for a sweep: ``frames`` frames scored against the certified truth.

    ``repeats`` is accepted for the common settings but unused: the row already carries the median
    ``seconds_per_frame`` over its frames.
    """
    from ..evaluate import run_implicit
    return run_implicit(scene, method, dict(params), frames=frames, width=width, height=height, seed=seed,
                        truth_frames=truth_frames)


def implicit_bench(evaluation, method: str, params: Mapping, seed: int) -> BenchInputs:
    """:class:`BenchInputs` of an implicit evaluation (:class:`ssbench.evaluate.ImplicitEvaluation`).

    The timed call is one frame from scratch (the progressive method from an empty state, i.e. its first
    frame); the sample count is the mean f evaluations per pixel of the last frame; the floor gathers from the
    hit-distance image (0 where no hit).
    """
    import dataclasses as dc

    from ..evaluate import resolve_params
    from ..passes import declared, implicit_method
    fn, params_cls = implicit_method(method)
    p = resolve_params(params_cls, params, method)
    if "seed" in {f.name for f in dc.fields(p)} and "seed" not in params:
        p = dc.replace(p, seed=seed)
    surf, cam = evaluation.scene.surface(0), evaluation.cameras[0]
    jittered = getattr(p, "jitter", False) and not declared(fn, "STATEFUL", False)

    def call():                           # the progressive method from an empty state: its first frame
        return fn(surf, cam, p, generator=torch.Generator().manual_seed(seed) if jittered else None)

    res = evaluation.result
    depth = torch.where(res.hit, res.t, torch.zeros_like(res.t)).float()
    return BenchInputs(call, depth, torch.ones_like(res.hit), max(1, round(float(res.evaluations.double().mean()))),
                       depth)


_NULL = type(None)

#: effect name -> :class:`Effect`; the sweep file's ``effect:`` picks one
EFFECTS: dict[str, Effect] = {
    "ao": Effect(
        "ao", methods="ssbench.passes:AO_METHODS", resolve="ssbench.passes:ao_method",
        evaluate="ssbench.evaluate:run_ao", bench="ssbench.bench.effects:ao_bench",
        pictures="ssbench.bench.pictures:AO_PICTURES",
        settings={"rays": Setting((int,), 256, lo=2, help="ground-truth rays per pixel"),
                  "blur": Setting((str, _NULL), None, choices=("box", "cross_bilateral", "joint_bilateral")),
                  "weighting": Setting((str, _NULL), None, choices=AO_WEIGHTINGS),
                  "oracle": Setting((bool,), True, help="trace the screen-space oracle"),
                  "flip": Setting((bool,), True, help="compute FLIP")},
        help="ambient occlusion vs ray-traced AO (ssbench.evaluate.ao)"),
    "ssr": Effect(
        "ssr", methods="ssbench.passes:SSR_METHODS", resolve="ssbench.passes:ssr_method",
        evaluate="ssbench.evaluate:run_ssr", bench="ssbench.bench.effects:ssr_bench",
        pictures="ssbench.bench.pictures:SSR_PICTURES",
        settings={"spp": Setting((int,), 16, lo=1, help="colour samples per pixel"),
                  "k_px": Setting((float,), 1.5, lo=0.0, help="hit tolerance in pixels"),
                  "reflective": Setting((str, _NULL), None, choices=("marched", "specular")),
                  "flip": Setting((bool,), True, help="compute FLIP")},
        help="screen-space reflections vs exact mirror reflections (ssbench.evaluate.ssr)"),
    "implicit": Effect(
        "implicit", methods="ssbench.passes:IMPLICIT_METHODS", resolve="ssbench.bench.effects:implicit_resolve",
        evaluate="ssbench.bench.effects:implicit_run", bench="ssbench.bench.effects:implicit_bench",
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
