# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Lesson 9 — Reading a report: speed against error, Pareto fronts, tuning
#
# ## Overview
#
# Lessons 2–8 took one method at a time and asked *what goes wrong, and why*. A report asks the question an
# engineer has to answer next: **which configuration should I ship?** That needs many configurations, each
# scored against the same ground truth and timed the same way, and a few ways of reading the pile:
#
# one tidy row per run → a sweep (a grid of configurations, as data) → error against time and the **Pareto
# front** → time in units of the **gather floor**, which survives a noisy machine → the **equal-error cost**: what
# the same error costs with the ray tracer itself → **small multiples** of the artifacts the articles show
# (SSAO article's banding, Fig. 5, and halos, Figs. 7–9) → **tuning**, default vs tuned on scenes the tuner never
# saw → a real report folder, and `ssbench report --compare` between two runs.
#
# These are the parts of the issue-6 report (`ssbench report`): sweeps and timing (`ssbench.bench`), the
# speed section (§3: fronts, equal-error cost, small multiples; `ssbench/report/speed_section.py`) and the tuning
# section (§4; `ssbench.tune`). Everything here is tiny (a 96 × 72 image, 48 × 36 in the tests) and seeded; the
# report runs the same code on more scenes and configurations.
#
# > **You will learn**
# > 1. what the columns of one evaluation row mean: errors against the cosine ground truth, artifact metrics,
# >    the ground truth's own noise, time;
# > 2. how a sweep is written (a dict or a YAML file), run (resumable, one atomic row per configuration) and what
# >    it leaves on disk;
# > 3. how to read an error-vs-time scatter, and the Pareto front re-derived in five lines;
# > 4. why the report prints `floor_ratio = time / gather floor` next to the time;
# > 5. the equal-error cost: how many ray-traced AO rays reach a method's error (σ/√n);
# > 6. how the report's small multiples show banding vs sample count and noise tile, and halos vs the range
# >    check and the blur — and what the `banding` and `tile_energy` columns each measure;
# > 7. what tuning buys on training scenes and on held-out ones;
# > 8. where `index.html`, `summary.md`, `rows/*.jsonl` and the images of a report run are, and how two runs
# >    are compared.

# %% [markdown]
# ## Setup
#
# The scene is `stairs` (steps and risers: contact creases, depth edges, large flat treads), at 96 × 72 (the
# report's speed sweeps run at up to `speed_section.SIZE`, 160 × 120), the ground truth cosine-weighted ray-traced AO at
# radius 0.5. Every file this lesson writes goes to a fresh temporary folder, printed below.

# %%
import json
import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from ssbench import evaluate, metrics
from ssbench.analysis import (Panel, ao_ladder, best_rows, config_text, dominates, equal_error_n, equal_error_table,
                              error_time_figure, pareto_rows, row_time_ms, small_multiples)
from ssbench.bench import TimingSpec, canonical_json, run_config, run_sweep, sweep_from_dict
from ssbench.bench.effects import ao_samples
from ssbench.bench.timing import round_fields
from ssbench.cli import main as ssbench_cli
from ssbench.passes import AO_METHODS
from ssbench.passes.ao.hbao import HBAOParams
from ssbench.report import speed_section
from ssbench.report.build import build_report
from ssbench.tune import tune
from _setup import pick, size

W, H = size((96, 72))                                # smaller than the report's sweeps (160 x 120), to stay quick
RAYS = pick(128, 64)                                 # ground-truth rays per pixel (the report's sweeps: 128)
RADIUS = 0.5                                         # the passes' radius and the ground truth's
SCENE = "stairs"
OUT = Path(tempfile.mkdtemp(prefix="ssbench-lesson09-"))
COLORS = {"hbao": "tab:blue", "gtao": "tab:orange", "ssao": "tab:green"}     # as the report draws them

checks = {}


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name


def bare(*axes):
    for a in axes:
        a.set_xticks([]), a.set_yticks([])


def show_png(ax, path, title):
    ax.imshow(plt.imread(path)), ax.set_title(title, fontsize=8), ax.axis("off")


def log_ms(ax):
    """A log time axis labelled 1, 2, 5, 10, … (plain numbers)."""
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def knobs(r):
    """A row's configuration as the report prints it: the parameters the sweep set, radius left out."""
    return config_text(r, [k for k in r["config"]["params"] if "radius" not in k])


print(f"{W}x{H}, {RAYS} ground-truth rays, files under {OUT}")

# %% [markdown]
# ## 1. One tidy row (`ssbench.evaluate.ao`)
#
# Everything in a report starts as one **row**: one method, one parameter set, one scene, scored against the
# ray-traced ground truth. `evaluate.run_ao` returns the row and the images behind it (`evaluate.ao` the row
# alone). Its columns come in groups:
#
# * *what ran*: `scene, method, params` (every parameter, defaults included), `width, height, radius, rays, seed`;
# * *error* against each target, `<metric>_<target>`: `cos` is cosine-weighted AO, the common yardstick;
#   `flavour` the quantity the pass itself estimates (HBAO: obscurance, SSAO: the volume fraction of its kernel,
#   `volume_hemisphere`; lesson 2 Step 4b, lesson 3 Step 7);
# * *artifacts*: `halo_band` (mean |error| within 4 px of a depth edge, SSAO article Figs. 7–9), `flat_bias`
#   (occlusion added on open flat ground), `banding` (the error left after a 1.5-px blur: Fig. 5's bands),
#   `tile_energy` (the share of the image at the noise-tile frequency), `noise`;
# * `gt_stderr_cos`: the ground truth's own standard error — no method can be scored more finely than this;
# * *time*: `seconds`, the median of `repeats` calls. A sweep adds the careful timing of Step 4.
#
# Below, the row's RMSE, bias and halo-band error are re-computed from the images it came from.

