"""A method declares itself in one module (``METHOD = Method(...)``) and everything finds it: the registries by
discovery inside the package, and a module outside the package through ``SSBENCH_METHODS``. The end-to-end test
writes a toy AO method as one file and sees it in the CLI, a sweep, the tuning space, the report's lists, the
report's speed sweeps and artifact plots, and an actual scored run."""
import json
import os
import subprocess
import sys
import textwrap

import pytest

from ssbench.passes import AO_METHODS, IMPLICIT_METHODS, SSR_METHODS, ao_method, ssr_method
from ssbench.passes.registry import Method, discover, face, merged, plugins, spec

TOY = textwrap.dedent('''
    """A toy AO method kept outside ssbench: AO = 1 − strength on every covered pixel."""
    from dataclasses import dataclass

    import torch

    from ssbench.passes.common import AOResult
    from ssbench.passes.registry import Method, SpeedPanel

    REQUIRES = ("view_z", "mask")
    FLAVOUR = "uniform"
    TUNABLE = {"strength": (0.0, 0.5, False)}
    TUNED_IN_REPORT = True


    @dataclass(frozen=True)
    class ToyParams:
        strength: float = 0.1
        radius: float = 0.5          # the ground truth's radius (the pass ignores it)
        seed: int = 0


    def toy_ao(gbuffer, params=ToyParams(), *, generator=None, debug=False):
        ao = torch.where(gbuffer.mask, 1.0 - params.strength, 1.0).to(gbuffer.view_z.dtype)
        return AOResult(ao=ao)


    def samples_per_pixel(params):
        return 1


    METHOD = Method("toyao", toy_ao, ToyParams, effect="ao", order=5)
    SPEED_GRIDS = {"cost": [{"strength": [0.1, 0.3]}]}
    SPEED_PANELS = (SpeedPanel("banding", "strength", (("blur", None),)),)
''')


