"""``ssbench tune``: parser wiring on a fresh parser, argument errors naming the argument, a tiny real run."""
import argparse
import json

import pytest

from ssbench.cli._tune_cmd import add_tune_parser, main


def _parser():
    p = argparse.ArgumentParser(prog="ssbench")
    add_tune_parser(p.add_subparsers(dest="command"))
    return p


def test_add_tune_parser_wires_into_a_parent_parser():
    a = _parser().parse_args(["tune", "hbao", "--scenes", "crease", "--held-out", "none", "--budget-ms", "12.5",
                              "--tune", "radius=0.1:0.9,ao_strength", "--param", "num_steps=4"])
    assert (a.method, a.scenes, a.held_out, a.budget_ms) == ("hbao", ["crease"], [], 12.5)
    assert a.tune == [("radius", (0.1, 0.9)), ("ao_strength", None)] and a.param == [("num_steps", 4)]
    assert a.handler.__name__ == "cmd_tune"
    d = _parser().parse_args(["tune", "gtao"])
    assert (d.scenes, d.held_out, d.width, d.height, d.gt_radius, d.weighting) == (
        ["crease", "sphere_on_plane"], ["cornell_box", "stairs"], 160, 120, 0.5, "cosine")


@pytest.mark.parametrize("argv, message", [
    (["tune", "gtoa"], "invalid choice: 'gtoa'"),
    (["tune", "gtao", "--points", "1"], "argument --points: expected an integer >= 2"),
    (["tune", "gtao", "--budget-ms", "0"], "argument --budget-ms: expected a number > 0"),
    (["tune", "gtao", "--tune", "radius=1:0.5"], "argument --tune: expected NAME or NAME=LO:HI"),
    (["tune", "gtao", "--scenes", "nowhere"], "argument --scenes: unknown scene(s) nowhere; built-in scenes: "),
    (["tune", "gtao", "--param", "radius"], "argument --param: expected NAME=VALUE"),
])
def test_bad_arguments_are_usage_errors(argv, message, capsys):
    with pytest.raises(SystemExit):
        _parser().parse_args(argv)
    err = capsys.readouterr().err
    assert message in err
    if "gtoa" in argv:
        assert "crytek" in err and "gtao" in err                       # the valid methods are listed


@pytest.mark.parametrize("argv, message", [
    (["--tune", "radus"], "ssbench: error: argument --tune: 'radus' not tunable for gtao; tunable: radius, "
                          "falloff_range, final_value_power"),
    (["--param", "slices=2"], "ssbench: error: argument --param: params: unknown parameter 'slices'"),
    (["--param", "quality=high", "--param", "quality=low"], "argument --param: a parameter is given twice"),
    (["--scenes", "none"], "argument --scenes: need at least one training scene"),
])
def test_bad_values_exit_1_naming_the_argument(argv, message, capsys):
    assert main(["tune", "gtao", *argv]) == 1
    assert message in capsys.readouterr().err


@pytest.mark.slow
def test_tiny_run_prints_the_table_and_writes_tune_json(tmp_path, capsys):
    out = tmp_path / "t"
    argv = ["tune", "gtao", "--scenes", "crease", "--held-out", "stairs", "--width", "32", "--height", "24",
            "--rays", "8", "--points", "3", "--rounds", "1", "--steps", "1", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "gtao: tuned on crease at 32x24 against cosine GT (radius 0.5, 8 rays); held out: stairs" in text
    assert "held_out" in text and "radius" in text and "time per frame (1 thread(s))" in text
    data = json.loads((out / "tune.json").read_text())
    assert data["method"] == "gtao" and data["settings"]["held_out"] == ["stairs"]
    assert data["summary"]["train_tuned"] <= data["summary"]["train_default"]
    assert [r["split"] for r in data["rows"]] == ["train", "held_out"]
    assert f"{data['rows'][1]['default']:.4f}" in text


def test_blur_argument_parses_and_lists_the_blurs(capsys):
    a = _parser().parse_args(["tune", "gtao", "--blur", "joint_bilateral", "--tune", "blur_sigma_space=1:3,radius"])
    assert a.blur == "joint_bilateral" and a.tune == [("blur_sigma_space", (1.0, 3.0)), ("radius", None)]
    assert _parser().parse_args(["tune", "gtao"]).blur is None
    with pytest.raises(SystemExit):
        _parser().parse_args(["tune", "gtao", "--blur", "gauss"])
    assert "invalid choice: 'gauss' (choose from" in capsys.readouterr().err


def test_blur_tunables_need_the_blur(capsys):
    assert main(["tune", "gtao", "--scenes", "crease", "--held-out", "none", "--tune", "blur_sigma_color"]) == 1
    err = capsys.readouterr().err
    assert "'blur_sigma_color' not tunable for gtao; tunable: radius, falloff_range, final_value_power" in err
    assert main(["tune", "gtao", "--blur", "cross_bilateral", "--scenes", "crease", "--held-out", "none",
                 "--tune", "blur_sigma_color"]) == 1
    assert ("not tunable for gtao with --blur cross_bilateral; tunable: radius, falloff_range, final_value_power, "
            "blur_falloff, blur_threshold") in capsys.readouterr().err
