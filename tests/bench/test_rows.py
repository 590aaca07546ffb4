"""The row store: atomic rows, stray temporary files, consolidated tables, volatile fields."""
import json
import math
import os

import pytest

from ssbench.bench import rows as R


def test_rows_are_whole_or_absent_and_strays_are_ignored(tmp_path):
    s = R.RowStore(tmp_path)
    s.write_row({"config_id": "a1", "v": 1})
    # what a kill -9 between writing and renaming leaves behind: a temporary file of a dead writer
    stray = tmp_path / "rows" / ".b2.json.999999999.ab.tmp"
    stray.write_text('{"config_id": "b2", "v"')
    assert s.done_ids() == {"a1"}
    assert R.RowStore(tmp_path).done_ids() == {"a1"} and not stray.exists()      # cleaned on open
    s.write_row({"config_id": "a1", "v": 2})                                    # replaced, not appended
    assert s.read_row("a1") == {"config_id": "a1", "v": 2}
    assert os.listdir(tmp_path / "rows") == ["a1.json"]


def test_a_failed_rename_leaves_nothing(tmp_path, monkeypatch):
    s = R.RowStore(tmp_path)

    def broken(tmp, path):
        raise OSError("disk gone")
    monkeypatch.setattr(R, "_commit", broken)
    with pytest.raises(OSError):
        s.write_row({"config_id": "c3"})
    assert os.listdir(tmp_path / "rows") == []


@pytest.mark.parametrize("cid", [None, "", "../x", ".hidden", 3])
def test_row_needs_a_plain_config_id(tmp_path, cid):
    with pytest.raises(ValueError, match="config_id"):
        R.RowStore(tmp_path).write_row({"config_id": cid})


def test_consolidated_tables_follow_the_given_order(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    s = R.RowStore(tmp_path)
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


def test_volatile_fields_and_canonical_json():
    a = {"config_id": "x", "rmse": float("nan"), "seconds": 0.1, "gt_seconds_cos": 2.0, "floor_ratio": 3.0,
         "floor_samples": 12, "run_id": "r1", "git_commit": "abc", "threads": 1}
    b = dict(a, seconds=0.2, gt_seconds_cos=5.0, floor_ratio=3.3, run_id="r2", git_commit="def",
             rmse=float("nan"))
    assert a != b and R.canonical_json(a) == R.canonical_json(b)                # NaN compares equal here
    assert R.canonical_json(a) != R.canonical_json(dict(b, floor_samples=13))   # the sample count is not volatile
    assert set(R.stable(a)) == {"config_id", "rmse", "floor_samples", "threads"}
    assert R.new_run_id() != R.new_run_id()
