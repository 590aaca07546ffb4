"""Equal depth-read budgets: every declared budget really caps a marcher's reads, and more reads find more."""
from __future__ import annotations

import pytest

from ssbench.analysis.equal_reads import budget_params, equal_read_rows, equal_read_table, read_budget
from ssbench.passes import SSR_METHODS, ssr_method
from tests.passes.ssr_scenes import room

BUDGETED = [m for m in SSR_METHODS if read_budget(m) is not None]


def test_the_marchers_declare_a_budget():
    assert {"linear", "dda", "hiz"} <= set(BUDGETED)


@pytest.mark.parametrize("method", BUDGETED)
@pytest.mark.parametrize("budget", [3, 12])
def test_the_budget_caps_every_rays_reads(method, budget):
    g = room(40, 30)
    fn, params, _ = ssr_method(method)
    kw = budget_params(method, budget, g)
    assert kw[read_budget(method)[0]] == budget
    r = fn(g, params(**kw))
    assert int(r.steps.max()) <= budget and int(r.steps.max()) >= budget - 1   # some ray spends it all


def test_bad_budget_and_undeclared_method(monkeypatch):
    with pytest.raises(ValueError, match="budget"):
        budget_params("dda", 0, room(8, 6))
    from ssbench.passes.ssr import dda
    monkeypatch.delattr(dda, "READ_BUDGET")
    with pytest.raises(ValueError, match="READ_BUDGET"):
        budget_params("dda", 8, room(8, 6))


def test_rows_on_a_real_scene_more_reads_miss_less():
    from ssbench.evaluate import SSR_GT_CHANNELS
    from ssbench.reference import gbuffer, reflections
    chans = tuple(dict.fromkeys(("view_z", "normal", "mask", "color", "metallic", "roughness") + SSR_GT_CHANNELS))
    g = gbuffer("fence", 48, 36, channels=chans, spp=2)
    truth = reflections("fence", g, spp=2)
    rows = equal_read_rows("fence", g, truth, budgets=[4, 96], progress=False)
    assert len(rows) == 2 * len(BUDGETED) and {r["budget"] for r in rows} == {4, 96}
    for m in BUDGETED:
        few, many = (next(r for r in rows if r["method"] == m and r["budget"] == b) for b in (4, 96))
        assert few["reads_mean"] <= 4 and many["reads_mean"] <= 96
        assert many["frac_correct"] > few["frac_correct"], m
    table = equal_read_table(rows)
    assert all(m in table for m in BUDGETED) and "punch-through" in table.splitlines()[0]


def test_layers_select_the_marchers_that_have_them():
    from ssbench.analysis.equal_reads import layered
    assert {"linear", "dda", "hiz"} <= {m for m in BUDGETED if layered(m, "back_faces")}
    assert {"dda", "hiz"} <= {m for m in BUDGETED if layered(m, "second_layer")} and not layered("linear", "second_layer")
    assert not layered("three_ssr") and layered("three_ssr", "front")
    g = room(16, 12)
    assert budget_params("dda", 8, g, "back_faces")["use_back_face_depth"] is True
    assert budget_params("hiz", 8, g, "second_layer")["use_second_layer"] is True
    with pytest.raises(ValueError, match="layered"):
        budget_params("three_ssr", 8, g, "back_faces")
    with pytest.raises(ValueError, match="layers"):
        budget_params("dda", 8, g, "three")
