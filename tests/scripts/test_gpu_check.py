"""scripts/gpu_check.py, run against the CPU itself (the only device here): one row per AO and SSR method, the
two runs agree exactly, and a missing CUDA device is a one-line error with exit status 1."""
import runpy
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "gpu_check.py"


def _main():
    return runpy.run_path(str(SCRIPT))["main"]


@pytest.mark.slow
@pytest.mark.mitsuba
def test_cpu_against_itself_lists_every_pass_and_agrees(capsys):
    from ssbench.passes import AO_METHODS, SSR_METHODS
    assert _main()(["--device", "cpu", "--scene", "sphere_on_plane", "--size", "32x24", "--repeats", "1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = {ln.split()[1]: ln.split() for ln in lines[2:]}
    assert set(rows) == set(AO_METHODS) | set(SSR_METHODS)
    assert all(float(r[-1]) == 0.0 for r in rows.values()), rows               # max |diff| CPU vs CPU


def test_no_cuda_is_a_one_line_error(monkeypatch, capsys):
    import torch
    if torch.cuda.is_available():
        pytest.skip("a CUDA device is here: run `make gpu-check` instead")
    assert _main()(["--device", "cuda"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gpu_check: error: no CUDA device"), err
