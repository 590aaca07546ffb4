"""Small multiples: one panel per (method, parameter) with the right points, lines per other parameter value and
scene, categories, per-frame lists, metric tuples, aggregation, and a PNG with one axes per panel."""
import itertools
import math

import numpy as np
import pytest

from ssbench.analysis.multiples import Panel, config_text, panel_lines, small_multiples, varying_keys


def f(k, n, scene):
    return k * 0.01 + n + (10 if scene == "b" else 0)


def _rows():
    rows = []
    for scene, k, n, mode in itertools.product(["a", "b"], [8, 16, 32], [2, 4], ["hash", "none"]):
        over = {"k": k, "n": n, "mode": mode}
        rows.append({"config_id": f"{scene}{k}{n}{mode}", "scene": scene, "method": "m",
                     "params": {**over, "radius": 0.5}, "config": {"params": over, "settings": {"blur": None}},
                     "blur": None, "metric": f(k, n, scene) + (0.5 if mode == "none" else 0.0),
                     "per_frame": [f(k, n, scene) / (i + 1) for i in range(3)], "other": -1.0, "error": None})
    rows.append({**rows[0], "config_id": "bad", "error": "RuntimeError: boom", "metric": 1e9})
    rows.append({**rows[0], "config_id": "other-method", "method": "q"})
    return rows


def test_lines_hold_exactly_the_rows_points():
    d = panel_lines(_rows(), Panel("m", "k", "metric", fix=(("mode", "hash"),)))
    assert d["categories"] is None and d["points"] == 12                  # error row and method q left out
    assert len(d["lines"]) == 4                                              # scene x n
    for ln in d["lines"]:
        scene, n = ln["label"].split(", ")[0], int(ln["label"].split("n=")[1])
        assert ln["x"] == [8.0, 16.0, 32.0] and ln["y"] == pytest.approx([f(k, n, scene) for k in (8, 16, 32)])


def test_categorical_x_fix_and_per_frame():
    d = panel_lines(_rows(), Panel("m", "mode", "metric", fix=(("k", 16), ("n", 2))))
    assert d["categories"] == ["hash", "none"] and len(d["lines"]) == 2
    a = next(ln for ln in d["lines"] if ln["label"] == "a")
    assert a["x"] == [0.0, 1.0] and a["y"] == pytest.approx([f(16, 2, "a"), f(16, 2, "a") + 0.5])
    d = panel_lines(_rows(), Panel("m", "frame", "per_frame", fix=(("k", 8), ("n", 4), ("mode", "none"))))
    (ln_a, ln_b) = d["lines"]
    assert ln_a["x"] == [1.0, 2.0, 3.0] and ln_a["y"] == pytest.approx([f(8, 4, "a") / i for i in (1, 2, 3)])


def test_metric_tuples_and_aggregation_beyond_max_lines():
    d = panel_lines(_rows(), Panel("m", "k", ("metric", "other"), fix=(("mode", "hash"), ("n", 2))))
    assert sorted(ln["label"] for ln in d["lines"]) == ["metric · a", "metric · b", "other · a", "other · b"]
    d = panel_lines(_rows(), Panel("m", "k", "metric"), max_lines=3)      # 8 lines per scene > 3: medians
    assert len(d["lines"]) == 2 and d["points"] == 24
    a = d["lines"][0]
    assert a["label"].startswith("a (median of 4 configs")
    vals = [f(8, n, "a") + dm for n in (2, 4) for dm in (0.0, 0.5)]
    assert a["y"][0] == pytest.approx(float(np.median(vals))) and (a["lo"][0], a["hi"][0]) == (min(vals), max(vals))


def test_helpers():
    rows = _rows()[:-2]
    assert varying_keys(rows) == ["k", "n", "mode"]
    assert config_text(rows[0]) == "k=8, n=2, mode=hash" and config_text(rows[0], ["blur"]) == "blur=none"


def test_png_has_one_panel_per_spec(tmp_path):
    import matplotlib.image as mimage
    panels = [Panel("m", "k", "metric"), Panel("m", "n", "metric"), Panel("m", "mode", "metric"),
              Panel("nobody", "k", "metric")]
    path = tmp_path / "sub" / "multiples.png"
    data = small_multiples(_rows(), panels, str(path), ncols=2, title="t")
    assert [d["panel"] for d in data] == panels and data[3]["lines"] == [] and all(d["lines"] for d in data[:3])
    img = mimage.imread(str(path))
    labels = {ln["label"] for d in data for ln in d["lines"]}             # one legend under the grid, 4 a row
    assert img.shape[:2] == (round(90 * (2.9 * 2 + 0.4 + 0.22 * math.ceil(len(labels) / 4))), round(90 * 3.6 * 2))
    with pytest.raises(ValueError, match="ncols"):
        small_multiples(_rows(), panels, None, ncols=0)
    assert not math.isnan(data[0]["lines"][0]["y"][0])
