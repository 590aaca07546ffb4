"""The Dr.Jit march against the torch march: the same hits, certificates and roots on every catalog scene.

The two engines share the method, not the code (lock-step torch lanes with exact directed rounding; one Dr.Jit
kernel with one segment per ray per turn and widened bounds), so agreement is an independent check of both.
Leaves may differ at the ``tolerance`` level; roots are bisected to ``epsilon``, so certified hits must agree
to ~1e-10. Closed-form checks of both engines are in ``test_implicit.py`` (parametrised over the engines).
"""
import pytest
import torch


def _max(x: torch.Tensor) -> float:
    return float(x.max()) if x.numel() else 0.0

from ssbench.implicit.catalog import names
from ssbench.implicit.scene import load
from ssbench.reference.implicit import engine_of, implicit


@pytest.fixture(scope="module", autouse=True)
def _jit():
    from ssbench.reference import backend
    if not backend.is_jit():
        pytest.skip("needs a vectorised Mitsuba variant (libllvm19)")


def _pair(name, w=32, h=24):
    sc = load(name)
    cam = sc.camera_at(0).with_resolution(w, h)
    surf = sc.surface(0)
    kw = dict(exits=True, use_cache=False)
    return implicit(surf, cam, engine="torch", **kw), implicit(surf, cam, engine="drjit", **kw)


@pytest.mark.parametrize("name", names())
def test_engines_agree_on_the_catalog(name):
    a, b = _pair(name)
    assert a.engine == "torch" and b.engine == "drjit"
    assert not bool(a.unfinished.any()) and not bool(b.unfinished.any())
    assert torch.equal(a.certified, b.certified), f"{name}: {int((a.certified != b.certified).sum())} certificates"
    sure = a.certified & b.certified
    assert torch.equal(a.hit[sure], b.hit[sure])
    both = sure & a.hit
    scale = a.t[both].abs().clamp(min=1.0)
    assert _max((a.t[both] - b.t[both]).abs() / scale) < 1e-10
    assert _max((a.t_exit[both] - b.t_exit[both]).abs() / scale) < 1e-8
    assert torch.equal(torch.isfinite(a.ambiguous_t), torch.isfinite(b.ambiguous_t))
    amb = torch.isfinite(a.ambiguous_t)
    assert _max((a.ambiguous_t[amb] - b.ambiguous_t[amb]).abs()) < 1e-5              # a run's first leaf
    assert torch.equal(a.object_index[both], b.object_index[both])
    assert _max((a.normal - b.normal).abs().amax(1)[both[:, 0]]) < 1e-6


def test_auto_picks_drjit_for_parsed_surfaces_and_torch_otherwise():
    surf = load("torus").surface(0)
    assert engine_of(surf) == "drjit" and engine_of(surf, "torch") == "torch"
    pow_scene = {"name": "p", "camera": {"eye": [0, 0, 4], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 40,
                                          "width": 8, "height": 6, "near": 0.1, "far": 10},
                 "implicit": [{"id": "a", "f": "length(p) ^ 1.5 - 1", "bounds": [[-1.2] * 3, [1.2] * 3]}]}
    psurf = load(pow_scene).surface(0)
    assert engine_of(psurf) == "torch"                                  # the real power stays with torch
    with pytest.raises(ValueError, match="engine"):
        engine_of(psurf, "drjit")
    with pytest.raises(ValueError, match="engine"):
        implicit(surf, load("torus").camera_at(0), engine="cuda")


def test_engines_agree_through_rotation_scale_and_translation():
    """The Dr.Jit box transform (``p − T``, ``Rᵀ·``, ``/ s``, widened) against the torch one, on a union."""
    scene = {"name": "moved", "camera": {"eye": [0.5, 1.5, 5], "target": [0, 0, 0], "up": [0, 1, 0], "fovy": 40,
                                          "width": 40, "height": 30, "near": 0.1, "far": 12},
             "implicit": [{"id": "a", "f": "length(vec3(length(vec3(x, 0, z)) - 1, y, 0)) - 0.25",
                           "bounds": [[-1.3, -0.3, -1.3], [1.3, 0.3, 1.3]], "rotate": [30, 20, 10], "scale": 0.7,
                           "translate": [0.3, -0.2, 0.1]},
                          {"id": "b", "f": "abs(length(p) - 0.5) - 0.02", "bounds": [[-0.6] * 3, [0.6] * 3],
                           "scale": 1.5, "translate": [-0.4, 0.5, -1]}]}
    sc = load(scene)
    surf, cam = sc.surface(0), sc.camera_at(0)
    a = implicit(surf, cam, engine="torch", exits=True, use_cache=False)
    b = implicit(surf, cam, engine="drjit", exits=True, use_cache=False)
    assert torch.equal(a.certified, b.certified) and torch.equal(a.hit, b.hit) and int(a.hit.sum()) > 100
    both = a.hit & a.certified
    assert _max((a.t[both] - b.t[both]).abs()) < 1e-10 and torch.equal(a.object_index, b.object_index)
    assert set(a.object_index[a.hit].tolist()) == {0, 1}


def _ball(eye, *, near=0.1, far=12.0, scale=1.0, translate=(0.0, 0.0, 0.0), target=None):
    return load({"name": "ball", "camera": {"eye": list(eye), "target": list(target or translate), "up": [0, 1, 0],
                                            "fovy": 40, "width": 24, "height": 18, "near": near, "far": far},
                 "implicit": [{"id": "a", "f": "length(p) - 1", "bounds": [[-1.1] * 3, [1.1] * 3], "scale": scale,
                               "translate": list(translate)}]})


@pytest.mark.parametrize("case", [
    dict(eye=(0, 0, 5e-5), near=1e-7, far=1e-3, scale=1e-5),                           # a 10 µm ball
    dict(eye=(1e6, 0, 1e6 + 5), translate=(1e6, 0, 1e6)),                               # a million units out
    dict(eye=(0, 0, 5), near=1e-9, far=1e12),                                           # extreme near/far
    dict(eye=(0, 0, 5e8), near=1.0, far=1e9, scale=1e8),                                # a 10⁸ ball
    dict(eye=(1.0, 0, 5), target=(1.0, 0, 0)),                                          # grazing silhouettes
], ids=["tiny", "far_away", "near_far", "huge", "grazing"])
def test_engines_agree_at_extreme_scales(case):
    sc = _ball(**case)
    surf, cam = sc.surface(0), sc.camera_at(0)
    a = implicit(surf, cam, engine="torch", exits=True, use_cache=False)
    b = implicit(surf, cam, engine="drjit", exits=True, use_cache=False)
    assert torch.equal(a.hit, b.hit) and torch.equal(a.certified, b.certified) and int(a.hit.sum()) > 20
    assert bool(b.certified.all()) and not bool(b.unfinished.any()) and not bool(b.t.isnan().any())
    assert _max((a.t - b.t).abs()[a.hit] / a.t.abs()[a.hit].clamp(min=1.0)) < 1e-10
