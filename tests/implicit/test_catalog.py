"""The built-in implicit scenes: they validate, their bounds and declared λ are honest, the interval
enclosure is sound on each, Dr.Jit agrees with torch, and the hard cases are as hard as described."""
import math

import pytest
import torch

from ssbench.implicit import catalog
from ssbench.implicit.scene import ImplicitScene, load
from ssbench.passes.implicit.common import camera_rays

NAMES = catalog.names()
F64 = torch.float64


def _poses(scene):
    """(frame, surface) at the rest pose and, for animations, at every segment boundary and the last frame."""
    frames = {0, scene.frames - 1}
    if scene.animation:
        frames |= {k for s in scene.animation.segments for k in (s.start, s.stop)}
    return [(k, scene.surface(k)) for k in sorted(frames)]


def test_catalog_has_the_issue_cases_with_one_line_descriptions():
    for n in ("sphere", "torus", "thin_shell", "thin_plate", "gyroid_sheet", "tangent_sphere", "double_root",
              "badly_scaled", "barth_sextic", "displaced_torus", "animated"):
        assert n in NAMES
    desc = catalog.describe()
    assert list(desc) == NAMES
    for text in desc.values():
        assert text.strip() == text and "\n" not in text and len(text) < 200


@pytest.mark.parametrize("name", NAMES)
def test_scene_loads_with_a_small_camera_and_a_point_light(name):
    s = load(name)
    assert isinstance(s, ImplicitScene) and s.name == name and s.source == f"<catalog:{name}>"
    cam = s.camera
    assert (cam.width, cam.height, cam.near) == (160, 120, 0.1) and 8 <= cam.far <= 15
    assert any(light.type == "point" for light in s.lights)
    assert len(s.materials) == len(s.objects.objects)
    assert s.content_hash() == catalog.get(name).content_hash()
    for k, surf in _poses(s):                 # the whole bounded region lies within far, in front of the eye
        c = s.camera_at(k)
        lo, hi = surf.bounds
        corners = torch.tensor([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
                               dtype=F64)
        assert float((corners - torch.tensor(c.eye, dtype=F64)).norm(dim=-1).max()) < c.far
        centre = c.world_to_view(((torch.tensor(lo) + torch.tensor(hi)) / 2).to(F64).view(1, 3), dim=-1)
        assert float(centre[0, 2]) < -c.near


def test_scenes_differ():
    assert len({load(n).content_hash() for n in NAMES}) == len(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_bounds_are_honest(name):
    """f > 0 at random points outside the declared world bounds (shells up to 3x the box, and far away)."""
    gen = torch.Generator().manual_seed(7)
    for _, surf in _poses(load(name)):
        lo, hi = (torch.tensor(b, dtype=F64) for b in surf.bounds)
        c, h = (lo + hi) / 2, (hi - lo) / 2
        u = torch.rand(40000, 3, dtype=F64, generator=gen) * 2 - 1
        axis = torch.randint(0, 3, (40000,), generator=gen)       # push one coordinate past the box face
        scale = 1 + torch.rand(40000, dtype=F64, generator=gen) ** 2 * 2
        u[torch.arange(40000), axis] = torch.sign(u[torch.arange(40000), axis]) * scale
        p = torch.cat([c + u * h, torch.randn(2000, 3, dtype=F64, generator=gen) * 50])
        outside = ((p < lo) | (p > hi)).any(-1)
        assert outside.float().mean() > 0.99
        assert bool((surf.f(p[outside]) > 0).all()), name


@pytest.mark.parametrize("name", NAMES)
def test_interval_encloses_f_on_random_boxes(name):
    gen = torch.Generator().manual_seed(11)
    surf = load(name).surface(20)
    lo, hi = (torch.tensor(b, dtype=F64) for b in surf.bounds)
    c, h = (lo + hi) / 2, (hi - lo) / 2 * 1.3
    n, m = 3000, 24
    a = c + (torch.rand(n, 3, dtype=F64, generator=gen) * 2 - 1) * h
    w = torch.rand(n, 3, dtype=F64, generator=gen) ** 4 * h * 2       # from tiny to box-sized boxes
    b = a + w
    flo, fhi = surf.interval(a, b)
    assert flo.dtype == F64 and flo.shape == (n,)
    pts = a[:, None] + torch.rand(n, m, 3, dtype=F64, generator=gen) * w[:, None]
    v = surf.f(pts)
    known = ~(flo.isnan() | fhi.isnan())
    assert known.float().mean() > 0.9, name
    inside = (flo[:, None] <= v) & (v <= fhi[:, None])
    assert bool(inside[known].all()), name


@pytest.mark.parametrize("name", NAMES)
def test_declared_lipschitz_bound(name):
    """λ bounds the observed |∇f| everywhere it is declared, except in displaced_torus (wrong on purpose)."""
    surf = load(name).surface(0)
    lam = surf.lipschitz
    lo, hi = (torch.tensor(b, dtype=F64) for b in surf.bounds)
    p = lo + torch.rand(50000, 3, dtype=F64, generator=torch.Generator().manual_seed(3)) * (hi - lo) * 1.2
    observed = float(surf.f_and_grad(p)[1].norm(dim=-1).max())
    if name == "displaced_torus":
        assert lam == 1.0 and 1.5 < observed <= 1.9 * (1 + 1e-9)   # |∇ bumps| <= 0.045·20 = 0.9
    elif lam is not None:
        assert observed <= lam * (1 + 1e-9), (name, observed)
    if name in ("double_root", "badly_scaled", "barth_sextic"):
        assert lam is None


def test_hard_cases_are_as_described():
    shell = catalog.as_dict("thin_shell")
    h = shell["camera"]["far"] / catalog.DESIGN_STEPS
    assert 2 * shell["params"]["w"] / h < 0.1                      # the wall is far thinner than a step
    p = torch.randn(20000, 3, dtype=F64) * 1.2
    assert bool((load("double_root").objects.f(p) >= 0).all())    # never negative: no sign change
    grad = load("badly_scaled").objects.f_and_grad(torch.tensor([[1.0, 0, 0]], dtype=F64))[1]
    assert float(grad.norm()) == pytest.approx(2000.0)
    # tangent_sphere: many pixel rays graze (chord < 0.4 << the unit radius) — analytic chord per pixel
    s = load("tangent_sphere")
    r = camera_rays(s.camera, dtype=F64)
    o, d = r.origin[0].reshape(3, -1).T, r.direction[0].reshape(3, -1).T
    miss = (o - ((o * d).sum(-1, keepdim=True)) * d).norm(dim=-1)  # distance of the ray line from the centre
    chord = 2 * torch.sqrt((1 - miss ** 2).clamp(min=0))
    assert int(((miss < 1) & (chord < 0.4)).sum()) >= 500
    anim = load("animated")
    assert anim.frames == 60 and anim.surface(0).f(torch.tensor([[-1.5, 0, 0]], dtype=F64)) < 0
    assert anim.surface(59).f(torch.tensor([[1.5, 0, 0]], dtype=F64)) < 0
    assert anim.camera_at(39) == anim.camera and anim.camera_at(60).eye == pytest.approx((1.0, 0.8, 4.6))


def test_torus_reference_geometry():
    """The torus is R = 1, r = 0.35 about y: f = 0 on the tube circle points, closed-form distance elsewhere."""
    surf = load("torus").objects
    phi = torch.rand(100, dtype=F64) * 2 * math.pi
    theta = torch.rand(100, dtype=F64) * 2 * math.pi
    rho = 1 + 0.35 * torch.cos(theta)
    p = torch.stack([rho * torch.cos(phi), 0.35 * torch.sin(theta), rho * torch.sin(phi)], -1)
    assert torch.allclose(surf.f(p), torch.zeros(100, dtype=F64), atol=1e-12)


def test_unknown_names():
    with pytest.raises(KeyError, match="name_or_path"):
        catalog.get("nope")
    with pytest.raises(KeyError, match="name_or_path") as e:
        load("nope")
    assert "torus" in str(e.value)


@pytest.mark.mitsuba
@pytest.mark.parametrize("name", NAMES)
def test_drjit_f_equals_torch_f(name):
    from ssbench.reference import backend
    backend.mitsuba()
    if not backend.is_jit():
        pytest.skip("scalar Mitsuba variant: no vectorised Dr.Jit arrays")
    import drjit as dr
    surf = load(name).surface(20)
    lo, hi = (torch.tensor(b, dtype=F64) for b in surf.bounds)
    p = lo + torch.rand(2000, 3, dtype=F64, generator=torch.Generator().manual_seed(5)) * (hi - lo)
    got = torch.tensor(list(surf.drjit_f(*(dr.llvm.Float64(p[:, i].tolist()) for i in range(3)))), dtype=F64)
    want = surf.f(p)
    assert torch.allclose(got, want, rtol=1e-12, atol=1e-12 * float(want.abs().max()))
