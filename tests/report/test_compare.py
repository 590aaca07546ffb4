"""``ssbench report --compare``: run resolution, row matching, tolerances, timings, output folder, CLI."""
import json
import os

import pytest

from ssbench.cli import main
from ssbench.report.compare import compare_runs, load_run, resolve_run, to_text, write_comparison

ROWS = [{"scene": "crease", "method": "ssao", "params": {"radius": 0.5}, "width": 32, "rmse_cos": 0.1,
         "nonfinite": 0, "psnr_cos": None, "seconds": 1.0},
        {"scene": "crease", "method": "gtao", "params": {"radius": 0.5}, "width": 32, "rmse_cos": 0.2,
         "seconds": 1.0}]
IMPLICIT = [{"scene": "thin_shell", "method": "sphere", "params": None, "frames": 1, "punch_through_rate": 0.1,
             "punch_through_per_frame": [0.1], "seconds_per_frame": 0.01},
            {"scene": "thin_shell", "method": "sphere", "params": None, "frames": 1, "truth_frames": "none",
             "steps_mean": 7.0}]


def _run(root, name, ao=ROWS, implicit=IMPLICIT, commit="abc", total=10.0, rows_in_meta=False):
    """A report run folder as build_report writes it (meta.json + rows/<section>.jsonl)."""
    d = root / name
    (d / "rows").mkdir(parents=True)
    meta = {"run": name, "git": {"commit": commit, "dirty": False}, "environment": {"variant": "llvm_ad_rgb"},
            "width": 32, "height": 24, "spp": 4, "seed": 0, "total_s": total,
            "scenes": [{"name": "crease", "timings": {"gbuffer_s": 1.0, "color_s": 2.0}}],
            "ao": {"available": True, "seconds": 3.0}, "implicit": {"available": True},
            "ssr": {"available": False, "note": "off"}}
    if rows_in_meta:                                        # a run written before rows/ existed
        meta["ao"]["rows"], meta["implicit"]["rows"] = ao, implicit
    else:
        for key, rows in (("ao", ao), ("implicit", implicit)):
            (d / "rows" / f"{key}.jsonl").write_text("".join(json.dumps({"effect": key, **r}) + "\n" for r in rows))
    (d / "meta.json").write_text(json.dumps(meta))
    return d


def _cmp(root, a, b, **kw):
    return compare_runs(load_run(str(root / a)), load_run(str(root / b)), **kw)


def test_a_run_against_itself_has_no_changes(tmp_path):
    _run(tmp_path, "r1")
    c = _cmp(tmp_path, "r1", "r1")
    assert c["rows_compared"] == 4 and c["rows_unchanged"] == 4
    assert c["results"] == [] and c["added"] == [] and c["removed"] == [] and c["timings"] == []
    assert not any(m["changed"] for m in c["metadata"] + c["sections"])
    assert "4 rows in both runs, 0 changed" in to_text(c)


def test_changes_beyond_the_tolerance_new_and_removed_rows(tmp_path):
    _run(tmp_path, "a")
    b_rows = [{**ROWS[0], "rmse_cos": 0.1 * (1 + 5e-4), "nonfinite": 3, "psnr_cos": 20.0, "seconds": 1.1},
              {**ROWS[1], "rmse_cos": 0.3, "seconds": 2.0},
              {**ROWS[1], "method": "hbao"}]
    _run(tmp_path, "b", ao=b_rows, implicit=IMPLICIT[:1], commit="def", total=20.0)
    c = _cmp(tmp_path, "a", "b", rtol=1e-3, time_rtol=0.25)
    changed = {(r["row"], r["field"]): r for r in c["results"]}
    assert set(changed) == {("ao/crease/ssao", "nonfinite"), ("ao/crease/ssao", "psnr_cos"),
                            ("ao/crease/gtao", "rmse_cos")}                  # 5e-4 relative is within rtol
    assert changed[("ao/crease/gtao", "rmse_cos")]["rel"] == pytest.approx(1 / 3)
    assert changed[("ao/crease/ssao", "psnr_cos")]["a"] == "–"               # a NaN (null) that became a number
    assert [k.split(" ")[0] for k in c["added"]] == ["ao/crease/hbao"]
    assert len(c["removed"]) == 1 and "truth_frames=none" in c["removed"][0]
    times = {t["what"]: t for t in c["timings"]}
    assert set(times) == {"total wall time", "ao/crease/gtao · seconds"}      # 1.0 → 1.1 is within 25 %
    assert times["total wall time"]["ratio"] == pytest.approx(2.0)
    meta = {m["what"]: m for m in c["metadata"]}
    assert meta["git commit"]["changed"] and not meta["variant"]["changed"]
    sections = {s["what"]: s for s in c["sections"]}
    assert sections["Implicit surfaces"]["changed"] and sections["Ambient occlusion"]["a"] == "2 rows"
    text = to_text(c)
    assert "* git commit" in text and "ao/crease/gtao" in text and "only in B: ao/crease/hbao" in text


