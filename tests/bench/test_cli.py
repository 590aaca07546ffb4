"""``ssbench sweep``: parser wiring, dry runs, a run with resume, and bad sweep files as file:line errors."""
import argparse
import json

import pytest

from ssbench.cli._sweep_cmd import add_sweep_parser, main


def test_add_sweep_parser_wires_into_a_parent_parser():
    p = argparse.ArgumentParser(prog="ssbench")
    add_sweep_parser(p.add_subparsers(dest="command"))
    a = p.parse_args(["sweep", "s.yaml", "--out", "o", "--executor", "dask", "--workers", "3", "--no-resume"])
    assert (a.config, a.out, a.executor, a.workers, a.resume, a.retry_errors) == ("s.yaml", "o", "dask", 3, False,
                                                                                  False)
    assert a.handler.__name__ == "cmd_sweep"
    assert p.parse_args(["sweep", "s.yaml"]).resume is True
    with pytest.raises(SystemExit):
        p.parse_args(["sweep", "s.yaml", "--workers", "0"])


def test_dry_run_lists_configurations(tmp_path, capsys):
    f = tmp_path / "s.yaml"
    f.write_text("effect: ao\nscenes: [crease]\nmethods: {hbao: {radius: [0.25, 0.5]}}\n")
    assert main(["sweep", str(f), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "2 configurations of effect ao" in out and "crease hbao radius=0.25" in out
    assert "reports/sweeps/s" in out


def test_bad_sweep_file_is_a_file_line_error(tmp_path, capsys):
    f = tmp_path / "s.yaml"
    f.write_text("effect: ao\nscenes: [crease]\nmethods:\n  hbao: {radius: [0.5]}\n  gtao: {preset: [low]}\n")
    assert main(["sweep", str(f)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"ssbench: error: {f}:5: methods.gtao.preset: unknown parameter 'preset'")
    assert "valid: quality, slice_count" in err
    assert main(["sweep", str(tmp_path / "missing.yaml")]) == 1
    assert "not found" in capsys.readouterr().err


def test_run_then_resume(toy, tmp_path, capsys):
    f = tmp_path / "toy.toml"
    f.write_text('effect = "toy"\nscenes = ["crease"]\nresolution = [8, 4]\n[methods.toy]\nx = [1, 2]\n')
    out = tmp_path / "out"
    assert main(["sweep", str(f), "--out", str(out), "--quiet"]) == 0
    assert "2 rows (2 run, 0 resumed, 1 with errors)" in capsys.readouterr().out
    assert main(["sweep", str(f), "--out", str(out), "--quiet"]) == 0
    assert "2 rows (0 run, 2 resumed, 1 with errors)" in capsys.readouterr().out
    assert main(["sweep", str(f), "--out", str(out), "--quiet", "--retry-errors"]) == 0
    assert "(1 run, 1 resumed, 1 with errors)" in capsys.readouterr().out
    assert len(json.load(open(out / "sweep.json"))["configs"]) == 2
