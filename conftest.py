"""Test-wide settings: a private reference cache, headless matplotlib, doctest names."""
import os
import tempfile

os.environ.setdefault("MPLBACKEND", "Agg")
if "SSBENCH_TEST_KEEP_CACHE" not in os.environ:
    # every test session renders afresh (and subprocesses inherit this directory)
    os.environ["SSBENCH_CACHE_DIR"] = tempfile.mkdtemp(prefix="ssbench-test-cache-")

import pytest  # noqa: E402
import torch  # noqa: E402


@pytest.fixture(autouse=True)
def _doctest_names(doctest_namespace):
    doctest_namespace["torch"] = torch
