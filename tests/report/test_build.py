"""build_report: run dir + latest copy, relative image links that resolve, metadata, summary.md."""
import json
import os
import re

import pytest

from ssbench.report.build import PREVIEW_ROW, build_report, git_state, refresh_latest

SCENES = ["sphere_on_plane", "crease"]


@pytest.fixture(autouse=True)
def _cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("reports")
    mp = pytest.MonkeyPatch()
    mp.setenv("SSBENCH_CACHE_DIR", str(root / "cache"))
    try:
        index = build_report(str(root / "reports"), scenes=SCENES, width=48, height=36, spp=4, progress=False)
    finally:
        mp.undo()
    return root / "reports", index


@pytest.mark.slow
@pytest.mark.mitsuba
def test_run_dir_and_latest(report):
    root, index = report
    run_dir = os.path.dirname(index)
    assert os.path.isfile(index) and os.path.dirname(run_dir) == str(root)
    assert re.fullmatch(r"\d{8}-\d{6}(-\d+)?", os.path.basename(run_dir))
    latest = root / "latest"
    for d in (run_dir, latest):
        for f in ("index.html", "summary.md", "meta.json"):
            assert os.path.isfile(os.path.join(d, f)), (d, f)
    assert not [n for n in os.listdir(root) if n.startswith(".")]            # no temporaries left behind


@pytest.mark.slow
@pytest.mark.mitsuba
def test_latest_images_resolve(report):
    import matplotlib.image as mimage
    latest = report[0] / "latest"
    html = (latest / "index.html").read_text()
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]+)"', html)
    assert len(srcs) == len(SCENES) * (1 + len(PREVIEW_ROW))
    for src in srcs:
        assert not os.path.isabs(src) and "://" not in src
        path = latest / src
        assert path.is_file() and src.endswith(".png"), src
    assert mimage.imread(str(latest / srcs[0])).shape[:2] == (36, 48)
    for name in SCENES:
        assert name in html


@pytest.mark.slow
@pytest.mark.mitsuba
def test_metadata(report):
    latest = report[0] / "latest"
    meta = json.loads((latest / "meta.json").read_text())
    html = (latest / "index.html").read_text()
    summary = (latest / "summary.md").read_text()
    commit = git_state()["commit"]
    assert meta["git"]["commit"] == commit and commit in html and commit in summary
    variant = meta["environment"]["variant"]
    assert variant in ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb") and variant in html and variant in summary
    assert [s["name"] for s in meta["scenes"]] == SCENES
    for s in meta["scenes"]:
        assert s["timings"]["gbuffer_s"] > 0 and s["timings"]["color_s"] > 0
        assert f"| {s['name']} |" in summary
    for key in ("torch", "mitsuba", "drjit", "kornia", "numpy", "python", "torch_threads", "drjit_threads",
                "node", "cpu_count"):
        assert key in meta["environment"]
    assert meta["total_s"] > 0 and meta["width"] == 48 and meta["spp"] == 4


def test_refresh_latest_replaces_previous_copy(tmp_path):
    root = tmp_path / "r"
    for run, text in (("a", "first"), ("b", "second")):
        os.makedirs(root / run / "img")
        (root / run / "index.html").write_text(text)
        (root / run / "img" / f"{run}.png").write_text(run)
        refresh_latest(str(root / run), str(root))
        assert (root / "latest" / "index.html").read_text() == text
    assert sorted(os.listdir(root / "latest" / "img")) == ["b.png"]         # a full copy, not a merge
    assert sorted(os.listdir(root)) == ["a", "b", "latest"]


def test_unknown_scene_is_rejected_before_rendering(tmp_path):
    with pytest.raises(ValueError, match="scenes: unknown"):
        build_report(str(tmp_path / "x"), scenes=["nope"])
    assert not (tmp_path / "x").exists()


def test_git_state_outside_a_repo(tmp_path):
    assert git_state(str(tmp_path)) == {"commit": "unknown", "dirty": None}
