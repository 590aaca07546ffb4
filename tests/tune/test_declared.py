"""A method declares what may be tuned (``TUNABLE``) and whether the report tunes it (``TUNED_IN_REPORT``) in its
own module: a toy method registered in one module shows up in the tuning space and the report's tuning list."""
import dataclasses
import sys
import types

import pytest

from ssbench.passes import AO_METHODS
from ssbench.report.tuning_section import report_methods
from ssbench.tune.space import SPACES, Tunable, declared_spaces, resolve_space


@dataclasses.dataclass(frozen=True)
class ToyParams:
    radius: float = 0.5
    gain: float = 1.0
    taps: int = 8


@pytest.fixture
def toy(monkeypatch):
    mod = types.ModuleType("ssbench_toy_ao")

    def toy_ao(gbuffer, params, *, generator=None, debug=False):
        raise NotImplementedError("never run here")

    toy_ao.__module__ = mod.__name__
    mod.toy_ao, mod.ToyParams, mod.REQUIRES = toy_ao, ToyParams, ("view_z", "mask")
    mod.TUNABLE = {"radius": (0.5, 2.0, True), "gain": (0.1, 3.0, False)}
    mod.TUNED_IN_REPORT = True
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setitem(AO_METHODS, "toy", "ssbench_toy_ao:toy_ao:ToyParams")
    return mod


def test_a_toy_method_declares_its_space_in_its_own_module(toy):
    spaces = declared_spaces()
    assert spaces["toy"] == (Tunable("radius", 0.5, 2.0, True), Tunable("gain", 0.1, 3.0, False))
    assert "toy" in report_methods() and report_methods()[:2] == ("hbao", "gtao")
    del toy.TUNED_IN_REPORT
    assert "toy" not in report_methods()
    del toy.TUNABLE
    assert "toy" not in declared_spaces()


def test_the_shipped_spaces_come_from_the_pass_modules():
    assert SPACES == declared_spaces() and set(SPACES) == set(AO_METHODS)
    s = resolve_space("gtao", 0.5)
    assert set(s) == {"radius", "falloff_range", "final_value_power"}
    assert s["radius"] == (0.125, 1.5)                                      # relative: 0.25 R ... 3 R
