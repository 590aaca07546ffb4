"""A shared check for the SSR marchers' size-dynamic compiled steps: at two image sizes, every setting's compiled
run is compared with its eager run, and the second size must compile nothing new."""
from __future__ import annotations

import dataclasses
from typing import Callable, Iterable

import torch

from ssbench.passes import compiled as C


def equal_outputs(eager, comp) -> None:
    """Every tensor field of two SSR results, and every debug buffer, equal bit for bit."""
    for f in dataclasses.fields(eager):
        if f.name != "debug":
            assert torch.equal(getattr(eager, f.name), getattr(comp, f.name)), f.name
    for k, v in eager.debug.items():
        assert not isinstance(v, torch.Tensor) or torch.equal(v, comp.debug[k]), k


def check_compiled_at_two_sizes(make_gbuffer: Callable, run: Callable, settings: Iterable, sizes,
                                compare: Callable = equal_outputs) -> None:
    """``run(gbuffer, params)`` eager and compiled for every setting on ``make_gbuffer(w, h)`` at both ``sizes``;
    ``compare(eager, compiled)`` asserts what must agree. The eager run must hit something (else the check is
    vacuous); the second size must add no compiled graph and no compile time."""
    from torch._dynamo.utils import counters
    settings = list(settings)
    for n, (w, h) in enumerate(sizes):
        g = make_gbuffer(w, h)
        for p in settings:
            with C.compiling(False):
                eager = run(g, p)
            with C.compiling(True):
                comp = run(g, p)
            assert bool(eager.hit.any())
            compare(eager, comp)
        if n == 0:
            seconds, graphs = C.compile_seconds(), counters["stats"]["unique_graphs"]
            assert seconds > 0 and graphs >= 1
    assert counters["stats"]["unique_graphs"] == graphs and C.compile_seconds() == seconds   # nothing new