# %%
HBAO_4x4 = {"radius": RADIUS, "num_directions": 4, "num_steps": 4}
ev = evaluate.run_ao(SCENE, "hbao", HBAO_4x4, width=W, height=H, rays=RAYS, oracle=False)
row = ev.row
gt_ref = ev.references["cos"]
gt, mask, view_z = gt_ref.ao.float(), ev.gbuffer.mask, ev.gbuffer.view_z
err = (ev.ao - gt)[mask]
halo = metrics.halo(ev.ao, gt, view_z, mask, band=4)
check("rmse_cos = sqrt(mean((AO - cosine AO)^2)) over the mask",
      math.isclose(row["rmse_cos"], float(err.pow(2).mean().sqrt()), rel_tol=1e-5))
check("bias_cos = mean(AO - cosine AO): positive means too bright", math.isclose(row["bias_cos"], float(err.mean()),
                                                                                rel_tol=1e-5, abs_tol=1e-7))
check("halo_band_cos = mean |error| within 4 px of a depth edge", math.isclose(row["halo_band_cos"], float(halo.band),
                                                                               rel_tol=1e-5))
check("gt_stderr_cos is the ground truth's mean standard error",
      math.isclose(row["gt_stderr_cos"], float(metrics.masked_mean(gt_ref.stderr.float(), mask)), rel_tol=1e-5))

groups = {"what ran": ["scene", "method", "params", "width", "height", "radius", "rays", "seed"],
          "error vs cosine AO": ["rmse_cos", "mae_cos", "bias_cos", "ssim_cos", "flip_cos"],
          "error vs its flavour": ["weighting", "rmse_flavour"],
          "artifacts": ["halo_band_cos", "halo_elsewhere_cos", "flat_bias_cos", "banding", "tile_energy", "tile",
                        "noise"],
          "ground truth's noise": ["gt_stderr_cos"], "time": ["seconds", "repeats", "threads"]}
for group, keys in groups.items():
    cells = [f"{k}={row[k]:.4g}" if isinstance(row[k], float) else f"{k}={row[k]}" for k in keys]
    print(f"{group:>22}: " + ", ".join(cells))
print(f"{'… and':>22}: {len(row) - sum(map(len, groups.values()))} more columns")

fig, ax = plt.subplots(1, 4, figsize=(14, 3.0), layout="constrained")
ax[0].imshow(ev.ao[0, 0], cmap="gray", vmin=0, vmax=1), ax[0].set_title(f"HBAO 4×4, RMSE {row['rmse_cos']:.3f}")
ax[1].imshow(gt[0, 0], cmap="gray", vmin=0, vmax=1), ax[1].set_title(f"cosine AO, {RAYS} rays")
im = ax[2].imshow((ev.ao - gt)[0, 0].masked_fill(~mask[0, 0], 0), cmap="RdBu", vmin=-0.5, vmax=0.5)
ax[2].set_title(f"HBAO − truth (blue: too bright, red: too dark)\nbias {row['bias_cos']:+.3f}", fontsize=9)
fig.colorbar(im, ax=ax[2], shrink=0.8)
ax[3].imshow(halo.band_mask[0, 0], cmap="gray"), ax[3].set_title(f"halo band: error {row['halo_band_cos']:.3f}\n"
                                                                  f"elsewhere {row['halo_elsewhere_cos']:.3f}",
                                                                  fontsize=9)
bare(*ax)
fig.suptitle("Step 1 — one row: the pass, the ground truth, the error and where halos are measured (002 Figs. 7–9)")
plt.show()

# %% [markdown]
# ## 2. A sweep is data (`ssbench.bench`)
#
# A sweep names an effect, scenes, a resolution, the ground truth's settings and, per method, a **grid** of
# parameters; every combination is one configuration. It can live in a YAML file (the report's are
# `ssbench/report/sweeps/*.yaml`) or, as here, in a dict: `sweep_from_dict` validates it (a wrong parameter name
# is an error naming the valid ones) and expands the grids. `run_sweep` runs every configuration once and writes
# each row atomically as `rows/<config_id>.json` the moment it is done, so a killed sweep resumes where it
# stopped; at the end it writes the whole table as `rows.jsonl` and `rows.parquet`.
#
# The `timing` block turns on careful timing (Step 4), here in this process only (`processes: 1`, an overview).
# `flip: false` skips ꟻLIP, the slowest metric.

