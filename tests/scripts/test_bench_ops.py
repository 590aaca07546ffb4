"""benchmarks/bench_ops.py: one row per operation with a finite time and ratio, and bad arguments as one argparse
error naming the option (no timing claims: the numbers are the benchmark's, not the test's)."""
import math
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_ops.py"


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=300)


def test_every_operation_gets_a_row_with_finite_numbers():
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import torch
        from bench_ops import operations
        names = list(operations(16 * 8, torch.Generator().manual_seed(0)))
    finally:
        sys.path.remove(str(SCRIPT.parent))
    r = run("--size", "16x8", "--rounds", "3", "--block-ms", "0.05")
    assert r.returncode == 0, r.stderr
    rows = {line[:38].strip(): line[38:].replace("±", " ").split() for line in r.stdout.splitlines()[2:]}
    assert list(rows) == names
    for name, (ns, ratio, iqr) in rows.items():
        assert math.isfinite(float(ns)) and float(ns) > 0 and float(ratio) > 0, name


@pytest.mark.parametrize("args,option", [(["--size", "64"], "--size"), (["--size", "0x8"], "--size"),
                                         (["--rounds", "2"], "--rounds"), (["--block-ms", "0"], "--block-ms")])
def test_bad_arguments_are_one_error_naming_the_option(args, option):
    r = run(*args)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip().splitlines()[-1].startswith(f"bench_ops.py: error: {option}: "), r.stderr
