"""The row store: atomic rows, stray temporary files, a failed rename, plain config ids, consolidated tables."""
import json
import math
import os

import pytest

from ssbench.bench import rows as R
from ssbench.bench.rowstore import RowStore


def test_rows_are_whole_or_absent_and_strays_are_ignored(tmp_path):
    s = RowStore(tmp_path)
    s.write_row({"config_id": "a1", "v": 1})
    # what a kill -9 between writing and renaming leaves behind: a temporary file of a dead writer
    stray = tmp_path / "rows" / ".b2.json.999999999.ab.tmp"
    stray.write_text('{"config_id": "b2", "v"')
    assert s.done_ids() == {"a1"}
    assert RowStore(tmp_path).done_ids() == {"a1"} and not stray.exists()      # cleaned on open
    s.write_row({"config_id": "a1", "v": 2})                                    # replaced, not appended
    assert s.read_row("a1") == {"config_id": "a1", "v": 2}
    assert os.listdir(tmp_path / "rows") == ["a1.json"]


def test_a_failed_rename_leaves_nothing(tmp_path, monkeypatch):
    s = RowStore(tmp_path)

    def broken(tmp, path):
        raise OSError("disk gone")
    monkeypatch.setattr(R, "_commit", broken)
    with pytest.raises(OSError):
        s.write_row({"config_id": "c3"})
    assert os.listdir(tmp_path / "rows") == []


@pytest.mark.parametrize("cid", [None, "", "../x", ".hidden", 3])
def test_row_needs_a_plain_config_id(tmp_path, cid):
    with pytest.raises(ValueError, match="config_id"):
        RowStore(tmp_path).write_row({"config_id": cid})


def test_consolidated_tables_follow_the_given_order(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    s = RowStore(tmp_path)
    rows = [{"config_id": "b", "method": "gtao", "params": {"quality": "low"}, "x": 1, "err": None},
            {"config_id": "a", "method": "hbao", "params": {"radius": 0.5}, "x": 2.5, "err": "ValueError: no",
             "runs": [1.0, 2.0], "m": float("nan")}]
    for r in rows:
        s.write_row(r)
    out = s.consolidate(["a", "b", "missing"])
    lines = open(out["jsonl"]).read().splitlines()
    assert [json.loads(x)["config_id"] for x in lines] == ["a", "b"]
    t = pq.read_table(out["parquet"]).to_pydict()
    assert t["config_id"] == ["a", "b"] and t["x"] == [2.5, 1.0]
    assert t["param.radius"] == [0.5, None] and t["param.quality"] == [None, "low"]
    assert json.loads(t["params"][0]) == {"radius": 0.5} and t["runs"] == ["[1.0, 2.0]", None]
    assert math.isnan(t["m"][0]) and t["err"] == ["ValueError: no", None]
