"""The depth buffer's height field: the lookup inside test against an independent float64 ray–triangle test and
against the same question traced through the mesh by Embree."""
import hashlib

import pytest
import torch

from ssbench.reference import ao_volume, backend, gbuffer, heightfield

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
CH = ["position", "normal", "mask", "view_z"]


def _points(g, n: int, radius: float, seed: int) -> torch.Tensor:
    """``n`` view-space points in balls of ``radius`` around foreground pixels, float32 ``(n, 3)``: half around
    any, half around those next to a depth jump (where the height field's triangles are almost parallel to the
    line of sight, the hard case)."""
    gen = torch.Generator().manual_seed(seed)
    z = g.position[0, 2]
    jump = torch.zeros_like(g.mask[0, 0])
    jump[:, :-1] |= (z[:, 1:] - z[:, :-1]).abs() > 0.25
    jump[:-1] |= (z[1:] - z[:-1]).abs() > 0.25
    pos = g.position[0].reshape(3, -1).T.double()
    fg, edge = pos[g.mask.reshape(-1)], pos[(g.mask[0, 0] & jump).reshape(-1)]
    centre = torch.cat([fg[torch.randint(len(fg), (n // 2,), generator=gen)],
                        edge[torch.randint(len(edge), (n - n // 2,), generator=gen)]])
    d = torch.randn(n, 3, generator=gen, dtype=torch.float64)
    r = torch.rand(n, 1, generator=gen, dtype=torch.float64) ** (1 / 3) * radius
    return (centre + d / d.norm(dim=1, keepdim=True) * r).float()


def _behind_float64(g, s: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Independent answer: the line from the eye through ``s`` tested against the 18 triangles of the 3×3 cells
    around ``s``'s pixel with signed volumes (no screen-space split), in float64; returns (inside, steep) where
    steep marks points under a triangle that spans a depth jump (vertices > 0.25 apart in z)."""
    pos = g.position[0].double()
    H, W = g.height, g.width
    s = s.double()
    px = g.camera.view_to_pixel(s, dim=-1) - 0.5
    ci, cj = px[:, 0].floor().long(), px[:, 1].floor().long()
    inside = torch.zeros(len(s), dtype=torch.bool)
    steep = torch.zeros(len(s), dtype=torch.bool)
    found = torch.zeros(len(s), dtype=torch.bool)
    front = s[:, 2] < 0
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            i, j = ci + di, cj + dj
            ok = front & (i >= 0) & (j >= 0) & (i <= W - 2) & (j <= H - 2)
            i, j = i.clamp(0, W - 2), j.clamp(0, H - 2)
            a, b = pos[:, j, i].T, pos[:, j, i + 1].T
            c, d = pos[:, j + 1, i].T, pos[:, j + 1, i + 1].T
            for v0, v1, v2 in ((a, c, b), (b, c, d)):
                e = [torch.linalg.det(torch.stack([p, q, s], 1)) for p, q in ((v0, v1), (v1, v2), (v2, v0))]
                through = ((e[0] >= 0) & (e[1] >= 0) & (e[2] >= 0)) | ((e[0] <= 0) & (e[1] <= 0) & (e[2] <= 0))
                take = ok & through & ~found
                n = torch.linalg.cross(v1 - v0, v2 - v0)
                n_s, n_v0 = (n * s).sum(1), (n * v0).sum(1)
                inside |= take & (n_s < 0) & (n_s <= n_v0) & (n_v0 <= 0)
                z = torch.stack([v0[:, 2], v1[:, 2], v2[:, 2]], 1)
                steep |= take & (z.max(1).values - z.min(1).values > 0.25)
                found |= take
    return inside, steep


def _lookup(g, s: torch.Tensor, traced: bool = False) -> torch.Tensor:
    mi = backend.mitsuba()
    import drjit as dr
    digest = hashlib.sha256(g.position.numpy().tobytes() + g.mask.numpy().tobytes()).hexdigest()
    hf = heightfield.load(mi, dr, g, digest)
    p = mi.Point3f(*(mi.Float(s[:, k].contiguous()) for k in range(3)))
    on = dr.ones(mi.Bool, len(s))
    if traced:
        return torch.from_numpy(ao_volume.inside(mi, dr, hf.scene, mi.Point3f(0.0), p, on).numpy().copy())
    return torch.from_numpy(heightfield.behind(mi, dr, hf, p, on).numpy().copy())


@pytest.mark.parametrize("scene", ["stairs", "furnished_room"])
def test_lookup_equals_an_independent_float64_line_triangle_test(scene):
    g = gbuffer(scene, 320, 240, channels=CH)
    s = _points(g, 200_000, 0.5, 0)
    got = _lookup(g, s)
    want, steep = _behind_float64(g, s)
    assert 0.1 < want.float().mean() < 0.9                        # both answers are exercised
    assert steep.sum() > 5000                                     # and the hard case: triangles across a jump
    assert (got != want).sum() == 0


def test_lookup_agrees_with_the_segment_traced_through_the_mesh():
    """The same question asked of Embree (``ao_volume.inside`` on the mesh): it differs only on points close
    to a triangle that spans a depth jump, where the long segment's float32 test is the one that slips."""
    g = gbuffer("stairs", 96, 72, channels=CH)
    s = _points(g, 200_000, 0.5, 1)
    got, traced = _lookup(g, s), _lookup(g, s, traced=True)
    _, steep = _behind_float64(g, s)
    differ = got != traced
    assert differ.float().mean() < 1e-3
    assert bool(steep[differ].all())


def test_points_behind_the_eye_or_off_screen_are_outside():
    g = gbuffer("stairs", 32, 24, channels=CH)
    p = g.position[0, :, 12, 16].float()
    s = torch.stack([p * 1.5,                                     # behind the surface on the same line: inside
                     torch.tensor([0.0, 0.0, 1.0]),               # behind the eye
                     torch.tensor([0.0, 0.0, 0.0]),               # at the eye
                     p * 1.5 + torch.tensor([1e3, 0.0, 0.0]),     # far off the image's right edge
                     p * 0.5])                                     # in front of the surface
    assert _lookup(g, s).tolist() == [True, False, False, False, False]