# %%
SWEEP = {
    "name": "lesson09_stairs", "effect": "ao", "scenes": [SCENE], "resolution": [W, H],
    "rays": RAYS, "oracle": False, "flip": False,
    "timing": {"min_run_time": 0.01, "warmup": 0, "processes": 1},
    "methods": {
        "hbao": {"radius": RADIUS, "num_directions": [2, 4, 8], "num_steps": [2, 4]},
        "gtao": {"radius": RADIUS, "quality": ["low", "medium", "high", "ultra"]},
        "ssao": {"kernel_radius": RADIUS, "kernel_size": [4, 8, 16, 32], "noise_size": [1, 4]},
    },
}
sweep = sweep_from_dict(SWEEP)
sweep_dir = OUT / "sweeps" / sweep.name
result = run_sweep(sweep, str(sweep_dir), progress=False)
rows = result.rows
check("one configuration per grid point: 3×2 HBAO + 4 GTAO + 4×2 SSAO = 18", len(sweep) == 18)
check("one row per configuration, none failed", len(rows) == len(sweep) and result.errors == 0
      and [r["config_id"] for r in rows] == sweep.ids())
with open(sweep_dir / "rows.jsonl", encoding="utf-8") as f:
    check("rows.jsonl holds the same number of rows", sum(1 for line in f if line.strip()) == len(sweep))
again = run_sweep(sweep, str(sweep_dir), progress=False)
check("running it again resumes: every configuration already has its row", again.ran == 0
      and again.skipped == len(sweep))
print(f"{len(rows)} rows in {sum(r['elapsed_s'] for r in rows):.1f} s; the folder holds:",
      sorted(p.name for p in sweep_dir.iterdir()))

labels = [f"{r['method']} {knobs(r)}" for r in rows]
fig, ax = plt.subplots(1, 2, figsize=(12, 5.2), layout="constrained", sharey=True)
y = np.arange(len(rows))
ax[0].barh(y, [r["rmse_cos"] for r in rows], color=[COLORS[r["method"]] for r in rows])
ax[0].set_yticks(y, labels, fontsize=7), ax[0].invert_yaxis(), ax[0].set_xlabel("rmse_cos")
ax[1].barh(y, [r["time_median_ms"] for r in rows], color=[COLORS[r["method"]] for r in rows])
ax[1].set_xlabel("time_median_ms (one call of the pass)")
fig.suptitle(f"Step 2 — the sweep's {len(rows)} rows, one bar each (stairs, {W}×{H})")
plt.show()

# %% [markdown]
# GTAO `low` (one slice, two steps per side) is far off: one slice — one direction across the screen — per
# pixel is a noisy estimate, and XeGTAO relies on a denoiser this sweep does not run. A report is full of such
# rows; the next steps are ways of not being lost in them.
#
# ## 3. Error against time, and the Pareto front
#
# Plot every configuration at (time, error). A configuration is **dominated** when another one is at least as
# fast *and* at least as accurate (and strictly better in one). The ones nobody dominates form the **Pareto
# front**: the only configurations worth shipping, whichever way you trade speed for quality. Sorted by time,
# the front is simply every row that beats the best error seen so far — five lines. `ssbench.analysis` computes
# it vectorised (`pareto_mask`, with ties kept and NaN rows left out); the two must agree, and a brute-force
# check with `dominates` confirms the definition. The report draws one such panel per scene and error metric
# (`error_time_figure`), the front as a staircase: the edge of what can be had.

# %%
def front_by_hand(rows, error):
    """The Pareto front of (time, error): sort by time, keep each row that improves on the best error so far."""
    front, best = [], math.inf
    for t, e, cid in sorted((row_time_ms(r), r[error], r["config_id"]) for r in rows if not r["error"]):
        if e < best:
            front.append(cid)
            best = e
    return front


by_id = {r["config_id"]: r for r in rows}
front = front_by_hand(rows, "rmse_cos")
library_front, on_front = pareto_rows(rows, "rmse_cos")
check("the front re-derived by hand equals ssbench.analysis.pareto_rows",
      front == [r["config_id"] for r in library_front])
check("… and the front the report's figure draws (error_time_figure)",
      [r["config_id"] for r in error_time_figure(rows, [("rmse_cos", "RMSE")])[SCENE, "rmse_cos"]] == front)
pt = {c: (r["rmse_cos"], row_time_ms(r)) for c, r in by_id.items()}
check("brute force: every other row is dominated by a front row, no front row by anything",
      all(any(dominates(pt[f], pt[c]) for f in front) for c in pt if c not in front)
      and not any(dominates(pt[a], pt[f]) for f in front for a in pt))

fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), layout="constrained")
for ax, metric in zip(axes, ["rmse_cos", "halo_band_cos"]):
    for m in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == m]
        ax.scatter([row_time_ms(r) for r in mine], [r[metric] for r in mine], color=COLORS[m], s=22, label=m)
    f_rows = [by_id[c] for c in front_by_hand(rows, metric)]
    ft, fe = [row_time_ms(r) for r in f_rows], [r[metric] for r in f_rows]
    ax.step(ft, fe, where="post", color="k", lw=1, label="Pareto front")
    ax.scatter(ft, fe, s=70, facecolors="none", edgecolors="k")
    for r, t, e in zip(f_rows, ft, fe):
        ax.annotate(knobs(r), (t, e), fontsize=6, xytext=(3, 3), textcoords="offset points")
    log_ms(ax), ax.set_xlabel("time per call, ms (log)"), ax.set_ylabel(metric)
    ax.set_title(f"{metric}: {len(f_rows)} of {len(rows)} configurations on the front", fontsize=9)
axes[0].legend(fontsize=8)
fig.suptitle("Step 3 — error against time; each metric has its own front")
plt.show()

