"""What each effect times: the pass alone on the inputs its evaluation prepared (:class:`BenchInputs`), built from an
evaluation by the effect's *bench* function (:func:`ao_bench`, :func:`ssr_bench`, :func:`implicit_bench`), with
the texel reads per pixel that the gather floors repeat (:func:`ao_samples`: what an AO method declares; SSR and
implicit casters: their own step counts). The effect registry (:mod:`ssbench.bench.effects`) names these
functions; :mod:`ssbench.bench.timing` times them.
"""
from __future__ import annotations

import dataclasses
import importlib
from typing import Any, Callable, Mapping

import torch

__all__ = ["BenchInputs", "ao_samples", "ao_bench", "ssr_bench", "implicit_resolve", "implicit_run", "implicit_bench"]


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
