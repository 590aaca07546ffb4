"""ssbench.passes.inference: a pass run without autograd's bookkeeping gives the same bits as the plain pass and
hands back normal tensors (usable in a backward pass, changeable in place); where a gradient can flow, inside
compiled mode and under the caller's own inference mode, the pass runs as it is."""
from __future__ import annotations

import dataclasses

import pytest
import torch

from ssbench.implicit.scene import load
from ssbench.implicit.shading import shade_hits
from ssbench.passes import AO_METHODS, IMPLICIT_METHODS, SSR_METHODS, ao_method, implicit_method, ssr_method
from ssbench.passes.compiled import compiling
from ssbench.passes.inference import as_normal, autograd_free, wants_grad
from tests.passes.ssr_scenes import room


def tensors(value, path: str = "") -> dict:
    """``{path: tensor}`` of every tensor in a result (dataclasses, dicts, tuples and lists)."""
    if isinstance(value, torch.Tensor):
        return {path: value}
    out: dict = {}
    if dataclasses.is_dataclass(value):
        for f in dataclasses.fields(value):
            out.update(tensors(getattr(value, f.name), f"{path}.{f.name}"))
    elif isinstance(value, dict):
        for k, v in value.items():
            out.update(tensors(v, f"{path}[{k}]"))
    elif isinstance(value, (tuple, list)):
        for i, v in enumerate(value):
            out.update(tensors(v, f"{path}[{i}]"))
    return out


def _run(method: str, fn, debug: bool):
    _, P, req = (ao_method if method in AO_METHODS else ssr_method)(method)
    g = room(16, 12).select(tuple(sorted(set(req) | {"mask", "color", "roughness"})))
    return fn(g, P(), generator=torch.Generator().manual_seed(3), debug=debug)


@pytest.mark.parametrize("method", [*AO_METHODS, *SSR_METHODS])
def test_every_pass_runs_autograd_free_with_the_same_bits_and_normal_tensors(method):
    fn = (ao_method if method in AO_METHODS else ssr_method)(method)[0]
    assert getattr(fn, "autograd_free", False), f"{method}: its pass function is not decorated with autograd_free"
    with compiling(False):
        for debug in (False, True):
            free, plain = _run(method, fn, debug), _run(method, fn.__wrapped__, debug)
            a, b = tensors(free), tensors(plain)
            assert a.keys() == b.keys() and a, method
            for k in a:
                assert not a[k].is_inference(), (method, k)
                assert a[k].dtype == b[k].dtype and torch.equal(torch.nan_to_num(a[k].double(), nan=7.0),
                                                                torch.nan_to_num(b[k].double(), nan=7.0)), (method, k)


@pytest.mark.parametrize("method", list(IMPLICIT_METHODS))
def test_every_implicit_caster_runs_autograd_free_and_still_takes_normals_by_autograd(method):
    fn, P = implicit_method(method)
    assert getattr(fn, "autograd_free", False), f"{method}: its pass function is not decorated with autograd_free"
    sc = load("thin_shell")
    cam, surf = sc.camera_at(0).with_resolution(16, 12), sc.surface(0)
    free, plain = fn(surf, cam, P()), fn.__wrapped__(surf, cam, P())
    a, b = tensors(free), tensors(plain)
    assert a.keys() == b.keys() and a
    for k in a:
        assert not a[k].is_inference(), (method, k)
        assert torch.equal(torch.nan_to_num(a[k].double(), nan=7.0), torch.nan_to_num(b[k].double(), nan=7.0)), k
    hit = free.hit[:, 0]
    assert bool(hit.any()) and bool((free.normal.norm(dim=1)[hit] > 0.99).all())     # ∇f found under the mode


def test_shade_hits_takes_the_gradient_inside_inference_mode():
    surf = load("thin_shell").surface(0)
    with torch.inference_mode():
        p = torch.tensor([[0.5, 0.4, 0.7], [0.3, -0.2, 0.9]], dtype=torch.float64)
        n, _ = shade_hits(surf, p)
    want, _ = shade_hits(surf, p.clone())
    assert torch.equal(n, want) and bool((n.norm(dim=1) > 0.99).all())


def test_a_result_can_enter_a_backward_pass_and_be_changed_in_place():
    ao = _run("ssao", ao_method("ssao")[0], False).ao
    w = torch.tensor(2.0, dtype=ao.dtype, requires_grad=True)
    (ao * w).sum().backward()                      # an inference tensor cannot be saved for backward
    assert float(w.grad) == pytest.approx(float(ao.sum()))
    ao.add_(1.0)                                   # nor changed in place outside inference mode


def test_inference_mode_is_used_only_where_no_gradient_can_flow():
    seen = []

    @autograd_free
    def probe(x, params=None):
        seen.append(torch.is_inference_mode_enabled())
        return {"y": x * 2.0}

    x, r = torch.ones(3), torch.tensor(1.0, requires_grad=True)
    assert not probe(x)["y"].is_inference()
    probe(x, params={"radius": r})                 # a parameter that wants a gradient
    with torch.no_grad():
        probe(x, params={"radius": r})             # ... but grad mode is off
    with compiling(True):
        probe(x)                                   # compiled kernels: no per-operation dispatch to save
    with torch.inference_mode():
        assert probe(x)["y"].is_inference()        # the caller's own mode, its tensors
    assert seen == [True, False, True, False, True]
    assert probe(torch.ones(3, requires_grad=True))["y"].requires_grad


def test_wants_grad_and_as_normal_walk_containers():
    @dataclasses.dataclass(frozen=True)
    class Params:
        radius: object = 1.0

    assert wants_grad(Params(torch.ones(1, requires_grad=True))) and not wants_grad(Params())
    assert wants_grad([{"a": (torch.ones(1, requires_grad=True),)}])
    assert not wants_grad([{"a": (torch.ones(1),)}], depth=3)
    with torch.inference_mode():
        made = Params(radius={"t": (torch.ones(2), 3)})
    keep = torch.ones(2)
    out = as_normal(made)
    assert not out.radius["t"][0].is_inference() and out.radius["t"][1] == 3
    assert as_normal({"k": keep})["k"] is keep     # normal tensors are not copied
