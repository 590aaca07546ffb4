"""The AO section's bent-normal and multi-bounce table on a real (small) run: a row per scene and method, bent
normals only where the pass returns them, the baselines beside, the template and summary render it."""
import math

import jinja2
import pytest

from ssbench.report import ao_beyond as B

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]


@pytest.fixture(scope="module")
def beyond():
    return B.build_ao_beyond(48, 36, progress=False)


def test_every_scene_and_method_has_a_row(beyond):
    from ssbench.passes import AO_METHODS
    assert beyond["available"] and not beyond["notes"]
    assert [(r["scene"], r["method"]) for r in beyond["rows"]] == [(s, m) for s in B.SCENES for m in AO_METHODS]
    for r in beyond["rows"]:
        assert math.isnan(r["bent_mean_deg"]) != r["has_bent_normals"]
        assert r["multibounce_rmse"] > 0 and r["bent_truth_stderr_deg"] > 0
    assert {r["method"] for r in beyond["rows"] if r["has_bent_normals"]} >= {"gtao", "vbao"}


def test_template_and_summary_render_the_tables(beyond):
    env = jinja2.Environment(loader=jinja2.PackageLoader("ssbench.report", "templates"), autoescape=True,
                             undefined=jinja2.Undefined)
    html = env.get_template("ao_section.html.j2").render(ao={"available": True, "beyond": beyond, "scenes": []},
                                                         fmt=lambda *a: "–")     # the rest of the section is empty
    assert 'id="ao-beyond"' in html and all(s in html for s in B.SCENES)
    md = "\n".join(B.summary_lines(beyond))
    assert "Beyond AO" in md and md.count("\n| ") >= len(beyond["rows"]) + len(B.SCENES)


def test_rows_go_to_their_own_file():
    from ssbench.report.summary import rows_jsonl
    out = rows_jsonl({"ao": {"rows": [{"a": 1}], "extra_rows": {"ao_beyond": [{"b": float("nan")}]}}})
    assert out["ao"] == '{"effect": "ao", "a": 1}\n' and out["ao_beyond"] == '{"effect": "ao", "b": null}\n'