# %% [markdown]
# Two cautions when reading a front. It is **per metric**: the RMSE front and the halo front differ, so "best"
# needs a metric (the report draws four: `rmse_cos`, `flip_cos`, `halo_band_flavour`, `banding`;
# `speed_section.SPECS`). And the time axis is a measurement on *this* machine: the errors of a seeded sweep are
# bit-for-bit repeatable, the times are not, so configurations close in time can swap places between runs. That
# is what the next step is about.
#
# ## 4. Time in units of the gather floor (`ssbench/bench/timing.py`)
#
# The `timing` block times the pass alone at one torch thread and, **in the same breath**, the *gather floor*: a
# plain texture gather of as many depth texels per pixel as the pass reads (HBAO: directions × steps;
# `ao_samples`). It does so in interleaved **rounds** — a block of pass calls, then a block of floor calls, again
# and again (`rounds`, 15 by default) — so `time_median_ms` and `time_iqr_ms` are the median and the interquartile
# range over rounds, and `floor_ratio` is the **median of the per-round ratios** pass / floor, with
# `floor_ratio_iqr` their IQR. The ratio says how many times more than its unavoidable memory reads the pass
# costs; a hiccup of the machine that slows both blocks of a round cancels in that round's ratio. (The rounds run
# with glibc's malloc thresholds held still — otherwise whether a pass page-faults its temporaries on every call
# depends on what the process did before, the largest gap between two runs; `timing.steady_heap`.)
#
# A shared machine does one more thing: its speed switches between regimes every second or so, and the floor
# follows only in part, so the rounds of a pass timed alone sit in one or two regimes and a second run can land in
# others. A sweep therefore times its configurations in **groups** (`timing: {interleave: 8}` by default): it
# evaluates 8 configurations, then runs one round of each in a shuffled order, the next round in another order,
# and so on (`ssbench/bench/interleave.py`, *randomized interleaved trials*). Each configuration's rounds then
# span the whole group's timing and its IQR takes in the regimes; `benchmarks/bench_sweep_timing.py --protocol
# interleaved,sweep` measures how often repeated runs agree within it.
#
# What no number of rounds in one process samples is the process itself: where its memory landed and what the
# machine did while it ran shift all of its rounds alike, so two runs' medians differ by more than their IQRs more
# often than the rounds alone would allow. So a sweep times each group again in two fresh Python processes, one
# after the other, and pools the rounds of all three (`timing: {processes: 3}`, the default;
# `ssbench/bench/processes.py`: repeated invocations, as benchmarking practice does for virtual machines and JITs).
# It costs three times the timing plus an evaluation per extra process; `benchmarks/bench_sweep_repeats.py` runs a
# sweep again and again, with 1 and 3 processes, and prints how often the runs agree. The report's sweeps, this
# lesson's and the demonstration below time in this process only (`processes: 1`): they are overviews.
#
# To see it, the same configuration is timed twice: once as it is, and once while busy-looping processes, one
# per core, compete for the CPU (they are stopped right after).

# %%
cfg = next(c for c in sweep.configs if c.method == "hbao" and dict(c.params) == HBAO_4x4)
spec = TimingSpec(min_run_time=0.05, warmup=1, processes=1)
quiet = run_config(cfg, spec)
hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(min(os.cpu_count() or 1, 8))]
try:
    loaded = run_config(cfg, spec)
finally:
    for p in hogs:
        p.kill()
        p.wait()

# the fields of five rounds (seconds per call), one of them hit by a hiccup that slowed pass and floor alike
rounds = [[0.010, 0.012, 0.011, 0.030, 0.010], [0.002, 0.002, 0.002, 0.006, 0.002]]
ratios = sorted(p / f for p, f in zip(*rounds))
fields = round_fields(rounds)
check("floor_ratio is the median of the per-round ratios (not median time / median floor)",
      math.isclose(fields["floor_ratio"], ratios[2]) and not math.isclose(fields["floor_ratio"], 11.0 / 2.0))
check("... and floor_ratio_iqr their interquartile range", math.isclose(fields["floor_ratio_iqr"], ratios[3] - ratios[1]))
for r in (quiet, loaded):
    check("every timing row carries its floor ratio and the number of rounds",
          r["floor_ratio"] > 0 and r["floor_ratio_iqr"] >= 0 and r["time_blocks"] >= 3)
check("the floor gathers as many texels per pixel as HBAO reads: 4 directions × 4 steps",
      quiet["floor_samples"] == ao_samples("hbao", HBAOParams(**HBAO_4x4)) == 16)
check("the load changes only the volatile fields (times), never the errors",
      canonical_json(quiet) == canonical_json(loaded))
change = {k: loaded[k] / quiet[k] - 1 for k in ("time_median_ms", "floor_median_ms", "floor_ratio")}
print("under load: " + ", ".join(f"{k} {v:+.0%}" for k, v in change.items()))

fig, ax = plt.subplots(1, 2, figsize=(11, 3.4), layout="constrained")
x = np.arange(2)
for i, (key, iqr, label) in enumerate([("time_median_ms", "time_iqr_ms", "HBAO 4×4"),
                                       ("floor_median_ms", "floor_iqr_ms", "gather floor (16 texels/px)")]):
    ax[0].bar(x + 0.38 * i, [quiet[key], loaded[key]], 0.38, yerr=[quiet[iqr], loaded[iqr]], label=label)
