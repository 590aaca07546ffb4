"""Executor selection and the local executor's contract (the Dask one: test_kill_resume_dask.py)."""
import pytest

from ssbench.bench.executors import DaskExecutor, LocalExecutor, make_executor


def _half(x):
    if x == 3:
        raise ValueError("three")
    return x / 2


def test_local_executor_yields_results_and_exceptions_in_order():
    with LocalExecutor() as ex:
        out = list(ex.imap_unordered(_half, [2, 3, 4]))
    assert [(i, r) for i, r, e in out] == [(2, 1.0), (3, None), (4, 2.0)]
    assert isinstance(out[1][2], ValueError) and out[0][2] is None


def test_make_executor_checks_its_arguments():
    assert isinstance(make_executor("local"), LocalExecutor)
    assert isinstance(make_executor("local", address="tcp://h:8786"), DaskExecutor)    # an address means Dask
    with pytest.raises(ValueError, match="^workers: the local executor"):
        make_executor("local", workers=2)
    with pytest.raises(ValueError, match="^executor: unknown executor 'ray'; known: local, dask"):
        make_executor("ray")
    with pytest.raises(ValueError, match="^workers: must be a positive integer"):
        make_executor("dask", workers=0)
    with pytest.raises(ValueError, match="not both"):
        DaskExecutor(address="tcp://h:8786", workers=2)
    with pytest.raises(RuntimeError, match="context manager"):
        list(DaskExecutor().imap_unordered(_half, [1]))
