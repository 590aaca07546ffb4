"""ssbench.metrics.thickness: one physical thickness onto each anchor's knob, in closed form."""
import math

import pytest
import torch

from ssbench.camera import Camera
from ssbench.metrics import thickness as T

CAM = Camera.from_look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 60.0, 320, 240, 0.1, 100.0)


def test_kode80_is_the_slab_itself():
    assert T.kode80_pixel_z_size(0.25) == 0.25
    assert T.physical_thickness("kode80_pixel_z_size", 0.25, -40.0) == 0.25            # depth-independent


@pytest.mark.parametrize("z", [-0.5, -3.0, -80.0, 7.0])
def test_hdrp_relative_matches_its_base_depth_formula(z):
    """HDRP's Hi-Z base ``b = d·k_s + k_b`` (reversed-Z device depth) is exactly linear depth (1 + t)·|z|."""
    n, f, thick = 0.1, 100.0, 0.2
    t = T.hdrp_relative_thickness(thick, z)
    assert t == pytest.approx(thick / abs(z))
    depth_of = lambda lin: n * (f - lin) / (lin * (f - n))                     # noqa: E731  reversed-Z
    lin_of = lambda d: n * f / ((f - n) * d + n)                               # noqa: E731  HDRP LinearDepth
    d = depth_of(abs(z))
    k_s, k_b = 1.0 / (1.0 + t), -n / (f - n) * (t / (1.0 + t))
    assert lin_of(d * k_s + k_b) - abs(z) == pytest.approx(thick, rel=1e-9)
    assert T.physical_thickness("hdrp_relative", t, z) == pytest.approx(thick)


def test_hdrp_default_means_different_slabs_at_different_depths():
    assert [T.physical_thickness("hdrp_relative", 0.01, z) for z in (-1.0, -100.0)] == pytest.approx([0.01, 1.0])


def test_fidelityfx_band_off_axis_and_confidence():
    assert T.fidelityfx_depth_buffer_thickness(0.015) == 0.015
    # a corner pixel: the Euclidean distance along its eye ray for a depth step Δz is Δz·|P|/|z|
    px = (0.0, 0.0)
    p = CAM.uv_to_view(CAM.pixel_to_uv(torch.tensor([[0.0], [0.0]], dtype=torch.float64), dim=0),
                       torch.tensor([[-1.0]], dtype=torch.float64), dim=0)[:, 0]
    sec = float(p.norm())
    assert T.secant(CAM, px) == pytest.approx(sec, rel=1e-12) and sec > 1.3
    tau = T.fidelityfx_depth_buffer_thickness(0.1, CAM, px)
    assert tau == pytest.approx(0.1 * sec)
    assert T.fidelityfx_confidence(0.1 * sec, tau) == pytest.approx(0.0)        # band ends at depth T
    assert T.fidelityfx_confidence(0.0, tau) == 1.0
    assert T.physical_thickness("fidelityfx_band", tau, -4.0, CAM, pixel=px) == pytest.approx(0.1)
    assert T.secant(CAM, (160.0, 120.0)) == pytest.approx(1.0)


@pytest.mark.parametrize("c", [0.0, 0.1, 0.5, 0.9, 1.0])
def test_fidelityfx_band_inverts_the_confidence(c):
    d = T.fidelityfx_band(0.015, c)
    assert 0.0 <= d <= 0.015
    assert T.fidelityfx_confidence(d, 0.015) == pytest.approx(c, abs=1e-12)
    with pytest.raises(ValueError, match="confidence"):
        T.fidelityfx_band(0.015, 1.5)


def test_ppv2_trace_size():
    assert T.ppv2_trace_size(320, 240) == 128                    # closest pow2 of 240 is 256, halved
    assert T.ppv2_trace_size(640, 360, "fullsize") == 256        # 360: 256 (−104) beats 512 (+152)
    assert T.ppv2_trace_size(1920, 1080, "supersampled") == 2048
    assert T.ppv2_trace_size(512, 512, "full") == 512
    with pytest.raises(ValueError, match="resolution"):
        T.ppv2_trace_size(320, 240, "half")
    with pytest.raises(ValueError, match="width"):
        T.ppv2_trace_size(0, 240)


def test_ppv2_stride_is_the_projected_size_over_the_cutoff():
    s = T.ppv2_trace_size(CAM.width, CAM.height)
    F = CAM.focal
    fpx = 0.5 * s * min(F / CAM.aspect, F)                        # texels per view unit at depth 1
    knob = T.ppv2_thickness(0.1, -5.0, CAM)
    assert knob == pytest.approx(0.1 * fpx / 5.0 / (1 - 5.0 / 100))
    # with the origin far away the z-cutoff shrinks the stride, so the knob must grow
    assert T.ppv2_thickness(0.1, -5.0, CAM, origin_depth=-50.0) == pytest.approx(0.1 * fpx / 5.0 / 0.5)
    assert math.isinf(T.ppv2_thickness(0.1, -5.0, CAM, origin_depth=-100.0))   # stride 0: PPv2's cutoff bug
    assert T.physical_thickness("ppv2_stride", knob, -5.0, CAM) == pytest.approx(0.1)
    assert T.physical_thickness("ppv2_stride", 8.0, -5.0, CAM, origin_depth=-150.0) == 0.0
    with pytest.raises(ValueError, match="camera"):
        T.physical_thickness("ppv2_stride", 8.0, -5.0)


@pytest.mark.parametrize("knob", list(T.KNOBS))
def test_round_trip_every_knob(knob):
    for z in (-0.3, -2.0, -30.0):
        v = T.thickness_knobs(0.05, z, CAM, pixel=(10.0, 200.0))[knob]
        assert T.physical_thickness(knob, v, z, CAM, pixel=(10.0, 200.0)) == pytest.approx(0.05)


def test_table_and_markdown():
    rows = T.thickness_table(0.1, [-1.0, -10.0], CAM)
    assert [r["depth"] for r in rows] == [1.0, 10.0]
    assert rows[1]["hdrp_relative"] == pytest.approx(0.01) and rows[0]["kode80_pixel_z_size"] == 0.1
    assert rows[0]["ppv2_stride"] == pytest.approx(10 * rows[1]["ppv2_stride"] * (1 - 0.1) / (1 - 0.01))
    md = T.thickness_table_md(0.1, [1.0, 200.0], CAM)
    lines = md.splitlines()
    assert len(lines) == 4 and "pixelZSize" in lines[0] and "HDRP" in lines[0] and "PPv2" in lines[0]
    assert lines[-1].rstrip().endswith("∞ |")                                     # beyond PPv2's cutoff


def test_bad_arguments():
    with pytest.raises(ValueError, match="thickness"):
        T.kode80_pixel_z_size(0.0)
    with pytest.raises(ValueError, match="depth"):
        T.hdrp_relative_thickness(0.1, 0.0)
    with pytest.raises(ValueError, match="knob"):
        T.physical_thickness("godot", 0.2, -1.0)
    with pytest.raises(ValueError, match="thickness"):
        T.thickness_knobs(math.nan, -1.0)
