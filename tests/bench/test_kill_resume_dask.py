"""Acceptance: a sweep killed (SIGKILL) midway and re-run completes with identical rows and no duplicates; the
Dask executor gives the same rows as the local one. Real AO at 32×24 with a few rays."""
import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from ssbench.bench import canonical_json, load_sweep, run_sweep

pytestmark = [pytest.mark.slow, pytest.mark.mitsuba]

SWEEP = """\
    effect: ao
    scenes: [sphere_on_plane, crease]
    methods:
      hbao: {num_directions: [2, 4], num_steps: 2}
    resolution: [32, 24]
    rays: 8
    flip: false
"""

# Runs `ssbench sweep` in a child whose row commits are instrumented: at the KILL_AT-th row it kills itself
# with SIGKILL after the row's temporary file is written and before the rename (the worst moment), or, with
# SLOW_S, it sleeps after each committed row so the parent can SIGKILL it from outside.
CHILD = textwrap.dedent("""\
    import os, signal, sys, time
    import ssbench.bench.rows as R
    from ssbench.cli._sweep_cmd import main
    kill_at, slow = int(os.environ.get("KILL_AT", "0")), float(os.environ.get("SLOW_S", "0"))
    n, real = [0], R._commit
    def commit(tmp, path):
        if os.sep + "rows" + os.sep in path:
            n[0] += 1
            if n[0] == kill_at:
                os.kill(os.getpid(), signal.SIGKILL)
        real(tmp, path)
        if slow and os.sep + "rows" + os.sep in path:
            time.sleep(slow)
    R._commit = commit
    sys.exit(main(sys.argv[1:]))
""")


@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    (d / "small.yaml").write_text(textwrap.dedent(SWEEP))
    return str(d / "small.yaml")


@pytest.fixture(scope="module")
def reference_rows(sweep_file, tmp_path_factory):
    """An uninterrupted local run (it also fills the ground-truth cache the other runs share)."""
    res = run_sweep(sweep_file, tmp_path_factory.mktemp("ref"), progress=False)
    assert len(res.rows) == 4 and not any(r["error"] for r in res.rows)
    return res.rows


def _child(sweep_file, out, **env):
    return subprocess.Popen([sys.executable, "-c", CHILD, "sweep", sweep_file, "--out", str(out), "--quiet"],
                            env={**os.environ, **{k: str(v) for k, v in env.items()}},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _check_resumed(sweep_file, out, reference_rows, done_before):
    res = run_sweep(sweep_file, out, progress=False)
    assert res.skipped == done_before and res.ran == 4 - done_before
    assert sorted(os.listdir(out / "rows")) == sorted(f"{r['config_id']}.json" for r in reference_rows)
    lines = [json.loads(x) for x in open(out / "rows.jsonl").read().splitlines()]
    assert len(lines) == len({r["config_id"] for r in lines}) == 4                   # no duplicates
    assert [canonical_json(r) for r in lines] == [canonical_json(r) for r in reference_rows]
    assert len({r["run_id"] for r in lines}) == (2 if 0 < done_before < 4 else 1)   # two invocations wrote them


def test_kill_between_write_and_rename_then_resume(sweep_file, reference_rows, tmp_path):
    p = _child(sweep_file, tmp_path, KILL_AT=3)
    p.communicate(timeout=240)
    assert p.returncode == -signal.SIGKILL
    assert len(os.listdir(tmp_path / "rows")) == 3                     # 2 rows + the stray temporary file
    assert sum(n.endswith(".tmp") for n in os.listdir(tmp_path / "rows")) == 1
    assert not (tmp_path / "rows.jsonl").exists()
    _check_resumed(sweep_file, tmp_path, reference_rows, done_before=2)
    assert not any(n.endswith(".tmp") for n in os.listdir(tmp_path / "rows"))


def test_external_sigkill_midway_then_resume(sweep_file, reference_rows, tmp_path):
    p = _child(sweep_file, tmp_path, SLOW_S=3)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 240 and p.poll() is None:
        if os.path.isdir(tmp_path / "rows") and any(n.endswith(".json") for n in os.listdir(tmp_path / "rows")):
            break
        time.sleep(0.02)
    p.send_signal(signal.SIGKILL)
    p.communicate(timeout=60)
    done = sum(n.endswith(".json") for n in os.listdir(tmp_path / "rows"))
    assert p.returncode == -signal.SIGKILL and 1 <= done < 4
    _check_resumed(sweep_file, tmp_path, reference_rows, done_before=done)


def test_dask_gives_the_same_rows_as_local(sweep_file, reference_rows, tmp_path):
    pytest.importorskip("dask.distributed")
    res = run_sweep(sweep_file, tmp_path, executor="dask", workers=2, progress=False)
    assert [canonical_json(r) for r in res.rows] == [canonical_json(r) for r in reference_rows]
    meta = json.load(open(tmp_path / "metadata.json"))
    assert meta["executor"]["kind"] == "dask" and meta["executor"]["workers"] == 2
    assert {r["variant"] for r in res.rows} == {meta["backend"]["variant"]} and res.notes == []   # pinned
    assert load_sweep(sweep_file).ids() == [r["config_id"] for r in res.rows]


def test_dask_with_interleaved_timing_gives_the_same_rows(sweep_file, reference_rows, tmp_path):
    pytest.importorskip("dask.distributed")
    plain, inter = tmp_path / "plain.yaml", tmp_path / "inter.yaml"
    plain.write_text(open(sweep_file).read() + "timing: {min_run_time: 0.005, interleave: 0, processes: 1}\n")
    inter.write_text(open(sweep_file).read() + "timing: {min_run_time: 0.005, interleave: 2, processes: 1}\n")
    local = run_sweep(str(plain), tmp_path / "local", progress=False)
    res = run_sweep(str(inter), tmp_path / "out", executor="dask", workers=2, progress=False)
    assert [canonical_json(r) for r in res.rows] == [canonical_json(r) for r in local.rows]
    assert all(canonical_json(r) == canonical_json(dict(q, floor_samples=r["floor_samples"], timing_error=None,
                                                        timing_min_run_time=0.005, timing_processes=1))
               for r, q in zip(res.rows, reference_rows))               # the untimed rows plus timing fields
    assert all(r["floor_ratio"] > 0 and r["time_blocks"] >= 3 and r["timing_error"] is None for r in res.rows)


def test_timing_pooled_over_fresh_processes(sweep_file, reference_rows, tmp_path):
    """``processes: 2``: each group is evaluated and timed again in a child process and the rounds pooled."""
    path = tmp_path / "pooled.yaml"
    path.write_text(open(sweep_file).read() + "timing: {min_run_time: 0.005, rounds: 3, processes: 2}\n")
    res = run_sweep(str(path), tmp_path / "out", progress=False)
    assert all(canonical_json(r) == canonical_json(dict(q, floor_samples=r["floor_samples"], timing_error=None,
                                                        timing_min_run_time=0.005, timing_processes=2))
               for r, q in zip(res.rows, reference_rows))
    assert all(r["time_blocks"] == 6 and r["floor_ratio"] > 0 for r in res.rows)   # 3 rounds in each process