ax[0].set_xticks(x + 0.19, ["quiet", "loaded"]), ax[0].set_ylabel("ms per call (bar: IQR)"), ax[0].legend(fontsize=8)
ax[1].bar(x, [quiet["floor_ratio"], loaded["floor_ratio"]], 0.5, yerr=[quiet["floor_ratio_iqr"],
                                                                       loaded["floor_ratio_iqr"]], color="tab:gray")
ax[1].set_xticks(x, ["quiet", "loaded"]), ax[1].set_ylabel("floor_ratio = time / floor")
for a, keys in ((ax[0], ("time_median_ms", "floor_median_ms")), (ax[1], ("floor_ratio",))):
    a.set_title(", ".join(f"{k.split('_')[0]} {change[k]:+.0%}" for k in keys) + " under load", fontsize=9)
fig.suptitle("Step 4 — one configuration timed twice: absolute times move with the machine, the ratio less")
plt.show()

# %% [markdown]
# How much the load shows depends on the machine (with idle cores to spare, little happens), so the checks
# above assert definitions, not speeds. The report prints both columns; `bench.agree(a, b)` tells whether two
# timing rows agree within their IQR. Claims about speed belong in `benchmarks/`, never in tests.
#
# ## 5. Equal-error cost: what the same error costs with the ray tracer
#
# The ground truth is an estimator too: ray-traced AO with `n` rays per pixel has a per-pixel variance `σ²/n`.
# Against the `R`-ray reference (an independent seed) its RMSE is `sqrt(σ̄²(1/n + 1/R))`, with `σ̄²` read off the
# reference's own standard error (`stderr² · R`, averaged over the mask). `ao_ladder` *measures* that error at
# `n = 2, 4, 8, …` and its time; `equal_error_n` finds, by log–log interpolation on the ladder, the `n` whose error
# equals a method's best error. That `n` — and its time — is the method's **equal-error cost**: the price of
# the same RMSE from the ground truth itself.

# %%
ladder = ao_ladder(SCENE, W, H, RADIUS, RAYS, seed=0)
var = float(metrics.masked_mean(gt_ref.stderr.double() ** 2 * RAYS, mask))
check("the ladder's prediction is sqrt(σ̄²(1/n + 1/R)) with σ̄² from the reference's standard error",
      all(math.isclose(p, math.sqrt(var * (1 / n + 1 / RAYS)), rel_tol=1e-6)
          for n, p in zip(ladder.ns, ladder.predicted)))
check("the measured ladder follows σ/√n within 20 % at every n",
      all(abs(e / p - 1) < 0.2 for e, p in zip(ladder.errors, ladder.predicted)))

best = best_rows(rows, "rmse_cos")                                 # each method's most accurate configuration
table = {e["method"]: e for e in equal_error_table(rows, {SCENE: ladder}, "rmse_cos")}
ns, es = np.log(ladder.ns), np.log(ladder.errors)
for m, e in table.items():
    target = best[SCENE, m]["rmse_cos"]
    i = int(np.argmax(np.array(ladder.errors) <= target)) if min(ladder.errors) <= target else None
    if i:                                                          # between ladder points i-1 and i, in log-log
        n_hand = math.exp(ns[i - 1] + (math.log(target) - es[i - 1]) / (es[i] - es[i - 1]) * (ns[i] - ns[i - 1]))
        check(f"{m}: log-log interpolation by hand gives the library's equal-error n",
              math.isclose(n_hand, e["n"], rel_tol=1e-9) and math.isclose(n_hand, equal_error_n(
                  ladder.ns, ladder.errors, target).n, rel_tol=1e-9))
    model = 1 / (target ** 2 / var - 1 / RAYS) if target ** 2 > var / RAYS else math.inf
    print(f"{m:>5} {e['params']}: RMSE {target:.4f} in {e['time_ms']:.2f} ms; ground truth of equal RMSE: "
          f"{e['n_text']} rays (σ/√n model: {model:.3g}), {e['gt_ms']:.1f} ms")

fig, ax = plt.subplots(1, 2, figsize=(12, 4), layout="constrained")
ax[0].loglog(ladder.ns, ladder.errors, "kx", label=f"measured ({RAYS}-ray reference)")
ax[0].loglog(ladder.ns, ladder.predicted, "k-", lw=0.8, label="sqrt(σ̄²(1/n + 1/R))")
ax[1].plot(np.array(ladder.seconds) * 1e3, ladder.errors, "kx--", lw=0.8, label="ray-traced AO, n rays")
ax[1].set_yscale("log"), log_ms(ax[1])
for n, s, e in zip(ladder.ns, ladder.seconds, ladder.errors):
    ax[1].annotate(str(n), (s * 1e3, e), fontsize=7, xytext=(3, 3), textcoords="offset points")
for m, e in table.items():
    ax[0].axhline(e["error"], color=COLORS[m], ls=":", lw=1)
    if e["status"] == "interpolated":
        ax[0].plot([e["n"]], [e["error"]], "o", color=COLORS[m], label=f"{m}: ≈ {e['n']:.3g} rays")
    ax[1].plot([e["time_ms"]], [e["error"]], "o", color=COLORS[m], label=f"{m} (best configuration)")
ax[0].set_xlabel("rays per pixel"), ax[0].set_ylabel("RMSE vs reference"), ax[0].legend(fontsize=7)
ax[1].set_xlabel("time, ms (log)"), ax[1].set_ylabel("RMSE vs reference"), ax[1].legend(fontsize=7)
ax[0].set_title("the ground truth's ladder, and each method's best error", fontsize=9)
ax[1].set_title("the same against time: screen space next to the ray tracer", fontsize=9)
fig.suptitle("Step 5 — equal-error cost")
plt.show()

