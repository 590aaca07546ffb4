"""Per-configuration pictures of a sweep (``images: true``): two PNGs per configuration named by its id, rows that
name them, ids that do not change, resume that fills in missing pictures, a drawing failure that keeps the row,
and the three effects' drawings on real evaluations."""
import dataclasses
import os
import types

import numpy as np
import pytest
import torch

from ssbench.bench import SweepError, run_sweep, sweep_from_dict
from ssbench.bench import effects as E
from ssbench.bench.pictures import AO_PICTURES, ColourScale, Pictures, ao_pictures, write_pictures

from .conftest import CALLS, TOY


def _draw(ev):
    """The toy's image: its depth as grey; its 'error': red where x > 1."""
    z = ev.gbuffer.view_z[0, 0].neg().clamp(0, 1).numpy()
    grey = (np.repeat(z[..., None], 3, -1) * 255).astype(np.uint8)
    return grey, np.where(z[..., None] < 1.0, grey, np.array([255, 0, 0], np.uint8))


TOY_PICTURES = Pictures(_draw, "depth", "x > 1 in red", ColourScale("gray", 0.0, 1.0, "depth"))


@pytest.fixture
def drawn(toy, monkeypatch):
    monkeypatch.setitem(E.EFFECTS, "toy", dataclasses.replace(TOY, pictures=TOY_PICTURES))


def _sweep(**extra):
    data = {"effect": "toy", "scenes": ["crease"], "methods": {"toy": {"x": [0.5, 2, 3]}}, "resolution": [6, 4]}
    data.update(extra)
    return sweep_from_dict(data, source="toy.yaml")


def test_images_write_two_pngs_per_configuration_and_keep_config_ids(drawn, tmp_path):
    import matplotlib.image as mimage
    plain, pics = _sweep(), _sweep(images=True)
    assert pics.images and not plain.images and pics.ids() == plain.ids()   # a view of the run, not a configuration
    res = run_sweep(pics, tmp_path, progress=False)
    ok = [r for r in res.rows if not r["error"]]
    assert len(ok) == 2 and all(r.get("images") is None for r in res.rows if r["error"])   # x = 2 fails: no pictures
    for r in ok:
        assert r["images"] == {"image": f"img/{r['config_id']}.png", "error": f"img/{r['config_id']}_error.png"}
        img, err = (mimage.imread(tmp_path / r["images"][k]) for k in ("image", "error"))
        assert img.shape[:2] == err.shape[:2] == (4, 6)
        red = (err[..., 0] > 0.99) & (err[..., 1] < 0.01)
        assert red.all() == (r["params"]["x"] > 1) and not red.any() == (r["params"]["x"] <= 1)
    assert sorted(os.listdir(tmp_path / "img")) == sorted(p for r in ok for p in
                                                          (f"{r['config_id']}.png", f"{r['config_id']}_error.png"))
    assert "images" not in run_sweep(plain, tmp_path / "plain", progress=False).rows[0]


def test_resume_draws_the_pictures_a_stored_row_lacks(drawn, tmp_path):
    run_sweep(_sweep(), tmp_path, progress=False)
    CALLS.clear()
    again = run_sweep(_sweep(images=True), tmp_path, progress=False)
    assert again.ran == 2 and again.skipped == 1 and {c[2]["x"] for c in CALLS} == {0.5, 3.0}   # not the error row
    CALLS.clear()
    assert run_sweep(_sweep(images=True), tmp_path, progress=False).ran == 0 and CALLS == []


def test_a_drawing_failure_keeps_the_row_and_says_why(toy, tmp_path):
    res = run_sweep(_sweep(images=True), tmp_path, progress=False)       # the toy effect declares no pictures
    r = res.rows[0]
    assert r["error"] is None and r["value"] > 0 and r["images"] is None
    assert r["images_error"] == "ValueError: effect 'toy' declares no pictures"


def test_images_must_be_a_boolean(toy):
    with pytest.raises(SweepError, match=r"images: expected true or false, got 'yes'"):
        _sweep(images="yes")


def test_a_drawing_that_is_no_rgb_image_is_refused(tmp_path):
    bad = Pictures(lambda ev: (np.zeros((4, 6), np.float32), None), "a", "b")
    with pytest.raises(ValueError, match="uint8"):
        write_pictures(bad, None, str(tmp_path), "abc")
    ok = Pictures(lambda ev: (np.zeros((4, 6, 3), np.uint8), None), "a", "b")
    assert write_pictures(ok, None, str(tmp_path), "abc") == {"image": "img/abc.png", "error": None}


def test_ao_error_picture_is_red_where_too_dark_and_blue_where_too_bright():
    ao = torch.tensor([[[[0.2, 0.9, 0.5]]]])
    truth = torch.tensor([[[[0.6, 0.5, 0.5]]]])
    mask = torch.tensor([[[[True, True, False]]]])
    ev = types.SimpleNamespace(ao=ao, gbuffer=types.SimpleNamespace(mask=mask),
                               references={"cos": types.SimpleNamespace(ao=truth)})
    image, error = ao_pictures(ev)
    assert image[0, :, 0].tolist() == [51, 230, 0]                        # grey levels, background black
    (r0, g0, b0), (r1, g1, b1), bg = error[0].astype(int)
    assert r0 > b0 + 60 and b1 > r1 + 60 and bg.tolist() == [0, 0, 0]   # too dark: red; too bright: blue
    assert AO_PICTURES.scale.vmin == -AO_PICTURES.scale.vmax              # a symmetric scale: white is exact


@pytest.mark.slow
@pytest.mark.mitsuba
@pytest.mark.parametrize("effect,scene,method", [("ao", "crease", "gtao"), ("ssr", "reflective_floor", "linear"),
                                                 ("implicit", "thin_plate", "fixed")])
def test_each_effect_draws_its_evaluation(effect, scene, method, tmp_path, monkeypatch):
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))
    eff = E.get_effect(effect)
    settings = {"ao": {"rays": 4, "oracle": False, "flip": False}, "ssr": {"spp": 1, "flip": False},
                "implicit": {}}[effect]
    ev = eff.run(scene, method, {}, width=20, height=14, seed=0, settings=settings)
    pics = eff.picture_spec()
    image, error = pics.draw(ev)
    assert image.shape == error.shape == (14, 20, 3) and image.dtype == error.dtype == np.uint8
    assert image.std() > 0 and error.std() > 0                            # a picture, not a blank
    assert (pics.scale is None) == (pics.classes is not None)             # read by a colour bar or a class legend
