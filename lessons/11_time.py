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
# # Lesson 11 — Time: flicker, temporal accumulation and ghosting
#
# ## Overview
#
# Every AO pass in lessons 2–3 was judged on one frame. A real-time renderer shows sixty a second, and they move:
# the noise that hides banding is re-drawn every frame, and TAA jitters the camera by a fraction of a pixel. A
# pass that is fine on one frame can **flicker**. Engines answer with **temporal accumulation**: reuse last
# frame's result where it still applies, and blend in a little of the new one. That trades flicker for
# **ghosting**: history that no longer belongs where it is drawn.
#
# This lesson measures all three with the library: frames of a still scene (`ssbench.evaluate.ao_frames`), the
# resolve step by step (`ssbench.passes.temporal`: Karis, "High Quality Temporal Supersampling", SIGGRAPH 2014),
# and ghosting on a moving camera against each frame's ray-traced truth (`ssbench.metrics.temporal`).
#
# > **You will learn**
# > 1. what flicker is, in AO units, and which of noise and jitter causes it;
# > 2. how reprojection finds where a pixel was last frame, and when the depth says the history is new;
# > 3. why the resolve clamps the history to the current neighbourhood, and what the blend weight does;
# > 4. how much accumulation cuts each method's flicker;
# > 5. what ghosting measures, and how it grows when the resolve keeps stale history.

# %% [markdown]
# ## Setup
#
# The scene is `stairs`: creases for the AO and depth edges for trails. The radius is 0.5, and there are 8
# frames. The size is 128 × 96 (64 × 48 in the tests).

# %%

import matplotlib.pyplot as plt
import torch

import _setup
from ssbench.evaluate import EDGE_BAND, EDGE_JUMP, ao_frames, orbit
from ssbench.metrics.ao import edge_band
from ssbench.metrics.temporal import flicker, ghosting
from ssbench.passes import AO_METHODS
from ssbench.passes.temporal import AccumulationParams, accumulate, reproject
from ssbench.reference import gbuffer
from ssbench.scenes import catalog

torch.set_num_threads(1)
W, H = _setup.size((128, 96))
SCENE, RADIUS, FRAMES = "stairs", 0.5, 8
sc = catalog.get(SCENE)
print(f"{SCENE} at {W}×{H}, radius {RADIUS}, {FRAMES} frames")

# %% [markdown]
# ## Step 1 — Flicker: noise or jitter?
#
# `ao_frames` runs one method over frames of a still scene. The noise advances every frame (a new generator per
# frame; GTAO: XeGTAO's frame index). The camera is jittered by the Halton (2, 3) offsets of TAA. **Flicker** is
# the mean per-pixel temporal standard deviation. A pixel that toggles between 0 and 1 would score about 0.5.

# %%
kw = dict(frames=FRAMES, width=W, height=H, radius=RADIUS)
noise_only = ao_frames(sc, "ssao", jitter=False, **kw)
jitter_only = ao_frames(sc, "ssao", advance_noise=False, **kw)
frozen = ao_frames(sc, "ssao", jitter=False, advance_noise=False, **kw)
print(f"SSAO flicker: noise only {noise_only.flicker:.4f}, jitter only {jitter_only.flicker:.4f}, "
      f"neither {frozen.flicker:.4f}")
std = noise_only.ao.std(0)[0, 0]
plt.figure(figsize=(4.5, 3.2))
plt.imshow(std, cmap="magma")
plt.colorbar(label="temporal std")
plt.title("SSAO: where the moving noise flickers")
plt.axis("off")
plt.show()

# %% [markdown]
# ## Step 2 — Reprojection: where was this pixel last frame?
#
# The camera turns 2° about the stairs between two frames. Each current pixel's view position goes to world
# space, then into the previous camera's view, then to its pixel. Last frame's image is read there
# (bilinear).
#
# The history is **rejected** in three cases: off the old screen, on its background, or where the old depth
# there disagrees with the reprojected depth by more than 2 %. Those are the pixels the motion just uncovered.

# %%
cam0 = sc.camera.with_resolution(W, H)
cam1 = orbit(cam0, 2.0)
g0 = gbuffer(sc.with_camera(cam0), W, H, channels=("view_z", "normal", "mask"))
g1 = gbuffer(sc.with_camera(cam1), W, H, channels=("view_z", "normal", "mask"))
here, valid = reproject(g0.view_z, cam0, g0.view_z, g1)          # reproject the old depth itself
fig, ax = plt.subplots(1, 3, figsize=(11, 3))
ax[0].imshow(g0.view_z[0, 0], cmap="viridis"), ax[0].set_title("frame 0 view z")
ax[1].imshow(torch.where(valid, here, torch.nan)[0, 0], cmap="viridis"), ax[1].set_title("reprojected into frame 1")
ax[2].imshow(valid[0, 0], cmap="gray"), ax[2].set_title("history trusted (white)")
for a in ax:
    a.axis("off")
plt.show()
print(f"history trusted on {float(valid[g1.mask].float().mean()):.1%} of frame 1's surface pixels")