# %% [markdown]
# The verdict is humbling: a few rays per pixel — tens at most — match the screen-space methods' best RMSE.
# Their error is mostly **bias** (what the depth buffer cannot see, lesson 3 Step 8), while the ray tracer's is
# unbiased noise that shrinks as 1/√n. RMSE is not the whole story — a 4-ray image is speckled where a
# screen-space one is smooth, and a denoiser changes the trade again — and the times are this machine's (the
# passes run in PyTorch on the CPU, not as shaders on a GPU), but the number puts "fast" in proportion. The
# report prints this table for every effect (SSR: the exact mirror trace at one ray per pixel; implicit
# surfaces: fixed-step march steps against the certified reference).
#
# ## 6. Artifact small multiples: banding and halos (SSAO article Fig. 5, Figs. 7–9)
#
# Error against time hides *what kind* of error. The report adds small multiples: one panel per (method,
# knob), an artifact metric on the y axis, one line per value of the other knobs (`analysis.Panel`,
# `small_multiples`). Two figures, as in the report:
#
# * **banding vs sample count and noise tile** (SSAO article Fig. 5) on the stairs sweep;
# * **halos vs the range check and the blur** (Figs. 7–9, and Fig. 6's blur) on a second, untimed sweep of
#   SSAO on `fence`, thin slats in front of a wall, where halos are worst (lesson 2, Step 6).
#
# The report's SSR and implicit sections draw the same kind of figure for their own artifacts: SSR article §4's
# failure classes (missed, false hit, punch-through vs steps, stride, thickness, jitter; lesson 6, Step 6)
# and progressive-tracing article's punch-through vs step size and frame (lessons 7–8).

# %%
HALO_SWEEP = {"name": "lesson09_fence", "effect": "ao", "scenes": ["fence"], "resolution": [W, H], "rays": RAYS,
              "oracle": False, "flip": False, "blur": [None, "box", "cross_bilateral"],
              "methods": {"ssao": {"kernel_radius": RADIUS, "kernel_size": 16, "noise_size": 4,
                                   "max_distance": [0.005, 0.02, 1.0]}}}
halo_sweep = sweep_from_dict(HALO_SWEEP)
halo_rows = run_sweep(halo_sweep, str(OUT / "sweeps" / halo_sweep.name), progress=False).rows

banding_panels = [Panel("ssao", "kernel_size", "banding"), Panel("hbao", "num_directions", "banding"),
                  Panel("gtao", "quality", "banding")]
halo_panels = [Panel("ssao", "max_distance", "halo_band_flavour"), Panel("ssao", "blur", "halo_band_flavour"),
               Panel("ssao", "max_distance", "banding")]
png_banding, png_halos = str(OUT / "banding.png"), str(OUT / "halos.png")
small_multiples(rows, banding_panels, png_banding, title="Banding vs sample count and noise tile (stairs)")
small_multiples(halo_rows, halo_panels, png_halos, title="Halos vs range check and blur (fence)")

fig, ax = plt.subplots(2, 1, figsize=(11, 7.6), layout="constrained")
show_png(ax[0], png_banding, "the report's banding figure, from the stairs sweep")
show_png(ax[1], png_halos, "the report's halo figure, from the fence sweep")
fig.suptitle("Step 6 — artifact small multiples (002 Fig. 5; Figs. 7–9; Fig. 6)")
plt.show()

ssao_rows = [r for r in rows if r["method"] == "ssao"]
fence = {(r["blur"], r["params"]["max_distance"]): r for r in halo_rows}
check("tile energy is scored at the pass's own noise tile (tile = noise_size)",
      all(r["tile"] == r["params"]["noise_size"] for r in ssao_rows))
check("a fixed kernel (noise_size 1) has no tile pattern, but its bands still count as banding",
      all(r["tile_energy"] == 0 and r["banding"] > 0 for r in ssao_rows if r["params"]["noise_size"] == 1))
check("fence: without the range check (MaxDistance 1) the halo band error is larger than with 0.02",
      fence[None, 1.0]["halo_band_flavour"] > fence[None, 0.02]["halo_band_flavour"])
check("a blur is no cure for halos: box-blurred without range check stays above the unblurred range-checked",
      fence["box", 1.0]["halo_band_flavour"] > fence[None, 0.02]["halo_band_flavour"])
check("the 5×5 box blur removes the 4×4 tile pattern (tile energy / 5 or less) at every MaxDistance",
      all(fence["box", d]["tile_energy"] <= fence[None, d]["tile_energy"] / 5 for d in (0.005, 0.02, 1.0)))

