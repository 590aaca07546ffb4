"""Disk cache (hits, corruption) and bit-identical results across processes and variants."""
import importlib
import os
import subprocess
import sys

import pytest
import torch

from ssbench.reference import cache, color, gbuffer  # noqa: E402
gb_module = importlib.import_module("ssbench.reference.gbuffer")

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]

DIGEST = ("import hashlib, sys\n"
          "from ssbench.reference import gbuffer, color\n"
          "g = gbuffer('fence', 48, 36, channels=['view_z', 'normal', 'position', 'back_z', 'shape_id', 'mask'],"
          " use_cache=False)\n"
          "h = hashlib.sha256()\n"
          "for k, t in sorted(g.as_dict().items()): h.update(t.numpy().tobytes())\n"
          "h.update(color('fence', 48, 36, spp=8, seed=3, use_cache=False).numpy().tobytes())\n"
          "print(h.hexdigest())\n")


def test_same_seed_same_bits_in_two_processes():
    outs = [subprocess.run([sys.executable, "-c", DIGEST], capture_output=True, text=True, timeout=300)
            for _ in range(2)]
    assert all(o.returncode == 0 for o in outs), outs[0].stderr[-2000:]
    digests = [o.stdout.strip().splitlines()[-1] for o in outs]
    assert digests[0] == digests[1] and len(digests[0]) == 64


def test_color_seeds():
    a = color("crease", 40, 30, spp=8, seed=1, use_cache=False)
    b = color("crease", 40, 30, spp=8, seed=1, use_cache=False)
    c = color("crease", 40, 30, spp=8, seed=2, use_cache=False)
    assert torch.equal(a, b) and not torch.equal(a, c)
    assert a.shape == (1, 3, 30, 40) and a.min() >= 0 and torch.isfinite(a).all()
    with pytest.raises(ValueError, match="spp"):
        color("crease", 40, 30, spp=0)
    with pytest.raises(ValueError, match="seed"):
        color("crease", 40, 30, seed=-1)


def test_color_converges_to_more_samples():
    """Pass-averaged colour is an unbiased estimate: 64 spp is closer to 256 spp than 4 spp is."""
    ref = color("cornell_box", 32, 24, spp=256, seed=7, use_cache=False)
    e4 = (color("cornell_box", 32, 24, spp=4, seed=1, use_cache=False) - ref).abs().mean()
    e64 = (color("cornell_box", 32, 24, spp=64, seed=1, use_cache=False) - ref).abs().mean()
    assert e64 < 0.5 * e4


def test_cache_hit_and_corrupt_entry_recomputed(tmp_path, monkeypatch):
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path))
    first = gbuffer("crease", 24, 18, channels=["view_z", "mask"])
    files = [os.path.join(d, f) for d, _, fs in os.walk(tmp_path) for f in fs if f.endswith(".npz")]
    assert len(files) == 1

    def boom(*a, **k):
        raise AssertionError("rendered although cached")
    monkeypatch.setattr(gb_module, "_render_jit", boom)
    monkeypatch.setattr(gb_module, "_render_scalar", boom)
    again = gbuffer("crease", 24, 18, channels=["view_z", "mask"])           # served from disk
    assert torch.equal(first.view_z, again.view_z)
    monkeypatch.undo()
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path))
    with open(files[0], "r+b") as f:                                         # flip bytes in the middle
        f.seek(os.path.getsize(files[0]) // 2)
        f.write(b"\x00garbage\x00")
    with pytest.warns(RuntimeWarning, match="corrupt"):
        fixed = gbuffer("crease", 24, 18, channels=["view_z", "mask"])
    assert torch.equal(first.view_z, fixed.view_z)
    assert cache.load(os.path.basename(files[0])[:-4]) is not None           # rewritten, valid again


def test_cache_key_depends_on_inputs():
    k = lambda *p: cache.make_key("gbuffer", *p)                            # noqa: E731
    assert k(1, "a", [1, 2]) == k(1, "a", [1, 2])
    assert k(1, "a", [1, 2]) != k(1, "b", [1, 2]) != k(2, "a", [1, 2])


def test_scalar_fallback_matches_llvm():
    code = ("import torch\nfrom ssbench.reference import gbuffer\n"
            "g = gbuffer('fence', 24, 18, channels=['view_z', 'normal', 'shape_id', 'mask', 'back_z'],"
            " use_cache=False)\n"
            "torch.save(g.as_dict(), __import__('sys').argv[1])\n")
    out = {}
    for variant in ("scalar_rgb", "llvm_ad_rgb"):
        path = os.path.join(os.environ["SSBENCH_CACHE_DIR"], f"{variant}.pt")
        r = subprocess.run([sys.executable, "-c", code, path], env=dict(os.environ, SSBENCH_VARIANT=variant,
                           SSBENCH_NO_CUDA="1"), capture_output=True, text=True, timeout=300)
        if r.returncode != 0 and variant == "llvm_ad_rgb" and "no libLLVM" in r.stderr:
            pytest.skip("no working libLLVM on this machine")
        assert r.returncode == 0, r.stderr[-2000:]
        out[variant] = torch.load(path)
    a, b = out["scalar_rgb"], out["llvm_ad_rgb"]
    assert torch.equal(a["mask"], b["mask"]) and torch.equal(a["shape_id"], b["shape_id"])
    for k in ("view_z", "normal", "back_z"):
        fin = torch.isfinite(a[k]) & torch.isfinite(b[k])
        assert torch.equal(torch.isfinite(a[k]), torch.isfinite(b[k]))
        assert (a[k][fin] - b[k][fin]).abs().max() <= 1e-4, k


def test_cache_reports_the_recorded_render_time(tmp_path, monkeypatch):
    """``info=``: a fresh render reports its own time, a cache hit the time recorded when it was rendered."""
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path))
    for render in (lambda info: color("crease", 24, 18, spp=4, info=info),
                   lambda info: gbuffer("crease", 24, 18, channels=["view_z", "mask"], info=info)):
        first, again, off = {}, {}, {}
        a, b = render(first), render(again)
        assert first["cached"] is False and first["seconds"] > 0
        assert again == {"cached": True, "seconds": first["seconds"]}
        meta = {}
        key = os.path.basename(next(os.path.join(d, f) for d, _, fs in os.walk(tmp_path) for f in fs))[:-4]
        assert cache.load(key, meta) is not None and meta["seconds"] > 0 and "sha256" in meta
        monkeypatch.setenv("SSBENCH_CACHE", "0")
        render(off)
        assert off["cached"] is False
        monkeypatch.delenv("SSBENCH_CACHE")
