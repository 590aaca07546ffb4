"""Sweep files → validated sweeps: grids, expansion, stable ids, and file:line errors naming the valid names."""
import os
import textwrap

import pytest

from ssbench.bench.config import (Sweep, SweepError, config_id, expand_logrange, expand_range, load_sweep,
                                  parse_sweep, sweep_from_dict)


def _write(tmp_path, text, name="s.yaml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return str(p)


def _err(tmp_path, text, name="s.yaml") -> str:
    path = _write(tmp_path, text, name)
    with pytest.raises(SweepError) as e:
        load_sweep(path)
    return str(e.value)


AO_YAML = """\
    effect: ao
    scenes: [sphere_on_plane, crease]
    methods:
      hbao:
        radius: [0.25, 0.5, 1]
        num_directions: {range: [4, 16, 4]}
      gtao: {quality: [low, high]}
    seeds: [0, 1]
    resolution: [32, 24]
    rays: 8
"""


def test_expansion_is_the_cartesian_product_in_order(tmp_path):
    s = load_sweep(_write(tmp_path, AO_YAML))
    assert isinstance(s, Sweep) and s.effect == "ao" and s.name == "s" and s.timing is None
    assert len(s) == 2 * (3 * 4 + 2) * 2
    first = s.configs[0]
    assert (first.scene, first.method, dict(first.params), first.seed) == \
        ("sphere_on_plane", "hbao", {"num_directions": 4, "radius": 0.25}, 0)
    assert s.configs[1].seed == 1 and s.configs[-1].scene == "crease" and s.configs[-1].method == "gtao"
    assert {c.settings["rays"] for c in s.configs} == {8}
    assert {c.settings["threads"] for c in s.configs} == {1}               # the default, recorded
    radii = [c.params["radius"] for c in s.configs if c.method == "hbao"]
    assert all(isinstance(r, float) for r in radii) and 1.0 in radii     # int 1 coerced to the float field
    assert len({c.config_id for c in s.configs}) == len(s)


def test_config_id_is_stable_and_canonical(tmp_path):
    a = load_sweep(_write(tmp_path, AO_YAML))
    reordered = AO_YAML.replace("        radius: [0.25, 0.5, 1]\n        num_directions: {range: [4, 16, 4]}\n",
                                "        num_directions: [4, 8, 12, 16]\n        radius: [0.25, 0.5, 1.0]\n")
    assert reordered != AO_YAML
    b = load_sweep(_write(tmp_path, reordered, "t.yaml"))
    assert {c.config_id for c in a.configs} == {c.config_id for c in b.configs}
    assert a.sha256 != b.sha256
    c0 = a.configs[0]
    assert c0.config_id == config_id(c0.canonical())
    assert config_id({**c0.canonical(), "seed": 7}) != c0.config_id


def test_toml_gives_the_same_configurations(tmp_path):
    toml = """\
        effect = "ao"
        scenes = ["sphere_on_plane", "crease"]
        seeds = [0, 1]
        resolution = [32, 24]
        rays = 8
        [methods.hbao]
        radius = [0.25, 0.5, 1]
        num_directions = {range = [4, 16, 4]}
        [methods.gtao]
        quality = ["low", "high"]
    """
    t = load_sweep(_write(tmp_path, toml, "s.toml"))
    y = load_sweep(_write(tmp_path, AO_YAML))
    assert t.ids() == y.ids()


def test_grid_forms():
    assert expand_range(0.5, 1.0, 0.25) == [0.5, 0.75, 1.0]
    assert expand_logrange(0.1, 10, 3) == [0.1, 1.0, 10.0]
    with pytest.raises(ValueError, match="does not lead"):
        expand_range(1, 5, -1)
    s = sweep_from_dict({"effect": "ao", "scenes": "crease", "resolution": [[32, 24], [16, 12]],
                         "methods": {"hbao": {"num_steps": {"logrange": [2, 16, 4]}},
                                     "ssao": None,
                                     "gtao": [{"quality": "low"}, {"slice_count": [1, 2], "quality": "low"}]},
                         "rays": {"values": [8, 16]}, "blur": [None, "box"], "threads": [1, 2]})
    steps = sorted({c.params["num_steps"] for c in s.configs if c.method == "hbao"})
    assert steps == [2, 4, 8, 16] and all(isinstance(v, int) for v in steps)     # ints for an int field
    assert [dict(c.params) for c in s.configs if c.method == "ssao"][:1] == [{}]
    gtao = {tuple(sorted(c.params.items())) for c in s.configs if c.method == "gtao"}
    assert gtao == {(("quality", "low"),), (("quality", "low"), ("slice_count", 1)),
                    (("quality", "low"), ("slice_count", 2))}
    per_point = 2 * 2 * 2 * 2                  # resolutions × rays × blur × threads
    assert len(s) == (4 + 1 + 3) * per_point
    assert {(c.width, c.height) for c in s.configs} == {(32, 24), (16, 12)}


def test_duplicate_points_are_run_once():
    s = sweep_from_dict({"effect": "ao", "scenes": ["crease", "crease"],
                         "methods": {"hbao": [{"radius": [0.5, 0.5]}, {"radius": 0.5}]}})
    assert len(s) == 1


def test_timing_block_and_scene_files(tmp_path):
    (tmp_path / "sc").mkdir()
    (tmp_path / "sc" / "ball.yaml").write_text(
        "camera: {eye: [0, 1, 5], target: [0, 0, 0], fovy: 45}\nshapes: [{type: sphere, radius: 1}]\n")
    s = load_sweep(_write(tmp_path, """\
        effect: ssr
        scenes: [sc/ball.yaml]
        methods: [dda, linear]
        timing: {min_run_time: 0.05, rounds: 9}
    """))
    assert s.timing.min_run_time == 0.05 and s.timing.floor is True and s.timing.rounds == 9
    c = s.configs[0]
    assert c.scene == "sc/ball.yaml" and os.path.isabs(c.scene_file) and len(c.scene_sha256) == 64
    assert c.settings == {"threads": 1, "repeats": 1, "spp": 16, "k_px": 1.5, "reflective": None, "flip": True}
    assert [c.method for c in s.configs] == ["dda", "linear"]


@pytest.mark.parametrize("body, where, words", [
    ("effect: aoo\nscenes: [crease]\nmethods: {hbao: {}}\n", ":1: effect:", ["unknown effect 'aoo'", "ao, ssr"]),
    ("effect: ao\nscenes: [crease]\nmethods:\n  hbao: {}\n  hbaoo: {radius: 1}\n", ":5: methods.hbaoo:",
     ["did you mean 'hbao'", "valid: crytek, ssao, hbao, gtao"]),
    ("effect: ao\nscenes: [crease]\nmethods:\n  gtao:\n    preset: [low, high]\n", ":5: methods.gtao.preset:",
     ["unknown parameter 'preset'", "valid: quality, slice_count", "denoise_passes"]),
    ("effect: ao\nscenes: [crease]\nmethods:\n  hbao:\n    num_steps: [4, five]\n", ":5: methods.hbao.num_steps[1]:",
     ["expected an integer, got 'five'"]),
    ("effect: ao\nscenes: [crease]\nmethods:\n  hbao:\n    radius: []\n", ":5: methods.hbao.radius:", ["empty grid"]),
    ("effect: ao\nscenes: [crease]\nmethods:\n  hbao:\n    radius: {range: [1, 0, 0.5]}\n",
     ":5: methods.hbao.radius.range:", ["does not lead"]),
    ("effect: ao\nscenes: [crease]\nmethods:\n  hbao:\n    radius:\n      - 0.5\n      - -1\n",
     ":7: methods.hbao.radius[1]:",
     ["HBAOParams rejects", "radius"]),
    ("effect: ao\nscenes: [crease, nowhere]\nmethods: {hbao: {}}\n", ":2: scenes[1]:",
     ["unknown scene 'nowhere'", "sphere_on_plane"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\nray: 8\n", ":4: ray:", ["unknown field", "rays"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {radius: .nan}}\n", ":3: methods.hbao.radius:", ["finite"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {num_steps: {range: [1, 100000, 1]}}}\n",
     ":3: methods.hbao.num_steps.range:", ["more than 10000"]),
    ("effect: ao\nscenes: [crease]\nmethods: [hbao, [gtao]]\n", ":3: methods[1]:", ["expected a non-empty string"]),
    ("name: ../up\neffect: ao\nscenes: [crease]\nmethods: [hbao]\n", ":1: name:", ["output folder"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\nrays: [8, 1]\n", ":4: rays[1]:", ["must be >= 2"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\nblur: gauss\n", ":4: blur:", ["'box'", "null"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\nresolution: [32]\n", ":4: resolution:", ["[width, height]"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\ntiming: {min_run_time: 0}\n", ":4: timing.min_run_time:",
     ["must be a number > 0"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\ntiming: {rounds: 2}\n", ":4: timing.rounds:",
     ["integer >= 3"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\nseeds: []\n", ":4: seeds:", ["empty grid"]),
    ("effect: ao\nmethods: {hbao: {}}\n", ":1: scenes:", ["missing required field"]),
    ("effect: ao\nscenes: [crease]\nmethods: {hbao: {}}\nmethods: {gtao: {}}\n", ":4:", ["duplicate key"]),
    ("effect: ao\nscenes: [crease\n", ":", ["malformed YAML"]),
    ("", ":1:", ["empty sweep file"]),
])
def test_yaml_errors_name_file_line_field_and_valid_names(tmp_path, body, where, words):
    msg = _err(tmp_path, body)
    assert msg.startswith(str(tmp_path / "s.yaml") + where), msg
    for w in words:
        assert w in msg, msg


def test_toml_errors_name_the_line(tmp_path):
    msg = _err(tmp_path, 'effect = "ao"\nscenes = ["crease"]\n\n[methods.hbao]\nradius = [0.5]\nnum_dirs = [4]\n',
               "s.toml")
    assert msg.startswith(str(tmp_path / "s.toml") + ":6: methods.hbao.num_dirs:") and "num_directions" in msg
    msg = _err(tmp_path, 'effect = "ao"\nscenes = [\n', "s.toml")
    assert "malformed TOML" in msg


def test_missing_file_and_type(tmp_path):
    with pytest.raises(SweepError, match="not found"):
        load_sweep(tmp_path / "nope.yaml")
    with pytest.raises(SweepError, match="unknown sweep file type"):
        load_sweep(_write(tmp_path, "effect: ao", "s.json"))
    with pytest.raises(SweepError, match=r"^<sweep>:1: empty sweep file"):
        parse_sweep("")


def test_the_readme_sweep_example_loads_and_has_the_configurations_it_claims(tmp_path):
    import re
    from pathlib import Path
    from ssbench.bench.config import load_sweep
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    block = re.search(r"```yaml\n(name: hbao_steps\n.*?)```", readme, re.S)
    assert block, "the README's minimal sweep example is gone"
    f = tmp_path / "hbao_steps.yaml"
    f.write_text(block.group(1))
    sweep = load_sweep(f)
    n = int(re.search(r"--dry-run` lists the (\d+) configurations", readme).group(1))
    assert len(sweep) == n == 2 * (4 + 2) and sweep.effect == "ao"
