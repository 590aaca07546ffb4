"""benchmarks/bench_passes.py checks its timing arguments before it renders any G-buffer: a bad one is one
argparse error naming the option (exit status 2), not a failure inside every configuration's subprocess."""
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_passes.py"


@pytest.mark.parametrize("args,option", [(["--rounds", "1"], "--rounds"), (["--min-run-time", "0"], "--min-run-time"),
                                         (["--min-run-time", "nan"], "--min-run-time")])
def test_bad_timing_arguments_fail_before_any_work(args, option):
    r = subprocess.run([sys.executable, str(SCRIPT), "--sizes", "8x6", *args], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip().splitlines()[-1].startswith(f"bench_passes.py: error: {option}: must be"), r.stderr
