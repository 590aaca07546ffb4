"""The implicit effect of a sweep: same numbers as ssbench.evaluate.run_implicit, timing, CLI wiring."""
import json

import pytest

from ssbench.bench import run_sweep, sweep_from_dict
from ssbench.cli import main
from ssbench.evaluate import run_implicit


def test_implicit_rows_equal_a_direct_evaluation_and_are_timed(tmp_path):
    sw = sweep_from_dict({"effect": "implicit", "scenes": ["thin_shell"], "resolution": [24, 18], "frames": 3,
                          "methods": {"fixed": {"steps": 16}, "progressive": {"steps": 16}},
                          "timing": {"min_run_time": 0.01}})
    res = run_sweep(sw, tmp_path / "imp", progress=False)
    assert [r["error"] for r in res.rows] == [None, None]
    for r, method in zip(res.rows, ["fixed", "progressive"]):
        ev = run_implicit("thin_shell", method, {"steps": 16}, frames=3, width=24, height=18)
        assert r["punch_through_per_frame"] == ev.row["punch_through_per_frame"]
        assert r["floor_samples"] == max(1, round(float(ev.result.evaluations.double().mean())))
        assert r["floor_ratio"] > 0
    fixed, prog = res.rows
    assert len(set(fixed["punch_through_per_frame"])) == 1                   # a fixed lattice has no memory
    assert prog["punch_through_per_frame"][-1] < prog["punch_through_per_frame"][0]


def test_implicit_sweep_errors_name_the_setting(tmp_path):
    with pytest.raises(ValueError, match="frames"):
        sweep_from_dict({"effect": "implicit", "scenes": ["sphere"], "frames": 0, "methods": {"sphere": {}}})
    with pytest.raises((ValueError, KeyError), match="no_such_scene"):
        sweep_from_dict({"effect": "implicit", "scenes": ["no_such_scene"], "methods": {"sphere": {}}})


def test_ssbench_sweep_is_a_subcommand(tmp_path, capsys):
    f = tmp_path / "s.yaml"
    f.write_text("effect: implicit\nscenes: [sphere, torus]\nresolution: [8, 6]\nmethods:\n  sphere: {}\n")
    assert main(["sweep", str(f), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "2 configurations of effect implicit" in out and "torus sphere" in out
    assert main(["sweep", str(f), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    rows = [json.loads(line) for line in (tmp_path / "o" / "rows.jsonl").read_text().splitlines()]
    assert sorted(r["scene"] for r in rows) == ["sphere", "torus"] and all(r["error"] is None for r in rows)
    f.write_text("effect: implicit\nscenes: [sphere]\nmethods:\n  sphere: {max_stepz: 3}\n")
    assert main(["sweep", str(f), "--dry-run"]) == 1
    assert "s.yaml:4" in capsys.readouterr().err
