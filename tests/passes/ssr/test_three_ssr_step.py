"""The three.js SSR march's step kernel (``ssbench.passes.ssr.three_ssr_step``): its unprojection against the
camera, and its compiled form against eager. (The whole pass equals the shader itself: tests/peer.)"""
from __future__ import annotations

import dataclasses

import torch

from ssbench.camera import Camera
from ssbench.passes.ssr.common import HIT
from ssbench.passes.ssr.three_ssr import ThreeSSRParams, ssr_three
from ssbench.passes.ssr.three_ssr_step import march_steps, unproject
from tests.passes.ssr_scenes import room


def test_unproject_inverts_the_projection():
    """``getViewPosition`` of a view point's own ``(uv, depth, clipW)`` gives the point back (float64)."""
    cam = Camera.from_look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 50.0, 64, 48, 0.1, 100.0)
    g = torch.Generator().manual_seed(2)
    p = torch.stack([torch.rand(500, generator=g, dtype=torch.float64) * 4 - 2,
                     torch.rand(500, generator=g, dtype=torch.float64) * 3 - 1.5,
                     -torch.rand(500, generator=g, dtype=torch.float64) * 50 - 0.2], 1)     # (N, 3) in the frustum
    clip = torch.cat([p, torch.ones(500, 1, dtype=torch.float64)], 1) @ cam.projection_matrix(torch.float64).T
    ndc = clip[:, :3] / clip[:, 3:]
    back = unproject(cam.inverse_projection_matrix(torch.float64), ndc[:, 0] * 0.5 + 0.5, ndc[:, 1] * 0.5 + 0.5,
                     ndc[:, 2] * 0.5 + 0.5, clip[:, 3])
    assert torch.allclose(back, p, rtol=1e-12, atol=1e-12)


def test_the_compiled_step_gives_the_eager_outputs_at_two_sizes_without_recompiling(monkeypatch):
    """The steps through ``torch.compile`` (size-dynamic, several per call, the hit's verdict judged for every ray)
    give eager's outputs, with the thickness test and with ``infinite_thick``; a second image size reuses the
    compiled steps, and so does another thickness (a number would specialise them). Three steps per call here
    (eight by default: the same kernel, compiled faster), so the last call of a 19-step march masks two. Inductor
    computes ``pointToLineDistance``'s cross product without the FMA ATen's kernel may use, an ulp apart in a
    quarter of the rays, so a ray exactly on the thickness bound could end differently: allowed in one pixel in 200
    (none here, nor on 192 outputs of six G-buffers and four settings, built-in scenes included, measured)."""
    from ssbench.passes import compiled as C
    from tests.passes.compiled_check import check_compiled_at_two_sizes
    monkeypatch.setattr(C, "STEPS_PER_CALL", 3)
    settings = [ThreeSSRParams(max_distance=30.0, thickness=0.05),
                ThreeSSRParams(max_distance=30.0, infinite_thick=True),
                ThreeSSRParams(max_distance=8.0, thickness=0.3, fresnel=False, max_step=20)]

    def compare(eager, comp):
        assert bool((eager.termination != HIT).any())
        same = (eager.termination == comp.termination)[:, 0]
        assert float((~same).float().mean()) <= 1 / 200
        for f in dataclasses.fields(eager):
            if f.name != "debug":
                a, b = getattr(eager, f.name), getattr(comp, f.name)
                assert torch.equal(a.movedim(1, -1)[same], b.movedim(1, -1)[same]), f.name

    from torch._dynamo.utils import counters
    before = counters["stats"]["unique_graphs"]
    check_compiled_at_two_sizes(lambda w, h: room(w, h, torch.float32, slat=True),
                                lambda g, p: ssr_three(g, p, debug=True), settings, ((32, 24), (40, 30)), compare)
    assert march_steps.eager is not march_steps
    graphs = counters["stats"]["unique_graphs"]
    assert graphs - before == 2                 # one per infinite_thick: not again for the first call's sizes
    with C.compiling(True):                              # another thickness and budget: the same compiled steps
        ssr_three(room(40, 30, torch.float32, slat=True),
                  ThreeSSRParams(max_distance=30.0, thickness=0.07, max_step=14))
    assert counters["stats"]["unique_graphs"] == graphs
