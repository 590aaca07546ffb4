"""A toy effect (no Mitsuba, no torch pass) registered for the tests that exercise the sweep machinery."""
import dataclasses
import types

import pytest
import torch

from ssbench.bench import effects as E


@dataclasses.dataclass(frozen=True)
class ToyParams:
    x: float = 1.0
    n: int = 2
    mode: str = "a"
    tile: object = None

    def __post_init__(self):
        if self.n < 1:
            raise ValueError(f"n: must be >= 1, got {self.n}")


def toy_pass(g, p, generator=None):
    return types.SimpleNamespace(ao=g * p.x)


TOY_METHODS = {"toy": "unused", "other": "unused"}
CALLS = []


def toy_resolve(name):
    if name not in TOY_METHODS:
        raise KeyError(f"method: unknown toy method {name!r}")
    return toy_pass, ToyParams, ("view_z",)


def toy_evaluate(scene, method, params, *, width, height, seed, repeats=1, level=0):
    """Deterministic row; x == 2 fails like a broken pass would."""
    CALLS.append((scene, method, dict(params), seed))
    p = ToyParams(**params)
    if p.x == 2.0:
        raise RuntimeError("boom at x=2")
    value = p.x * p.n + seed + 0.5 * level + width / height
    row = {"scene": scene, "method": method, "params": dataclasses.asdict(p), "width": width, "height": height,
           "seed": seed, "level": level, "value": value, "nan_metric": float("nan"), "seconds": 1e-3 * len(CALLS),
           "threads": torch.get_num_threads()}
    z = torch.full((1, 1, height, width), -float(p.x))
    return types.SimpleNamespace(row=row, gbuffer=types.SimpleNamespace(view_z=z), p=p)


def toy_bench(ev, method, params, seed):
    return E.BenchInputs(lambda: ev.gbuffer.view_z * 2, ev.gbuffer.view_z, torch.ones_like(ev.gbuffer.view_z,
                         dtype=torch.bool), ev.p.n * 3, ev.gbuffer.view_z)


TOY = E.Effect("toy", methods=TOY_METHODS, resolve=toy_resolve, evaluate=toy_evaluate, bench=toy_bench,
               settings={"level": E.Setting((int,), 0, lo=0)})


@pytest.fixture
def toy(monkeypatch):
    """Register the toy effect (one entry of EFFECTS) and stub the slow metadata probes."""
    monkeypatch.setitem(E.EFFECTS, "toy", TOY)
    import ssbench.runinfo as build
    monkeypatch.setattr(build, "environment", lambda: {"torch": torch.__version__, "variant": "stub",
                                                       "torch_threads": torch.get_num_threads(), "cpu_count": 2})
    monkeypatch.setattr(build, "git_state", lambda: {"commit": "c0ffee", "dirty": False})
    import ssbench.bench.sweep as S
    monkeypatch.setattr(S, "_variant", lambda: "stub")
    CALLS.clear()
    return TOY
