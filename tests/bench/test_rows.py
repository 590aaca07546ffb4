"""Row encoding: volatile fields, canonical JSON, strict JSON for non-finite numbers, tables and metadata."""
from ssbench.bench import rows as R


def test_volatile_fields_and_canonical_json():
    a = {"config_id": "x", "rmse": float("nan"), "seconds": 0.1, "gt_seconds_cos": 2.0, "floor_ratio": 3.0,
         "floor_samples": 12, "run_id": "r1", "git_commit": "abc", "threads": 1}
    b = dict(a, seconds=0.2, gt_seconds_cos=5.0, floor_ratio=3.3, run_id="r2", git_commit="def",
             rmse=float("nan"))
    assert a != b and R.canonical_json(a) == R.canonical_json(b)                # NaN compares equal here
    assert R.canonical_json(a) != R.canonical_json(dict(b, floor_samples=13))   # the sample count is not volatile
    assert set(R.stable(a)) == {"config_id", "rmse", "floor_samples", "threads"}
    assert R.new_run_id() != R.new_run_id()
