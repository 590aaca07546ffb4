"""The suite's own settings (``conftest.py`` at the repository root), run as they run in ``make test``: a fresh
reference cache per run that its xdist workers share, one torch thread per worker, and no cache left behind."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PROBE = '''
import json, os, torch

def test_probe(tmp_path_factory):
    out = os.environ["PROBE_OUT"]
    me = os.environ.get("PYTEST_XDIST_WORKER", "main")
    cache = os.environ["SSBENCH_CACHE_DIR"]
    with open(os.path.join(cache, me + ".txt"), "w") as f:       # something to clean up
        f.write("x")
    with open(os.path.join(out, me + ".json"), "w") as f:
        json.dump({"cache": cache, "threads": torch.get_num_threads(), "omp": os.environ.get("OMP_NUM_THREADS")}, f)

test_probe_again = test_probe
'''


def run_probe(tmp_path, *args) -> list:
    (tmp_path / "test_probe.py").write_text(PROBE)
    out = tmp_path / "out"
    out.mkdir()
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PYTEST_", "SSBENCH_TEST_", "SSBENCH_CACHE")) and k != "OMP_NUM_THREADS"}
    env.update(PROBE_OUT=str(out), PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "conftest",
                        "--rootdir", str(tmp_path), *args, str(tmp_path / "test_probe.py")],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    return [json.loads(p.read_text()) for p in sorted(out.glob("*.json"))]


@pytest.mark.slow
def test_one_process_renders_into_a_fresh_cache_and_removes_it(tmp_path):
    (seen,) = run_probe(tmp_path, "-p", "no:xdist")
    assert Path(seen["cache"]).name.startswith("ssbench-test-cache-")
    assert not Path(seen["cache"]).exists()


@pytest.mark.slow
def test_workers_share_one_cache_and_run_one_thread(tmp_path):
    seen = run_probe(tmp_path, "-n", "2")
    assert len(seen) == 2 and seen[0]["cache"] == seen[1]["cache"]
    assert all(s["threads"] == 1 and s["omp"] == "1" for s in seen)
    assert not Path(seen[0]["cache"]).exists()
