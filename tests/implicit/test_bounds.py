"""check_bounds: a box the surface reaches is refused (closed forms, the issue's scene file), an honest one is
proved, and a proof is sound (f > 0 at random points of every face)."""
import pytest
import torch

from ssbench.implicit import catalog, load
from ssbench.implicit.bounds import FACES, BoundsError, check_bounds
from ssbench.implicit.expression import parse
from ssbench.implicit.schema import scene_from_file
from ssbench.implicit.surface import ImplicitObject
from ssbench.scenes.model import SceneError

F64 = torch.float64


def box(b):
    return ((-b, -b, -b), (b, b, b))


@pytest.mark.parametrize("r", [0.5, 0.9, 0.99])
def test_sphere_inside_its_box_is_proved(r):
    check_bounds(parse(f"length(p) - {r}"), box(1.0), "ball")


@pytest.mark.parametrize("r", [1.01, 1.2, 1.5, 3.0])
def test_sphere_larger_than_its_box_is_refused_with_a_witness_on_a_face(r):
    with pytest.raises(BoundsError, match="reaches the bounds face") as e:
        check_bounds(parse(f"length(p) - {r}"), box(1.0), "ball")
    face = dict((n, (a, s)) for n, a, s in FACES)[e.value.face]
    point = torch.tensor(e.value.point, dtype=F64)
    assert float(point[face[0]]) == (-1.0, 1.0)[face[1]]                  # the witness lies on that face
    assert float(point.norm()) - r <= 0                                    # and the surface reaches it there
    assert "'ball'" in str(e.value)


def test_tangent_sphere_is_not_proved():
    """f = 0 at the face centres: interval arithmetic cannot show f > 0, so the box is refused."""
    with pytest.raises(BoundsError, match="could not prove"):
        check_bounds(parse("length(p) - 1"), box(1.0), "ball")


def test_torus_cut_on_one_face_names_that_face():
    ring = "sqrt(square(sqrt(x^2 + z^2) - 1) + y^2) - 0.4"
    check_bounds(parse(ring), ((-1.45, -0.45, -1.45), (1.45, 0.45, 1.45)), "torus")
    with pytest.raises(BoundsError) as e:
        check_bounds(parse(ring), ((-1.45, -0.45, -1.45), (1.45, 0.2, 1.45)), "torus")
    assert e.value.face == "+y"


def test_object_construction_verifies_and_field_only_objects_may_opt_out():
    with pytest.raises(BoundsError):
        ImplicitObject("ball", parse("length(p) - 1.5"), bounds=box(1.0))
    o = ImplicitObject("plane", parse("y"), bounds=box(1.0), verify_bounds=False)
    assert o.f(torch.tensor([[0.0, 2.0, 0.0]], dtype=F64)).item() == 2.0


def test_the_issue_scene_file_is_refused_with_file_line_and_face(tmp_path):
    text = ("name: bad_bounds\n"
            "camera: {eye: [0, 1, 4], target: [0, 0, 0], up: [0, 1, 0], fovy: 45, width: 160, height: 120}\n"
            "lights: [{type: point, position: [3, 4, 3], intensity: [10, 10, 10]}]\n"
            "implicit:\n"
            "  - id: ball\n"
            "    f: \"length(p) - 1.5\"\n"
            "    bounds: [[-1, -1, -1], [1, 1, 1]]\n")
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(SceneError, match=r"bad\.yaml:7: implicit\[0\]\.bounds: object 'ball': the surface reaches"):
        scene_from_file(path)
    fixed = text.replace("[[-1, -1, -1], [1, 1, 1]]", "[[-1.6, -1.6, -1.6], [1.6, 1.6, 1.6]]")
    path.write_text(fixed)
    assert scene_from_file(path).objects.objects[0].id == "ball"


@pytest.mark.parametrize("name", catalog.names())
def test_catalog_boxes_are_proved_and_the_proof_is_sound(name):
    """Every catalog object passes, and f > 0 at 20,000 random points of each face of its box."""
    gen = torch.Generator().manual_seed(3)
    for o in load(name).objects.objects:
        check_bounds(o.expression, o.bounds, o.id)
        lo, hi = (torch.tensor(b, dtype=F64) for b in o.bounds)
        for _, axis, side in FACES:
            p = lo + torch.rand(20000, 3, dtype=F64, generator=gen) * (hi - lo)
            p[:, axis] = (lo, hi)[side][axis]
            assert bool((o.expression(p) > 0).all()), (name, o.id, axis, side)


def test_random_sphere_boxes_agree_with_the_closed_form():
    """Sphere of radius r at centre c in the unit box: honest iff the nearest face is farther than r."""
    gen = torch.Generator().manual_seed(5)
    for _ in range(40):
        c = (torch.rand(3, dtype=F64, generator=gen) - 0.5) * 0.8
        r = float(torch.rand((), dtype=F64, generator=gen)) * 0.9 + 0.05
        gap = float((1 - c.abs()).min()) - r                              # distance to the nearest face - r
        if abs(gap) < 0.02:
            continue                                                       # near-tangent: either is fine
        expr = parse(f"length(p - vec3({c[0]:.17g}, {c[1]:.17g}, {c[2]:.17g})) - {r:.17g}")
        if gap > 0:
            check_bounds(expr, box(1.0), "s")
        else:
            with pytest.raises(BoundsError):
                check_bounds(expr, box(1.0), "s")
