"""The DDA's set-up (SSR article §2.2 up to the loop; :mod:`ssbench.passes.ssr.dda_rays`): the pixel matrix against
the camera, the fitted stride, and the compiled set-up against the eager one, bit for bit."""
from __future__ import annotations

import dataclasses
import math

import pytest
import torch

from ssbench.gbuffer import GBuffer
from ssbench.passes.ssr.common import OUT_OF_STEPS
from ssbench.passes.ssr.dda import DDASSRParams, jitter_fractions, ssr_dda
from ssbench.passes.ssr.dda_rays import dda_rays, project_to_pixel_matrix
from tests.passes.ssr_scenes import room

F64 = torch.float64


def test_pixel_matrix_matches_camera():
    cam = room().camera
    p = torch.tensor([[0.3, -0.2, -1.0], [-2.0, 1.0, -7.5], [0.0, 0.0, -0.1]], dtype=F64)
    Hc = torch.cat([p, torch.ones(3, 1, dtype=F64)], 1) @ project_to_pixel_matrix(cam).T
    assert torch.allclose(Hc[:, :2] / Hc[:, 3:], cam.view_to_pixel(p, dim=-1), atol=1e-9)
    assert torch.allclose(Hc[:, 3], -p[:, 2])                             # H.w = −z, so k = 1/H.w > 0


@pytest.mark.parametrize("kw", [dict(), dict(jitter=1.0), dict(pixel_stride=3.0, pixel_stride_z_cutoff=2.0)])
def test_fit_stride_spans_the_segment(kw):
    g, zero = room(), torch.zeros(1, 1, 36, 48, dtype=F64)
    for K in (3, 8, 20):
        p = DDASSRParams(max_ray_distance=50.0, max_steps=K, fit_stride_to_steps=True, **kw)
        s, sel, P0, P1 = dda_rays(g, p, zero)
        fixed = dda_rays(g, DDASSRParams(max_ray_distance=50.0, max_steps=K, **kw), zero)[0].stride
        L = (P1 - P0).abs().amax(1)                                       # major-axis pixels, after clipping
        assert torch.equal(s.stride, torch.maximum(fixed, torch.ceil(L / K)))   # the cutoff only scales the floor
        assert bool((s.stride * K >= L).all())                         # K samples reach P1 …
        if "pixel_stride" not in kw:
            assert bool((s.stride <= L.clamp(min=1.0)).all())          # … and the first never jumps past it
        assert OUT_OF_STEPS not in ssr_dda(g, p).termination.unique().tolist()


def test_the_compiled_set_up_gives_the_eager_bits_and_follows_every_setting():
    """``ray_constants`` compiled: every :class:`DDARays` field and both segment ends equal to the eager set-up's,
    bit for bit, in float32 and float64, on a batch of two images, with jitter, a stride cut off by depth (also
    ``math.inf``), a fitted stride and short rays; settings changed after the first compilation are followed (a
    number that fills a tensor would keep its first value, ``ssbench.passes.compiled``); a second image size,
    other numbers and another camera (field of view, near plane: the pixel matrix is an input and the near plane a
    number) compile nothing new, and rays that leave the second viewport stop at its edges."""
    from torch._dynamo.utils import counters

    from ssbench.passes import compiled as C
    from ssbench.passes.ssr.dda_rays import ray_constants
    assert ray_constants.eager is not ray_constants

    def batch(w, h, dtype):
        g = room(w, h, dtype=dtype, slat=True)
        return GBuffer(g.camera, **{n: torch.cat([getattr(g, n), getattr(g, n).flip(-1)]) for n in g.channels})

    def compare(g, p):
        jitter = jitter_fractions(p, (2, 1, g.height, g.width), torch.Generator().manual_seed(5))
        with C.compiling(False):
            eager = dda_rays(g, p, jitter)
        with C.compiling(True):
            comp = dda_rays(g, p, jitter)
        assert eager[0].count > 100
        for f in dataclasses.fields(eager[0]):
            a, b = getattr(eager[0], f.name), getattr(comp[0], f.name)
            assert (a is None and b is None) or (a.dtype == b.dtype and torch.equal(a, b)), f.name
        for a, b in zip(eager[1:], comp[1:]):
            assert torch.equal(a, b)
        s = eager[0]                                     # rays that leave through the right or bottom edge
        return int((s.stop == torch.where(s.permute, float(g.height), float(g.width))).sum())

    settings = [DDASSRParams(), DDASSRParams(pixel_stride=4.0, jitter=1.0, pixel_stride_z_cutoff=3.0),
                DDASSRParams(max_ray_distance=2.5, pixel_stride=3.0, pixel_stride_z_cutoff=math.inf),
                DDASSRParams(max_ray_distance=0.7, pixel_stride=1.6, pixel_stride_z_cutoff=0.9, jitter=0.3),
                DDASSRParams(max_ray_distance=50.0, max_steps=8, fit_stride_to_steps=True, pixel_stride=2.0),
                DDASSRParams(max_ray_distance=50.0, max_steps=3, fit_stride_to_steps=True)]
    for dtype in (torch.float32, F64):
        for p in settings:
            compare(batch(40, 30, dtype), p)
    seconds, graphs = C.compile_seconds(), counters["stats"]["unique_graphs"]
    assert sum(compare(batch(36, 20, F64), p) for p in settings[1:3] + settings[-1:]) > 100   # a new viewport
    assert C.compile_seconds() == seconds                                        # no first call: nothing new
    g = batch(36, 20, F64)
    for camera in (dataclasses.replace(g.camera, fovy_deg=45.0), dataclasses.replace(g.camera, near=1.5)):
        compare(GBuffer(camera, **{n: getattr(g, n) for n in g.channels}), settings[0])   # near 1.5 clips more rays
    assert counters["stats"]["unique_graphs"] == graphs