# %% [markdown]
# ## Step 3 — Clamp and blend
#
# Where the history is trusted, `out = lerp(history, current, α)`. With α = 0.1, about ten frames are averaged.
# Before blending, the history is **clamped** to the min/max of the current frame's 3 × 3 neighbourhood. A history
# value that no nearby current pixel supports cannot survive, and this bounds trails where the rejection missed.
#
# With a still camera and no clamp, the resolve is the exponential moving average, up to float32 rounding of the
# sample positions (exactly so in float64, `tests/passes/test_temporal.py`). That is checked
# below.

# %%
frames = noise_only.ao                                            # (T, 1, 1, H, W) on the still camera
still = gbuffer(sc.with_camera(cam0), W, H, channels=("view_z", "mask"))
p = AccumulationParams(alpha=0.1, clamp="none")
out = ema = frames[0]
for t in range(1, FRAMES):
    h, ok = reproject(out, cam0, still.view_z, still)
    out = accumulate(frames[t], h, ok, p)
    ema = ema + (frames[t] - ema) * 0.1
err_ema = float((out - ema).abs()[still.mask].max())
print(f"still camera, no clamp: |resolve − EMA| ≤ {err_ema:.2e}")

# %% [markdown]
# ## Step 4 — Accumulation against flicker, per method
#
# The same frames (noise advancing, jitter on) for every AO method, raw and through the resolve
# (α = 0.1, min/max clamp).

# %%
rows = {}
for m in AO_METHODS:
    r = ao_frames(sc, m, accumulation=AccumulationParams(), **kw)
    rows[m] = (r.flicker, r.flicker_accumulated)
    print(f"{m:>11}: flicker raw {r.flicker:.4f} → accumulated {r.flicker_accumulated:.4f}")
plt.figure(figsize=(6, 3))
x = torch.arange(len(rows))
plt.bar(x - 0.2, [v[0] for v in rows.values()], 0.4, label="raw")
plt.bar(x + 0.2, [v[1] for v in rows.values()], 0.4, label="accumulated")
plt.xticks(x, list(rows), rotation=20)
plt.ylabel("flicker (AO units)")
plt.legend()
plt.show()

# %% [markdown]
# ## Step 5 — Ghosting on a moving camera
#
# Now the camera turns 1.5° per frame, and each frame has its own ray-traced truth. **Ghosting** is the error
# the resolve adds over the raw frames, measured where it kept history:
#
# $$\overline{|a - g|} - \overline{|r - g|}$$
#
# A negative value means the history helped. A positive value means stale history. Loosening the resolve should
# raise it: a smaller α, no clamp, and a depth tolerance so wide that nothing is rejected. That is the metric's
# calibration.

# %%
moving = dict(kw, orbit_deg=1.5, truth_rays=_setup.pick(64, 32))
tight = ao_frames(sc, "ssao", accumulation=AccumulationParams(), **moving)
loose = ao_frames(sc, "ssao", accumulation=AccumulationParams(alpha=0.05, clamp="none", depth_tolerance=10.0),
                  **moving)
print(f"SSAO ghosting: tight resolve {tight.ghosting:+.4f}, loose resolve {loose.ghosting:+.4f}")
last = gbuffer(sc.with_camera(tight.cameras[-1]), W, H, channels=("view_z", "mask"))
edges = edge_band(last.view_z, last.mask, EDGE_BAND, EDGE_JUMP, silhouettes=True)   # what ghosting_edges counts
fig, ax = plt.subplots(1, 3, figsize=(11, 3))
ax[0].imshow(tight.truth[-1, 0, 0], cmap="gray", vmin=0, vmax=1), ax[0].set_title("truth, last frame")
ax[1].imshow((loose.accumulated[-1] - loose.truth[-1])[0, 0], cmap="RdBu", vmin=-0.2, vmax=0.2)
ax[1].set_title("loose resolve − truth")
ax[2].imshow(edges[0, 0], cmap="gray"), ax[2].set_title("depth edges (trails live here)")
for a in ax:
    a.axis("off")
plt.show()

# %% [markdown]
# ## Checks

# %%
assert noise_only.flicker > 0 and jitter_only.flicker > 0 and frozen.flicker == 0.0
assert float(valid[g1.mask].float().mean()) > 0.7 and not bool(valid.all())
assert err_ema < 1e-5                                             # float32 sample positions
assert sum(v[1] for v in rows.values()) < sum(v[0] for v in rows.values())
assert rows["ssao"][1] < rows["ssao"][0] and rows["hbao"][1] < rows["hbao"][0]
assert loose.ghosting > tight.ghosting
assert float(flicker(frozen.ao, frozen.mask)) == 0.0
assert ghosting(tight.accumulated, tight.ao, tight.truth, tight.history_valid) == tight.ghosting
print("all checks passed")

# %% [markdown]
# ## See also
#
# - `ssbench/passes/temporal.py`: the resolve, with its parameters.
# - `ssbench/report/time_section.py`: the same numbers for every method in the report's **Time** section, with
#   the error over frames and an animated raw | accumulated comparison.
# - Lesson 3 (GTAO's noise and its denoiser) and lesson 9 (reading a report).