# %% [markdown]
# Read the two columns with their definitions in mind. `banding` (`metrics.banding`) is the error against the
# oracle (or the truth, `banding_target`) after a 1.5-pixel Gaussian, where the truth shows occlusion and away
# from depth edges: the bands of Fig. 5, which a small blur cannot remove — independent of any noise tile, so a
# fixed kernel (`noise_size 1`) scores its bands. `tile_energy` is the share of the image's detail at the
# frequency of the noise **tile**: the fine pattern a 4×4 rotation texture leaves and a 4–5 pixel blur removes
# (lesson 2, Steps 5 and 9); a fixed kernel has none. The report's calibration section shows `banding` falling
# with the kernel size and lower with the rotation on.
#
# ## 7. Tuning: default vs tuned, on scenes the tuner never saw
#
# Comparing methods at their defaults is unfair to the one with worse defaults. `ssbench.tune.tune` fits a
# method's *continuous* parameters (radius, falloff, power, …; discrete sample counts stay fixed) to the fixed
# ray-traced AO of some **training** scenes: a grid over the parameter box, narrowed around the best node round
# after round, then a few Adam steps through the torch pass on the parameters it is differentiable in. The tuned
# point is the best of default, grid and gradient on the training scenes — so it can never be worse there.
# Whether it is better on **held-out** scenes is the real question. Here GTAO is tuned on `stairs` and scored on
# `crease` and `cornell_box`, with a tiny search (3 nodes per axis, 2 rounds, 3 Adam steps).

# %%
tuned = tune("gtao", [SCENE], ["crease", "cornell_box"], width=W, height=H, rays=RAYS, points=3, rounds=2, steps=3)
s = tuned.summary
gtao_high = next(r for r in rows if r["method"] == "gtao" and r["params"]["quality"] == "high")
check("tuning never makes the training error worse", s["train_tuned"] <= s["train_default"])
check("the tuner's default on stairs is the sweep's GTAO-high row (same pass, truth, seed)",
      math.isclose(s["train_default"], gtao_high["rmse_cos"], rel_tol=1e-5))
held = [r for r in tuned.rows if r["split"] == "held_out"]
check("held-out means are the means of the held-out rows, and 'held_improved' says which is lower",
      math.isclose(s["held_tuned"], np.mean([r["tuned"] for r in held]), rel_tol=1e-9)
      and s["held_improved"] == (s["held_tuned"] < s["held_default"]))
for p in tuned.params:
    print(f"{p['name']:>17}: {p['default']:.3g} → {p['tuned']:.3g} in [{p['lo']:.3g}, {p['hi']:.3g}]"
          f"{'' if p['differentiable'] else '  (not differentiable: grid only)'}")
print(f"training RMSE {s['train_default']:.4f} → {s['train_tuned']:.4f} ({s['source']}); held-out "
      f"{s['held_default']:.4f} → {s['held_tuned']:.4f}; {tuned.search['evaluations']} evaluations")

fig, ax = plt.subplots(1, 2, figsize=(12, 3.6), layout="constrained")
x = np.arange(len(tuned.rows))
ax[0].bar(x - 0.2, [r["default"] for r in tuned.rows], 0.4, label="default", color="tab:gray")
ax[0].bar(x + 0.2, [r["tuned"] for r in tuned.rows], 0.4, label="tuned", color="tab:green")
ax[0].set_xticks(x, [f"{r['scene']}\n({r['split'].replace('_', '-')})" for r in tuned.rows])
ax[0].set_ylabel("RMSE vs cosine AO"), ax[0].legend(fontsize=8)
ax[0].set_title("GTAO: tuned on stairs only", fontsize=9)
n_grid = tuned.search["grid_evaluations"]
grid_err = [h["value"] for h in tuned.search["grid_rounds"]]
grad_err = [h["loss"] for h in tuned.search["gradient"]]
ax[1].plot(range(1, len(grid_err) + 1), grid_err, "o-", label=f"grid rounds ({n_grid} evaluations)")
ax[1].plot(range(len(grid_err), len(grid_err) + len(grad_err)), grad_err, "s-", label="Adam steps")
ax[1].axhline(s["train_default"], color="tab:gray", ls=":", label="default")
ax[1].set_xlabel("round / step"), ax[1].set_ylabel("training RMSE"), ax[1].legend(fontsize=8)
ax[1].set_title("the search: best of each grid round, then gradient steps", fontsize=9)
fig.suptitle("Step 7 — tuning: better on the training scene; the held-out bars are the honest number")
plt.show()

# %% [markdown]
# The report's tuning section does this for HBAO and GTAO (training `crease` and `sphere_on_plane`, held out
# `cornell_box` and `stairs`) and says in words whether tuning beat the defaults *on the held-out scenes*; a tuned
# parameter set that only helps its training scenes is overfitting, and the report shows it as such. A
# `budget_ms` rejects configurations slower than a frame budget, so the tuned point stays comparable in cost.
#
# ## 8. A real report, and comparing two runs (`build_report`, `ssbench report --compare`)
#
# `build_report` renders the scenes, runs the sections and writes one **run folder**
# `<out>/<YYYYmmdd-HHMMSS>/` plus a copy `<out>/latest/`:
#
# * `index.html` — the page: contents, *at a glance*, the scenes, one section per effect (`#sec-ao`, …,
#   `#speed`, `#tuning`), metadata; `summary.md` — the same as text; `meta.json` — everything, unrounded;
# * `rows/<section>.jsonl` — every evaluation row, one JSON object per line (the speed section adds
#   `rows/speed_<effect>.jsonl`, its sweeps' rows, and `sweeps/<name>/`, their row stores);
# * `img/<scene>/…` G-buffer previews, `img/ao/<scene>/…` AO maps and error maps, `img/speed/…` the figures of
#   Steps 3 and 6.
#
# Here: `stairs` only, with the AO section and nothing else, twice with the same settings. The speed section is
# then run on its own into the second run's folder, with this lesson's stairs sweep (the full report runs the
# embedded `ssbench/report/sweeps/*.yaml` for AO, SSR and implicit surfaces — minutes, not seconds; its ꟻLIP
# panel stays empty here because the sweep says `flip: false`). Finally the two runs are compared with the
# command line, `ssbench report --compare RUN_A RUN_B`.