@pytest.fixture
def toy_env(tmp_path):
    (tmp_path / "toy_ao_plugin.py").write_text(TOY)
    env = dict(os.environ, SSBENCH_METHODS="toy_ao_plugin",
               PYTHONPATH=os.pathsep.join([str(tmp_path), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return env


def _run(args, env, cwd):
    return subprocess.run([sys.executable, *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=600)


def test_the_registries_are_the_declared_methods_in_order():
    assert list(AO_METHODS) == ["crytek", "ssao", "hbao", "gtao", "sao", "vbao", "three_gtao"]
    assert list(SSR_METHODS) == ["linear", "dda", "dda_supercover", "hiz", "three_ssr", "glossy_stochastic",
                                 "glossy_blur"]
    assert list(IMPLICIT_METHODS) == ["fixed", "sphere", "progressive"]
    for methods in (discover("ssbench.passes.ao", "ao"), discover("ssbench.passes.ssr", "ssr")):
        for m in methods:
            assert AO_METHODS.get(m.name, SSR_METHODS.get(m.name)) == spec(m)
    fn, params, requires = ao_method("hbao")
    assert fn.__module__ == "ssbench.passes.ao.hbao" and params.__name__ == "HBAOParams" and "view_z" in requires


def test_declarations_and_plugin_lists_are_checked(tmp_path, monkeypatch):
    def f(g, p):
        return None

    class P:
        pass

    with pytest.raises(ValueError, match="name"):
        Method("not a name", f, P)
    with pytest.raises(ValueError, match="effect"):
        Method("x", f, P, effect="fog")
    with pytest.raises(TypeError, match="params"):
        Method("x", f, P())
    with pytest.raises(ValueError, match="SSBENCH_METHODS: cannot import 'no_such_module_here'"):
        plugins("no_such_module_here")
    (tmp_path / "plug_none.py").write_text("X = 1\n")
    (tmp_path / "plug_noeffect.py").write_text(
        "from ssbench.passes.registry import Method\nclass P: pass\ndef f(g, p): pass\nMETHOD = Method('x', f, P)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ValueError, match="declares no METHOD"):
        plugins("plug_none")
    with pytest.raises(ValueError, match="must name its effect"):
        plugins(" plug_noeffect , ")
    taken = Method("hbao", f, P, effect="ao")
    with pytest.raises(ValueError, match="hbao already names a built-in ao method"):
        merged(discover("ssbench.passes.ao", "ao"), [taken], "ao")
    assert [m.name for m in merged(discover("ssbench.passes.ao", "ao"), [taken], "ssr")] == list(AO_METHODS)
    with pytest.raises(ValueError, match="public name 'f'"):
        face([Method("a", f, P), Method("b", lambda g, p: None, type("Q", (), {}), module=None)]
             + [Method("c", type("f", (), {"__call__": lambda self: None}), P)])


@pytest.mark.slow
def test_a_toy_method_in_one_module_is_seen_everywhere(toy_env, tmp_path):
    env, cwd = toy_env, tmp_path
    r = _run(["-m", "ssbench", "ao", "--help"], env, cwd)
    choices = "{" + ",".join(["toyao", *AO_METHODS]) + "}"                   # the plugin first, then the built-ins
    assert r.returncode == 0 and choices in r.stdout.replace("\n", "").replace(" ", ""), r.stderr
    (tmp_path / "s.yaml").write_text("effect: ao\nscenes: [crease]\nmethods: {toyao: {strength: [0.1, 0.2]}}\n")
    r = _run(["-m", "ssbench", "sweep", str(tmp_path / "s.yaml"), "--dry-run"], env, cwd)
    assert r.returncode == 0 and "2 configurations of effect ao" in r.stdout, r.stderr
    assert "crease toyao strength=0.1" in r.stdout
    probe = textwrap.dedent('''
        import json
        from ssbench.passes import AO_METHODS, toy_ao, ToyParams
        from ssbench.tune.space import declared_spaces
        from ssbench.report.tuning_section import report_methods
        from ssbench.bench.effects import ao_samples
        from ssbench.report import speed_section as S
        sweeps = S.load_embedded(S.default_sweeps()["ao"], (16, 12), 0)
        panels = S.figures("ao")["banding"][1]
        print(json.dumps({"first": list(AO_METHODS)[0], "space": [t.name for t in declared_spaces()["toyao"]],
                          "tuned": "toyao" in report_methods(), "samples": ao_samples("toyao", ToyParams()),
                          "face": toy_ao.__module__,
                          "speed": sorted(c.params["strength"] for s in sweeps for c in s.configs
                                          if c.method == "toyao"),
                          "panel": [(p.param, p.metric) for p in panels if p.method == "toyao"]}))
    ''')
    r = _run(["-c", probe], env, cwd)
    assert r.returncode == 0, r.stderr
    seen = json.loads(r.stdout)
    assert seen == {"first": "toyao", "space": ["strength"], "tuned": True, "samples": 1, "face": "toy_ao_plugin",
                    "speed": [0.1, 0.1, 0.3, 0.3],                   # its grid on both scenes of the speed sweep
                    "panel": [["strength", "banding"]]}


@pytest.mark.slow
@pytest.mark.mitsuba
def test_the_toy_method_runs_and_is_scored(toy_env, tmp_path):
    r = _run(["-m", "ssbench", "ao", "sphere_on_plane", "--method", "toyao", "--param", "strength=0.25",
              "--width", "16", "--height", "12", "--rays", "8", "--repeats", "1", "--json"], toy_env, tmp_path)
    assert r.returncode == 0, r.stderr
    row = json.loads(r.stdout[r.stdout.index("{"):])
    assert row["method"] == "toyao" and row["params"] == {"strength": 0.25, "radius": 0.5, "seed": 0}
    assert row["weighting"] == "uniform" and row["nonfinite"] == 0 and row["radius"] == 0.5
    assert 0 < row["rmse_flavour"] < 1 and 0 < row["rmse_cos"] < 1          # scored against the ray-traced truth


def test_every_screen_space_pass_takes_the_one_call():
    """AO and SSR: ``fn(gbuffer, params, *, generator=None, debug=False)``, the same for every declared method."""
    import inspect

    import torch

    from tests.passes.ssr_scenes import room
    g = room()
    for name, resolve in [(n, ao_method) for n in AO_METHODS] + [(n, ssr_method) for n in SSR_METHODS]:
        fn, params_cls, _ = resolve(name)
        sig = inspect.signature(fn).parameters
        assert list(sig)[:2] == ["gbuffer", "params"], name
        for kw in ("generator", "debug"):
            assert sig[kw].kind is inspect.Parameter.KEYWORD_ONLY and sig[kw].default in (None, False), (name, kw)
        out = fn(g, params_cls(), generator=torch.Generator().manual_seed(0), debug=False)
        assert out is not None, name