def test_repeated_rows_get_distinct_labels(tmp_path):
    rows = [{**IMPLICIT[0], "truth_frames": "all"}, IMPLICIT[1], IMPLICIT[1]]
    _run(tmp_path, "a", implicit=rows)
    _run(tmp_path, "b", implicit=[rows[0], rows[1], {**rows[2], "steps_mean": 9.0}])
    c = _cmp(tmp_path, "a", "b")
    assert [r["row"] for r in c["results"]] == ["implicit/thin_shell/sphere truth_frames=none #2"]
    assert c["rows_compared"] == 5 and c["rows_unchanged"] == 4


def test_runs_with_rows_only_in_meta_json_compare_like_new_ones(tmp_path):
    _run(tmp_path, "old", ao=[{**ROWS[0], "psnr_cos": float("nan")}, ROWS[1]], rows_in_meta=True)
    _run(tmp_path, "new")
    c = _cmp(tmp_path, "old", "new")
    assert c["rows_compared"] == 4 and c["results"] == []                    # NaN there, null here: the same


def test_resolving_runs(tmp_path):
    _run(tmp_path, "20250101-000000")
    (tmp_path / "latest").symlink_to(tmp_path / "20250101-000000")
    (tmp_path / "broken").mkdir()
    assert resolve_run("latest", str(tmp_path)) == str(tmp_path / "latest")
    assert resolve_run(str(tmp_path / "20250101-000000"), "/nonexistent") == str(tmp_path / "20250101-000000")
    with pytest.raises(ValueError, match=r"RUN_B: no run 'nope' .*runs there: 20250101-000000"):
        resolve_run("nope", str(tmp_path), "RUN_B")
    with pytest.raises(ValueError, match="RUN_A: .*broken.* holds no meta.json"):
        resolve_run("broken", str(tmp_path), "RUN_A")
    with pytest.raises(ValueError, match="rtol"):
        _cmp(tmp_path, "20250101-000000", "20250101-000000", rtol=-1)


def test_the_comparison_folder_replaces_itself_and_leaves_runs_alone(tmp_path):
    a, b = _run(tmp_path, "a"), _run(tmp_path, "b", commit="def")
    before = {p: os.stat(p).st_mtime_ns for d in (a, b) for p in d.rglob("*")}
    c = _cmp(tmp_path, "a", "b")
    dest = write_comparison(c, str(tmp_path))
    assert os.path.basename(dest) == "compare-a-vs-b"
    assert sorted(os.listdir(dest)) == ["compare.html", "compare.json", "compare.md"]
    assert "| * git commit | abc | def |" in (tmp_path / "compare-a-vs-b" / "compare.md").read_text()
    html = (tmp_path / "compare-a-vs-b" / "compare.html").read_text()
    assert '<tr class="changed"><td>* git commit</td><td>abc</td><td>def</td></tr>' in html
    (tmp_path / "compare-a-vs-b" / "stale.txt").write_text("x")
    assert write_comparison(c, str(tmp_path)) == dest and "stale.txt" not in os.listdir(dest)
    kept = [n for n in os.listdir(tmp_path) if n.startswith(".compare-a-vs-b@")]  # the current and previous copy
    assert os.readlink(dest) in kept and len(kept) == 2
    assert sorted(n for n in os.listdir(tmp_path) if n not in kept and n != ".compare-a-vs-b.lock") == \
        ["a", "b", "compare-a-vs-b"]
    assert {p: os.stat(p).st_mtime_ns for d in (a, b) for p in d.rglob("*")} == before


def test_cli_compare(tmp_path, capsys):
    _run(tmp_path, "a")
    _run(tmp_path, "b", total=30.0)
    assert main(["report", "--out", str(tmp_path), "--compare", "a", "b", "--time-rtol", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "A = a  vs  B = b" in out and "total wall time" in out and "compare-a-vs-b" in out
    assert (tmp_path / "compare-a-vs-b" / "compare.md").is_file()
    assert main(["report", "--out", str(tmp_path), "--compare", "a", "nope"]) == 1
    err = capsys.readouterr().err
    assert "ssbench: error: RUN_B: no run 'nope'" in err and "Traceback" not in err


@pytest.mark.parametrize("argv, names", [
    (["--compare", "a", "b", "--width", "64"], ["--compare", "--width"]),
    (["--compare", "a", "b", "--no-ao", "--scenes", "crease"], ["--compare", "--no-ao", "--scenes"]),
    (["--compare", "a"], ["--compare", "2 arguments"]),
    (["--compare", "a", "b", "--rtol", "-1"], ["--rtol"]),
    (["--compare", "a", "b", "--time-rtol", "nan"], ["--time-rtol"]),
])
def test_cli_compare_usage_errors(tmp_path, capsys, argv, names):
    _run(tmp_path, "a")
    _run(tmp_path, "b")
    assert main(["report", "--out", str(tmp_path)] + argv) == 2
    err = capsys.readouterr().err
    assert "ssbench: error:" in err and "Traceback" not in err
    for n in names:
        assert n in err
    assert sorted(os.listdir(tmp_path)) == ["a", "b"]                        # nothing built, nothing written