# %%
reports = OUT / "reports"
kw = dict(scenes=[SCENE], width=W, height=H, spp=16, ao_rays=RAYS, ssr=False, implicit=False, speed=False,
          tuning=False, use_cache=True, progress=False)
run_a = Path(build_report(str(reports), **kw)).parent
run_b = Path(build_report(str(reports), **kw)).parent
speed = speed_section.build_speed_section(str(run_b), width=W, height=H, sweeps={"ao": SWEEP}, progress=False)

files = sorted(str(p.relative_to(run_b)) for p in run_b.rglob("*") if p.is_file() and "sweeps" not in p.parts)
print(f"{run_b.name}/: {len(files)} files, e.g. " + ", ".join(f for f in files if "/" not in f or f.startswith("rows")))
ids = re.findall(r'id="([^"]+)"', (run_b / "index.html").read_text(encoding="utf-8"))
print("index.html anchors:", ", ".join(ids))
ao_rows = [ln for ln in (run_b / "rows" / "ao.jsonl").read_text(encoding="utf-8").splitlines() if ln.strip()]
check("summary.md, index.html, meta.json and rows/ao.jsonl are where the README says",
      all((run_b / f).is_file() for f in ("summary.md", "index.html", "meta.json", "rows/ao.jsonl")))
check("rows/ao.jsonl: one row per AO method on the one scene", len(ao_rows) == len(AO_METHODS))
check("index.html has the AO section and the metadata footer", "sec-ao" in ids and "metadata" in ids)

effect = speed["effects"][0]
check("the speed section ran the sweep: as many rows as configurations",
      effect["available"] and effect["rows"] == len(sweep))
check("its 'best configuration per method' is best_rows of this lesson's sweep (errors are repeatable)",
      {(x["method"], x["config"]) for x in effect["summary"]}
      == {(m, knobs(r)) for (_, m), r in best.items()})
print(speed_section.summary_md(speed))

code = ssbench_cli(["report", "--out", str(reports), "--compare", run_a.name, run_b.name])
comparison = next(reports.glob(f"compare-{run_a.name}-vs-{run_b.name}"))
c = json.loads((comparison / "compare.json").read_text(encoding="utf-8"))
check("ssbench report --compare exits 0 and writes compare.md / .html / .json",
      code == 0 and all((comparison / f).is_file() for f in ("compare.md", "compare.html", "compare.json")))
check("same settings, same seeds: every row matched and none changed beyond rtol",
      c["rows_compared"] == len(AO_METHODS) and c["rows_unchanged"] == c["rows_compared"] and not c["results"]
      and not c["added"] and not c["removed"])

pictures = ["img/stairs/color.png", "img/ao/stairs/gt_cosine.png", "img/ao/stairs/gtao.png",
            "img/ao/stairs/gtao_err_cos.png", "img/speed/ao_error_time.png"]
fig, ax = plt.subplot_mosaic([["0", "1", "2", "3"], ["4", "4", "4", "4"]], figsize=(13, 7.4),
                             layout="constrained", height_ratios=[1, 1.25])
for i, rel in enumerate(pictures):
    show_png(ax[str(i)], str(run_b / rel), rel)
fig.suptitle(f"Step 8 — inside a run folder ({run_b.name}/): previews, the AO section, the speed section")
plt.show()

# %% [markdown]
# The comparison matches rows by effect, scene, method, parameters and settings, lists every result field that
# moved by more than `--rtol`, the rows only one run has, and the wall times that moved by more than
# `--time-rtol` (first runs pay Dr.Jit's kernel compilation and cold caches, so times differ between two
# identical runs while results do not). Before trusting a change in a report, compare it with the previous run:
# a result that moved with no commit in between is a bug; a time that moved is usually the machine.
#
# ## Checks

# %%
print(f"{len(rows)} configurations; RMSE front: {len(front)} of them; equal-error rays: "
      + ", ".join(f"{m} {e['n_text']}" for m, e in table.items())
      + f"; GTAO tuned: training {s['train_default']:.4f} → {s['train_tuned']:.4f}, held-out "
      f"{s['held_default']:.4f} → {s['held_tuned']:.4f}")
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * `ssbench/bench/` — sweep files (`config.py`: the format, grids, `config_id`), `sweep.py` (`run_sweep`,
#   resume), `rows.py` (the row store, volatile fields), `timing.py` (interleaved rounds of the pass and the gather floor), `processes.py` (rounds pooled over processes);
#   `ssbench sweep FILE` runs a sweep from the command line.
# * `ssbench/analysis/` — `pareto.py`, `equal_error.py`, `multiples.py`, `figures.py`; their docstrings state
#   the definitions used here.
# * `ssbench/report/speed_section.py` (`SPECS`: the metrics and figures per effect) and
#   `ssbench/report/sweeps/*.yaml`; `ssbench/report/tuning_section.py`; `ssbench/tune/` and `ssbench tune METHOD`.
# * `reports/README.md` — the run folder, the timing methodology, `--compare`.
# * `benchmarks/` — where claims about speed are measured with care.
