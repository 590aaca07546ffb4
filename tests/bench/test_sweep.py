"""The runner: rows per configuration, error rows, resume without duplicates, metadata, real AO/SSR rows."""
import json
import math
import os

import pytest

from ssbench.bench import canonical_json, run_sweep, sweep_from_dict
from ssbench.bench.sweep import run_config

from .conftest import CALLS


def _toy(**extra):
    data = {"effect": "toy", "scenes": ["crease", "stairs"], "methods": {"toy": {"x": [1, 2, 3]}},
            "seeds": [0, 1], "resolution": [8, 4]}
    data.update(extra)
    return sweep_from_dict(data, source="toy.yaml")


def test_every_configuration_gives_one_row_and_failures_are_rows(toy, tmp_path):
    s = _toy()
    res = run_sweep(s, tmp_path, progress=False)
    assert len(res.rows) == len(s) == 12 and res.ran == 12 and res.skipped == 0
    assert [r["config_id"] for r in res.rows] == s.ids()                          # sweep order
    bad = [r for r in res.rows if r["error"]]
    assert len(bad) == res.errors == 4 and all(r["params"] == {"x": 2.0} for r in bad)
    assert bad[0]["error"] == "RuntimeError: boom at x=2" and "toy_evaluate" in bad[0]["error_traceback"]
    ok = next(r for r in res.rows if not r["error"])
    assert ok["value"] == pytest.approx(1.0 * 2 + 0 + 8 / 4) and math.isnan(ok["nan_metric"])
    assert ok["config"] == s.configs[0].canonical() and ok["scene"] == "crease" and ok["effect"] == "toy"
    assert ok["run_id"] == res.run_id and ok["git_commit"] == "c0ffee" and ok["variant"] == "stub"
    assert ok["level"] == 0 and ok["threads"] == 1
    meta = json.load(open(tmp_path / "metadata.json"))
    assert meta["status"] == "finished" and meta["ran"] == 12 and meta["errors"] == 4
    assert meta["sweep"]["sha256"] == s.sha256 and meta["executor"]["kind"] == "local"
    assert meta["git"] == {"commit": "c0ffee", "dirty": False} and meta["versions"]["torch"]
    assert os.path.isfile(tmp_path / "runs" / f"{res.run_id}.json")
    assert len(open(tmp_path / "rows.jsonl").read().splitlines()) == 12


def test_resume_skips_done_rows_and_retries_errors_on_request(toy, tmp_path):
    s = _toy()
    first = run_sweep(s, tmp_path, progress=False)
    CALLS.clear()
    again = run_sweep(s, tmp_path, progress=False)
    assert again.ran == 0 and again.skipped == 12 and CALLS == []
    assert [canonical_json(r) for r in again.rows] == [canonical_json(r) for r in first.rows]
    retry = run_sweep(s, tmp_path, progress=False, retry_errors=True)
    assert retry.ran == 4 and retry.skipped == 8 and {c[2]["x"] for c in CALLS} == {2.0}
    fresh = run_sweep(s, tmp_path, progress=False, resume=False)
    assert fresh.ran == 12 and len(os.listdir(tmp_path / "rows")) == 12
    assert [canonical_json(r) for r in fresh.rows] == [canonical_json(r) for r in first.rows]


def test_a_grown_sweep_runs_only_the_new_points_and_tables_hold_the_current_sweep(toy, tmp_path):
    run_sweep(_toy(), tmp_path, progress=False)
    CALLS.clear()
    grown = _toy(methods={"toy": {"x": [1, 2, 3, 4]}})
    res = run_sweep(grown, tmp_path, progress=False)
    assert res.ran == 4 and {c[2]["x"] for c in CALLS} == {4.0}
    narrow = _toy(methods={"toy": {"x": [3]}})
    res = run_sweep(narrow, tmp_path, progress=False)
    assert res.ran == 0 and len(res.rows) == 4 and len(os.listdir(tmp_path / "rows")) == 16
    assert len(open(tmp_path / "rows.jsonl").read().splitlines()) == 4


def test_an_output_folder_of_another_effect_is_refused(toy, tmp_path):
    run_sweep(_toy(), tmp_path, progress=False)
    ao = sweep_from_dict({"effect": "ao", "scenes": ["crease"], "methods": {"hbao": {}}})
    with pytest.raises(ValueError, match="effect 'toy'"):
        run_sweep(ao, tmp_path, progress=False)


