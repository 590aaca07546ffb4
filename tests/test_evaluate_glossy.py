"""Glossy evaluation: the error split responds to what it names, on the glossy_ramp scene."""
from __future__ import annotations

import math

import pytest

from ssbench.evaluate import ROUGHNESS_EDGES, run_glossy


@pytest.fixture(scope="module")
def runs():
    out, g, truth = {}, None, None
    for m in ("dda", "glossy_blur", "glossy_stochastic"):
        ev = run_glossy("glossy_ramp", m, width=64, height=48, rays=32, spp=4, warmup=False, gbuffer=g, truth=truth)
        g, truth = ev.gbuffer, ev.truth
        out[m] = ev
    return out


def test_row_keys_and_bins(runs):
    r = runs["dda"].row
    for k in ("mae_lobe", "mae_vs_oracle", "mae_oracle", "mae_specular", "mae_resolve_only", "rmse_lobe_net",
              "rmse_oracle_net", "rmse_vs_oracle_net", "truth_se_mean", "seconds"):
        assert isinstance(r[k], float) and math.isfinite(r[k]), k
    assert [(b["lo"], b["hi"]) for b in r["bins"]] == list(zip(ROUGHNESS_EDGES[:-1], ROUGHNESS_EDGES[1:]))
    assert sum(b["n"] for b in r["bins"]) == r["glossy_pixels"] and r["nonfinite"] == 0
    assert r["rmse_lobe_net"] <= r["rmse_lobe"] and r["rmse_oracle_net"] <= r["rmse_oracle"]
    # the information loss and the resolve-only error do not depend on the method
    assert runs["glossy_blur"].row["mae_oracle"] == r["mae_oracle"]
    assert runs["glossy_blur"].row["mae_resolve_only"] == r["mae_resolve_only"]


def test_a_mirror_marcher_falls_behind_as_roughness_grows(runs):
    """The mirror DDA ignores roughness: against the oracle its error must grow from the mirror strip to the
    roughest; a glossy method must beat it on the rough strips."""
    dda = [b for b in runs["dda"].row["bins"] if b["n"] > 20]
    assert dda[0]["lo"] == 0.0 and dda[-1]["hi"] >= 0.6
    assert dda[-1]["mae_vs_oracle"] > 2 * dda[0]["mae_vs_oracle"]
    rough = lambda m: sum(b["mae_vs_oracle"] for b in runs[m].row["bins"] if b["lo"] >= 0.15 and b["n"] > 20)  # noqa
    assert rough("glossy_blur") < rough("dda") and rough("glossy_stochastic") < rough("dda")


def test_bad_arguments():
    with pytest.raises(ValueError, match="rays"):
        run_glossy("glossy_ramp", "dda", rays=1, width=8, height=6)
    with pytest.raises(KeyError, match="method"):                # as ssbench.evaluate.ssr does
        run_glossy("glossy_ramp", "nope", width=8, height=6)
