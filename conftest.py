"""Test-wide settings: a private reference cache, headless matplotlib, one torch thread per xdist worker, doctest
names."""
import os
import shutil
import tempfile

os.environ.setdefault("MPLBACKEND", "Agg")
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
_OWN_CACHE = None                                         # the folder this process made, removed when the run ends
if "SSBENCH_TEST_KEEP_CACHE" not in os.environ:
    # every test run renders afresh into a folder of its own, which its xdist workers (spawned with the controller's
    # environment) and their subprocesses share: cache files are written whole (a temporary file renamed into place)
    run_cache = os.environ.get("SSBENCH_TEST_RUN_CACHE") if _WORKER else None
    if not run_cache:
        run_cache = _OWN_CACHE = os.environ["SSBENCH_TEST_RUN_CACHE"] = tempfile.mkdtemp(prefix="ssbench-test-cache-")
    os.environ["SSBENCH_CACHE_DIR"] = run_cache

import pytest  # noqa: E402
import torch  # noqa: E402

if _WORKER:
    # `make test` runs one worker per core: a second torch (OpenMP) thread in each would contend for the cores
    # (two threads per process measured 7-11x slower on a loaded 2-core VM)
    torch.set_num_threads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")        # and in the processes the tests start (CLI, notebook kernels)


@pytest.fixture(autouse=True)
def _doctest_names(doctest_namespace):
    doctest_namespace["torch"] = torch


def pytest_unconfigure(config):
    """The run's cache goes with it (each run left ~110 MB of renders in the temporary folder), once every worker
    has finished: only the process that made the folder removes it."""
    if _OWN_CACHE:
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)
