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
# > 5. what ghosting measures, and how it grows when the resolve keeps stale history;
# > 6. what a moving object adds, and what its motion vectors fix (and do not fix);
# > 7. why reflections lag behind the camera after a resolve;
# > 8. how TXAA anti-aliases an implicit surface, and why a depth test in the resolve undoes it.

# %% [markdown]
# ## Setup
#
# The scene is `stairs`: creases for the AO and depth edges for trails. The radius is 0.5, and there are 8
# frames. The size is 128 × 96 (64 × 48 in the tests).

# %%

import matplotlib.pyplot as plt
import torch

import _setup
from ssbench.evaluate import EDGE_BAND, EDGE_JUMP, ao_frames, implicit_frames, orbit, ssr_frames
from ssbench.metrics.ao import edge_band
from ssbench.metrics.temporal import flicker, ghosting
from ssbench.passes import AO_METHODS
from ssbench.passes.temporal import AccumulationParams, accumulate, reproject
from ssbench.reference import gbuffer
from ssbench.scenes import catalog
from ssbench.scenes.motion import Motion

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
# ## Step 6 — A moving object and its motion vectors
#
# Now the camera stands still and the ball of `sphere_on_plane` slides 0.15 per frame
# (`ssbench.scenes.motion.Motion`). Two things change under it:
#
# - the **ball's own pixels** now show a surface point that was elsewhere last frame. Reprojecting by the camera
#   alone reads the history at the same pixel; the **motion vectors** (`ssbench.passes.temporal.object_motion`:
#   where the surface point is now minus where it was) send the lookup to where that point was;
# - its **contact shadow** moves over the floor, which did not move. The floor's history is valid by every
#   test, yet the AO there is stale. No motion vector can fix that; only the clamp bounds it.
#
# `ghosting_moving` counts the pixels within 8 px of the ball, where both effects show.

# %%
ball = dict(kw, truth_rays=_setup.pick(64, 32), moving=Motion("ball", (0.15, 0.0, 0.0)))
runs = {(clamp, mv): ao_frames("sphere_on_plane", "gtao", accumulation=AccumulationParams(clamp=clamp),
                                motion_vectors=mv, **ball)
        for clamp in ("minmax", "none") for mv in (True, False)}
for (clamp, mv), r in runs.items():
    print(f"clamp {clamp:6}  motion vectors {str(mv):5}  ghosting near the ball {r.ghosting_moving:+.4f}  "
          f"history kept {float(r.history_valid[1:].float().mean()):.1%}")
r = runs[("none", False)]
fig, ax = plt.subplots(1, 2, figsize=(8, 3))
ax[0].imshow(r.truth[-1, 0, 0], cmap="gray", vmin=0, vmax=1), ax[0].set_title("truth, last frame")
ax[1].imshow((r.accumulated[-1] - r.truth[-1])[0, 0], cmap="RdBu", vmin=-0.2, vmax=0.2)
ax[1].set_title("no clamp, camera only − truth")
for a in ax:
    a.axis("off")
plt.show()

# %% [markdown]
# The clamp does most of the work: the trail is the contact shadow, and its floor pixels carry no motion. The
# motion vectors keep more history (the ball's pixels reproject onto the ball) and trim the rest.
#
# ## Step 7 — Reflections lag
#
# The same resolve on SSR (`ssbench.evaluate.ssr_frames`, scene `glossy_ramp`). The history of a reflection is
# found through the **floor's** depth and motion, but what the reflection shows moves with its own parallax:
# turn the camera and the reflected spheres slide across the floor faster than the floor does. The truth of each
# frame is the screen-space oracle (the G-buffer colour where each lobe direction's hit projects), so the
# comparison is about the resolve, not what the screen lacks.

# %%
ssr_kw = dict(frames=FRAMES, width=W, height=H, truth_rays=_setup.pick(16, 8))
refl = {name: ssr_frames("glossy_ramp", "dda", accumulation=acc, orbit_deg=1.5, **ssr_kw)
        for name, acc in (("tight", AccumulationParams()),
                          ("loose", AccumulationParams(alpha=0.05, clamp="none", depth_tolerance=10.0)))}
still = ssr_frames("glossy_ramp", "glossy_stochastic", accumulation=AccumulationParams(), frames=FRAMES, width=W,
                   height=H)
print(f"DDA reflections, turning camera: ghosting tight {refl['tight'].ghosting:+.4f}, "
      f"loose {refl['loose'].ghosting:+.4f} (near edges {refl['tight'].ghosting_edges:+.4f} → "
      f"{refl['loose'].ghosting_edges:+.4f})")
print(f"stochastic glossy SSR, still camera: flicker {still.flicker:.4f} raw → {still.flicker_accumulated:.4f}")

# %% [markdown]
# ## Step 8 — TXAA on an implicit surface
#
# The progressive-tracing article's notes (補足: アンチエイリアシング) jitter the camera by a random sub-pixel
# offset every frame. Resolved over frames, the jittered samples average over each pixel's area: the
# supersampled image, without supersampling. `ssbench.evaluate.implicit_frames` casts the frames, resolves them,
# and scores the silhouettes against the certified reference at 4 × 4 samples per pixel.
#
# One setting matters: the AO resolve's **depth test**. The jitter moves every silhouette by up to half a pixel
# each frame, so a silhouette pixel flips between the surface and the background, and its depth with it. A depth
# test then throws the history away exactly where TXAA works. `TXAA` resolves without it (and keeps the
# background, which is a colour here).

# %%
txaa = implicit_frames("torus", "sphere", frames=16, width=W // 2, height=H // 2)
depth = implicit_frames("torus", "sphere", frames=16, width=W // 2, height=H // 2,
                        accumulation=AccumulationParams(background=True))
print(f"silhouette error: raw {txaa.raw_error():.4f}, TXAA {txaa.late_error():.4f} (last 4 frames), with a depth "
      f"test {depth.late_error():.4f}")
fig, ax = plt.subplots(1, 3, figsize=(11, 3))
for a, (img, title) in zip(ax, ((txaa.color[-1], "one jittered frame"), (txaa.accumulated[-1], "TXAA, 16 frames"),
                                (txaa.truth, "4×4 supersampled truth"))):
    a.imshow((img[0].permute(1, 2, 0).clamp(0, 1) ** (1 / 2.2)).numpy()), a.set_title(title), a.axis("off")
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
assert runs[("none", True)].ghosting_moving > runs[("minmax", True)].ghosting_moving
assert refl["loose"].ghosting > refl["tight"].ghosting and still.flicker_accumulated < still.flicker
assert txaa.late_error() < txaa.raw_error() and depth.late_error() > txaa.late_error()
print("all checks passed")

# %% [markdown]
# ## See also
#
# - `ssbench/passes/temporal.py`: the resolve, with its parameters.
# - `ssbench/report/time_section.py`: the same numbers for every method in the report's **Time** section, with
#   the error over frames and animated raw | accumulated comparisons (camera turning, ball moving); the SSR and
#   TXAA tables come from `time_ssr.py` and `time_implicit.py`.
# - `ssbench/evaluate/_frames.py`: the frame loop (jitter, orbit, moving object, motion vectors) every temporal
#   evaluation shares.
# - Lesson 3 (GTAO's noise and its denoiser) and lesson 9 (reading a report).
