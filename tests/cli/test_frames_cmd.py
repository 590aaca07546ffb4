"""``ssbench frames``: AO, SSR and implicit TXAA over frames from the command line; numbers as JSON equal to the
library's, and every bad argument one ``ssbench: error:`` line naming it."""
import json

import pytest

from ssbench.cli import main

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]
SMALL = ["--frames", "3", "--width", "40", "--height", "30"]


def test_ao_frames_with_a_moving_object_print_the_library_numbers(capsys):
    from ssbench.evaluate import ao_frames
    from ssbench.passes.temporal import AccumulationParams
    from ssbench.scenes.motion import Motion
    assert main(["frames", "ao", "sphere_on_plane", "--method", "gtao", "--move", "ball:0.15,0,0",
                 "--truth-rays", "8", "--json", *SMALL]) == 0
    row = json.loads(capsys.readouterr().out)
    run = ao_frames("sphere_on_plane", "gtao", frames=3, width=40, height=30, accumulation=AccumulationParams(),
                    truth_rays=8, moving=Motion("ball", (0.15, 0.0, 0.0)))
    assert row["ghosting_moving"] == pytest.approx(run.ghosting_moving) and row["flicker"] == pytest.approx(run.flicker)
    assert row["moving"] == {"shape": "ball", "velocity": [0.15, 0.0, 0.0]} and row["motion_vectors"] is True


def test_ssr_and_implicit_frames_run_and_print_a_table(capsys):
    assert main(["frames", "ssr", "glossy_ramp", "--method", "glossy_stochastic", *SMALL]) == 0
    out = capsys.readouterr().out
    assert "flicker_accumulated" in out and "glossy_stochastic" in out
    assert main(["frames", "implicit", "torus", "--method", "sphere", "--json", *SMALL]) == 0
    row = json.loads(capsys.readouterr().out)
    assert row["depth_tolerance"] == float("inf") and row["error_raw"] > 0


@pytest.mark.parametrize("argv, needle", [
    (["ao", "sphere_on_plane", "--method", "nope"], "argument --method"),
    (["ao", "sphere_on_plane", "--method", "gtao", "--move", "ball:1,2"], "argument --move"),
    (["ao", "sphere_on_plane", "--method", "gtao", "--move", "wall:1,2,3"], "argument --move: shape"),
    (["ao", "sphere_on_plane", "--method", "gtao", "--param", "radius=-1"], "argument --param"),
    (["ao", "sphere_on_plane", "--method", "gtao", "--frames", "1"], "argument --frames"),
    (["ao", "sphere_on_plane", "--method", "gtao", "--truth-rays", "1"], "argument --truth-rays"),
    (["implicit", "torus", "--method", "sphere", "--orbit", "2"], "still camera"),
    (["ao", "nowhere", "--method", "gtao"], "nowhere"),
])
def test_bad_arguments_are_one_line(capsys, argv, needle):
    assert main(["frames", *argv]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("ssbench: error:") and needle in err[-1], err
    assert "Traceback" not in "\n".join(err)