def test_timing_block_adds_floor_fields_to_every_row(toy, tmp_path):
    res = run_sweep(_toy(timing={"min_run_time": 0.01, "processes": 1}, scenes=["crease"], seeds=[0]), tmp_path, progress=False)
    for r in res.rows:
        assert {"time_median_ms", "time_iqr_ms", "floor_median_ms", "floor_ratio", "threads"} <= set(r)
        if r["error"]:
            assert math.isnan(r["floor_ratio"]) and r["timing_error"].startswith("not timed")
        else:
            assert r["floor_ratio"] > 0 and r["floor_samples"] == 2 * 3 and r["timing_error"] is None


def test_run_config_restores_threads_and_sets_them(toy):
    import torch
    before = torch.get_num_threads()
    s = _toy(threads=[1, 2], scenes=["crease"], seeds=[0], methods={"toy": {"x": 1}})
    rows = [run_config(c) for c in s.configs]
    assert [r["threads"] for r in rows] == [1, 2] and torch.get_num_threads() == before


@pytest.mark.slow
@pytest.mark.mitsuba
def test_real_rows_with_timing(tmp_path):
    ao = sweep_from_dict({"effect": "ao", "scenes": ["sphere_on_plane"], "resolution": [32, 24], "rays": 8,
                          "flip": False, "methods": {"hbao": {"num_directions": [2, 4], "num_steps": 3}},
                          "timing": {"min_run_time": 0.01}})
    res = run_sweep(ao, tmp_path / "ao", progress=False)
    assert [r["error"] for r in res.rows] == [None, None]
    assert [r["floor_samples"] for r in res.rows] == [2 * 3, 4 * 3]                  # directions × steps
    assert all(r["floor_ratio"] > 0 and r["rmse_cos"] >= 0 and r["variant"] for r in res.rows)
    ssr = sweep_from_dict({"effect": "ssr", "scenes": ["reflective_floor"], "resolution": [32, 24], "spp": 2,
                           "flip": False, "methods": {"dda": {"max_steps": 16}, "linear": {"iterations": 8}},
                           "timing": {"min_run_time": 0.01}})
    res = run_sweep(ssr, tmp_path / "ssr", progress=False)
    assert [r["error"] for r in res.rows] == [None, None]
    from ssbench.evaluate import run_ssr
    for r, (method, params) in zip(res.rows, [("dda", {"max_steps": 16}), ("linear", {"iterations": 8})]):
        ev = run_ssr("reflective_floor", method, params, width=32, height=24, spp=2, flip=False, repeats=1)
        assert r["floor_samples"] == max(1, round(float(ev.result.steps.float().mean())))   # reads per pixel
        assert r["floor_ratio"] > 0 and 0 <= r["frac_correct"] <= 1


def test_a_corrupt_row_is_quarantined_named_and_recomputed(toy, tmp_path):
    """Regression: a corrupt row file stopped the resume ('Unterminated string …') without naming it."""
    s = _toy()
    first = run_sweep(s, tmp_path, progress=False)
    victim = first.rows[3]["config_id"]
    path = tmp_path / "rows" / f"{victim}.json"
    path.write_text('{"config_id": "' + victim[:5])                             # a torn write
    CALLS.clear()
    with pytest.warns(RuntimeWarning, match=f"sweep row .*{victim}.json is corrupt"):
        again = run_sweep(s, tmp_path, progress=False)
    assert again.ran == 1 and again.skipped == 11 and len(CALLS) == 1
    aside = [n for n in os.listdir(tmp_path / "rows") if n.startswith(f"{victim}.json.corrupt-")]
    assert len(aside) == 1 and any(aside[0] in n for n in again.notes)
    assert [canonical_json(r) for r in again.rows] == [canonical_json(r) for r in first.rows]


def test_rows_are_strict_json_and_round_trip_non_finite_values(toy, tmp_path):
    """Regression: rows.jsonl held a bare NaN (not JSON)."""
    first = run_sweep(_toy(), tmp_path, progress=False)
    strict = lambda text: json.loads(text, parse_constant=lambda c: pytest.fail(f"bare {c} in a row"))  # noqa: E731
    lines = [strict(x) for x in (tmp_path / "rows.jsonl").read_text().splitlines()]
    ok = [r for r in lines if r.get("error") is None]
    assert ok and all(r["nan_metric"] is None and r["nonfinite"]["nan_metric"] == "nan" for r in ok)
    for name in os.listdir(tmp_path / "rows"):
        strict((tmp_path / "rows" / name).read_text())
    assert all(math.isnan(r["nan_metric"]) for r in first.rows if r.get("error") is None)
    again = run_sweep(_toy(), tmp_path, progress=False)                         # read back from the files
    assert all(math.isnan(r["nan_metric"]) for r in again.rows if r.get("error") is None)
