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
# # Lesson 4 — Screen-space reflections: the basic march
#
# ## Overview
#
# A mirror shows what its reflected ray hits. **Screen-space reflections** (SSR; Crytek's "real-time local
# reflections" in Crysis 2) find that hit without the scene: reflect the eye ray at every pixel, march along
# the reflected ray in small steps, and stop when a step falls *behind* the depth buffer. SSR article §1 builds the
# basic version — reflection vector, near-plane clipping, a linear march with a `Thickness`, back-face depth,
# binary search, and the two fades that hide what the march cannot do. We build it in that order and score
# every choice against the **exact mirror hit** that Mitsuba traces for each pixel
# (`ssbench.reference.reflections`), labelling every pixel correct, missed, false hit, punch-through, or one of
# the failures no screen-space method can fix.
#
# > **You will learn**
# > 1. the reflection vector `reflect(normalize(P), N)` in view space (§1.1);
# > 2. why rays toward the camera must be clipped at the near plane (§1.2);
# > 3. the linear march and its hit test, traced by hand for one pixel (§1.2, Figs. 2–3);
# > 4. what `Thickness` trades — missed hits against false ones (Figs. 4–6) — and how back-face depth helps (Fig. 7);
# > 5. how a few bisection steps pin the hit down (§1.3);
# > 6. the screen-edge and distance fades (§1.4–1.5, Figs. 8–9).

# %% [markdown]
# ## Setup

# %%
import math

import matplotlib.pyplot as plt
import numpy as np
import torch

from ssbench import reference
from ssbench.metrics import ssr as ssr_metrics
from ssbench.passes.common import uv_to_texel
from ssbench.passes.ssr.common import clip_ray_length, reflection_rays
from ssbench.passes.ssr.fade import distance_fade, edge_fade
from ssbench.passes.ssr.linear import LinearSSRParams, ssr_linear
from ssbench.scenes import load
from _setup import pick, size

W, H = size()
scene = load("reflective_floor")
g = reference.gbuffer(scene, W, H, channels=("view_z", "normal", "position", "mask", "color", "back_z",
                                             "shape_id", "metallic"), spp=pick(256, 64))
cam, mask = g.camera, g.mask
truth = reference.reflections(scene, g, spp=pick(32, 8))       # the exact mirror ray of every pixel
mirror = mask & (g.metallic > 0.5)                            # the reflective pixels: the floor

checks = {}


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name


def classes_of(result):
    """Label every mirror pixel against the exact reflection; also return the class fractions."""
    classes, _ = ssr_metrics.classify(result, truth, g, reflective=mirror)
    return classes, ssr_metrics.class_fractions(classes, ssr_metrics.truth_classes(truth, g, reflective=mirror))


def srgb(x):
    return x[0].permute(1, 2, 0).clamp(0, 1).pow(1 / 2.2).numpy()


fig, ax = plt.subplots(1, 3, figsize=(13, 3.4), layout="constrained")
ax[0].imshow(srgb(g.color)), ax[0].set_title("colour (path traced; the floor is a mirror)")
ax[1].imshow(srgb(truth.radiance * mirror)), ax[1].set_title("what the mirror sees (exact mirror rays)")
ax[2].imshow(ssr_metrics.class_rgb(ssr_metrics.truth_classes(truth, g, reflective=mirror)))
ax[2].set_title("what a perfect screen-space pass could get")
ax[2].legend(handles=ssr_metrics.legend_handles([1, 5, 6, 7]), fontsize=7, loc="lower left")
for a in ax:
    a.set_xticks([]), a.set_yticks([])
plt.show()

# %% [markdown]
# The right panel is the ceiling: green pixels reflect something the depth buffer holds; yellow, orange and cyan
# reflect something it cannot (off screen, hidden, a back face) — lesson 6 returns to those.
#
# ## 1. The reflection vector (§1.1)
#
# In view space the camera is at the origin, so the eye ray to a pixel's position `P` is `normalize(P)`, and
# GLSL's `reflect(I, N) = I − 2·dot(N, I)·N` mirrors it about the normal.

# %%
P = cam.uv_to_view(cam.uv_grid(torch.float64)[None], g.view_z.double())     # rayOrg (view space)
N = g.normal.double()
I = P / P.norm(dim=1, keepdim=True)                                          # incidentVec
R_by_hand = I - 2 * (N * I).sum(1, keepdim=True) * N                         # reflect(I, N)
R_lib = reflection_rays(P, N)
check("reflect(normalize(P), N) by hand equals reflection_rays",
      torch.allclose(R_by_hand[mirror.expand(-1, 3, -1, -1)], R_lib[mirror.expand(-1, 3, -1, -1)], atol=1e-6))

col = W // 2 + W // 8                                                        # one image column, side view
rows = [r for r in range(0, H, max(1, H // 12)) if mirror[0, 0, r, col]]
fig, ax = plt.subplots(1, 2, figsize=(12, 3.8), layout="constrained")
for r in rows:
    p, d = P[0, :, r, col], R_lib[0, :, r, col]
    ax[0].plot([0, p[2]], [0, p[1]], color="0.7", lw=0.8)                    # eye ray (z, y)
    ax[0].plot([p[2], p[2] + 2 * d[2]], [p[1], p[1] + 2 * d[1]], color="C0")  # reflected ray
ax[0].plot(P[0, 2, :, col][mask[0, 0, :, col]], P[0, 1, :, col][mask[0, 0, :, col]], "k.", ms=2)
ax[0].plot(0, 0, "k*", ms=12), ax[0].set_xlabel("view z"), ax[0].set_ylabel("view y")
ax[0].set_title("side view of one column: eye rays (grey), reflections (blue)"), ax[0].set_aspect("equal")
ax[1].imshow(torch.where(mirror, R_lib * 0.5 + 0.5, 0)[0].permute(1, 2, 0))
ax[1].axvline(col, color="y", lw=0.8), ax[1].set_title("reflection direction as (R + 1)/2")
ax[1].set_xticks([]), ax[1].set_yticks([])
fig.suptitle("Step 1 — reflect the eye ray about the normal (§1.1)")
plt.show()

# %% [markdown]
# ## 2. Clip to the near plane (§1.2)
#
# A ray is marched up to `MaxRayDistance`. A ray coming back toward the camera would cross `z = −near` and then
# the plane of the eye, where the perspective divide by `w = −z` blows up and flips. The article shortens it:
#
# ```
# rayLength = (rayOrg.z + rayDir.z·MaxRayDistance > −CameraNear) ? (−CameraNear − rayOrg.z) / rayDir.z
#                                                                   : MaxRayDistance
# ```

# %%
max_distance = 20.0
z0, dz = P[:, 2:3], R_lib[:, 2:3]
crossing = z0 + dz * max_distance > -cam.near
length_by_hand = torch.where(crossing, (-cam.near - z0) / dz, torch.full_like(z0, max_distance))
length_lib = clip_ray_length(z0, dz, max_distance, cam.near)
check("rayLength by hand equals clip_ray_length", torch.allclose(length_by_hand[mask], length_lib[mask]))
end_z = z0 + dz * length_lib
check("no clipped ray ends behind the near plane", bool((end_z[mask] <= -cam.near + 1e-9).all()))
print(f"{float(crossing[mask].float().mean()):.0%} of all rays are clipped (they head back toward the camera)")

plt.figure(figsize=(6, 3.4))
plt.imshow(torch.where(mask, length_lib, torch.nan)[0, 0], cmap="viridis")
plt.colorbar(label="rayLength"), plt.xticks([]), plt.yticks([])
plt.title("Step 2 — ray length after near-plane clipping:\nrays that face the camera are cut short")
plt.show()

# %% [markdown]
# ## 3. The linear march (§1.2, Figs. 2–3)
#
# `Iterations` equal steps `deltaStep = (rayEnd − rayOrg)/Iterations` in view space. Each sample `Q` is
# projected to a texel, and the depth buffer there gives `sceneZMax`. The test of the article:
#
# ```
# dist = Q.z − sceneZMax;   hit ⇔ dist < 0 && dist > −Thickness      (the sample is behind the visible
#                                                                     surface, but by less than Thickness)
# ```
#
# Here it is for one floor pixel that reflects the blue ball, next to the library's trace of the same pixel
# (`trace_pixel=` records every sample the pass takes).

# %%
target = (truth.hit_shape == 1) & mirror & truth.visible & truth.on_screen      # floor pixels that see the ball
longest = torch.where(target, truth.ray_length, 0).flatten().argmax()           # ... with the longest path
py, px = divmod(int(longest), W)
params = LinearSSRParams(iterations=100, thickness=0.5, binary_search_iterations=0, position_from="view_z")
lib = ssr_linear(g, params, trace_pixel=(px, py))
trace = lib.debug["trace"][0]

# the same march by hand
o, d = P[0, :, py, px], R_lib[0, :, py, px]
length = float(clip_ray_length(o[2:], d[2:], params.max_ray_distance, cam.near))
delta_step = d * length / params.iterations
Q, samples, hit_at = o.clone(), [], None
scene_z = g.view_z.double()[0, 0]
for i in range(params.iterations):
    Q = Q + delta_step                                                      # Q += deltaStep
    uv = cam.ndc_to_uv(cam.view_to_ndc(Q, dim=0)[:2])                       # hitPixel
    c_, r_ = (int(t) for t in uv_to_texel(uv[None], H, W, dim=1))
    dist = float(Q[2] - scene_z[r_, c_])                                    # Q.z - sceneZMax
    samples.append((float(Q[2]), float(scene_z[r_, c_])))
    if -params.thickness < dist < 0:                                        # rayIntersectsDepth
        hit_at = i
        break
first_hit = int(trace["hit"].nonzero()[0, 0])
check("the hand march hits at the same step as ssr_linear", hit_at == first_hit)
check("at the same point", torch.allclose(Q, trace["view"][first_hit].double(), atol=1e-5))

fig, ax = plt.subplots(1, 2, figsize=(13, 3.8), layout="constrained")
ax[0].imshow(srgb(g.color))
ax[0].plot(trace["pixel"][:, 0], trace["pixel"][:, 1], "y.-", ms=3), ax[0].plot(px + 0.5, py + 0.5, "yo")
ax[0].set_title("the march, projected (one dot per sample)"), ax[0].set_xticks([]), ax[0].set_yticks([])
zs = np.array(samples)
ax[1].plot(-zs[:, 0], "o-", ms=3, label="ray: −Q.z")
ax[1].plot(-zs[:, 1], "s", ms=3, label="depth buffer under it: −sceneZMax")
ax[1].fill_between(range(len(zs)), -zs[:, 1], -zs[:, 1] + params.thickness, color="C1", alpha=0.2,
                   label="Thickness behind the surface")
ax[1].axvline(hit_at, color="C3", ls=":", label=f"hit at step {hit_at}")
ax[1].set_xlabel("step"), ax[1].set_ylabel("distance from the camera"), ax[1].legend(fontsize=8)
ax[1].set_title("hit = the ray is behind the surface, by less than Thickness")
fig.suptitle("Step 3 — the linear march in view space (Figs. 2–4)")
plt.show()

# %% [markdown]
# ## 4. `Thickness` (Figs. 4–6)
#
# The depth buffer stores only the front surface, so "behind the surface" is ambiguous: is the ray *inside*
# the object, or has it passed *behind* it (Fig. 5)? The article gives every surface a fixed thickness (Fig. 6).
# Too thin, and steps jump over the slab and **miss**; too thick, and rays that pass behind an object are
# taken to hit it — a **false hit**, the reflection of a foreground object smeared downward.

# %%
thicknesses = [0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 3.0, 10.0]
keys = ["correct", "missed", "false_hit", "misplaced_hit", "punch_through"]
sweep = {}
for bf in (False, True):
    for t in thicknesses:
        result = ssr_linear(g, LinearSSRParams(thickness=t, use_back_face_depth=bf))
        sweep[bf, t] = (result, classes_of(result))


def class_map(result, classes):
    return ssr_metrics.class_rgb(classes)


fig, ax = plt.subplots(1, 3, figsize=(15, 3.6), layout="constrained", width_ratios=[1, 1, 1.2])
for a, t in zip(ax[:2], (0.05, 10.0)):
    result, (classes, frac) = sweep[False, t]
    a.imshow(class_map(result, classes)), a.set_title(f"Thickness {t}: correct {frac['correct']:.0%}, "
                                                      f"missed {frac['missed']:.0%}, false {frac['false_hit']:.0%}",
                                                      fontsize=9)
    a.set_xticks([]), a.set_yticks([])
ax[0].legend(handles=ssr_metrics.legend_handles([1, 2, 3, 9, 4]), fontsize=7, loc="lower left")
for k, c in zip(keys, ("C2", "C0", "C3", "salmon", "m")):
    ax[2].semilogx(thicknesses, [sweep[False, t][1][1][k] for t in thicknesses], "o-", color=c, label=k)
ax[2].set_xlabel("Thickness (view units)"), ax[2].set_ylabel("share of mirror pixels"), ax[2].legend(fontsize=8)
ax[2].set_title("front depth only")
fig.suptitle("Step 4 — Thickness: too thin misses, too thick invents hits (Figs. 4–6)")
plt.show()
frac_of = {t: sweep[False, t][1][1] for t in thicknesses}
check("a thin Thickness misses many hits", frac_of[0.05]["missed"] > 0.3)
wrong = {t: f["false_hit"] + f["misplaced_hit"] for t, f in frac_of.items()}
check("a thick Thickness invents wrong hits (false or misplaced)", wrong[10.0] > 3 * wrong[0.2])

# %% [markdown]
# ## 5. Back-face depth (§1.2, Fig. 7)
#
# Render the scene a second time with front faces culled and you know where every object *ends*: the hit test
# becomes `backZ − Thickness < Q.z < sceneZ` (`use_back_face_depth=True`, G-buffer channel `back_z`). Now a thin
# `Thickness` no longer misses — the object is as thick as it really is — and the fixed width only covers open
# surfaces (an open rectangle has no back, so it is treated as infinitely thick, as the article warns).

# %%
fig, ax = plt.subplots(1, 2, figsize=(12, 3.5), layout="constrained")
back = torch.where(mask & torch.isfinite(g.back_z), g.view_z - g.back_z, torch.nan)
h_ = ax[0].imshow(back[0, 0], cmap="magma"), ax[0].set_xticks([]), ax[0].set_yticks([])
fig.colorbar(h_[0], ax=ax[0], shrink=0.8, label="view_z − back_z (object thickness)")
ax[0].set_title("back-face depth: how thick each pixel's object is")
for k, c in zip(keys[:3], ("C2", "C0", "C3")):
    ax[1].semilogx(thicknesses, [frac_of[t][k] for t in thicknesses], "o--", color=c, alpha=0.5, label=f"{k}, front only")
    ax[1].semilogx(thicknesses, [sweep[True, t][1][1][k] for t in thicknesses], "o-", color=c, label=f"{k}, with back faces")
ax[1].set_xlabel("Thickness"), ax[1].legend(fontsize=7), ax[1].set_title("the sweep again, with back-face depth")
fig.suptitle("Step 5 — back-face depth gives objects their real thickness (Fig. 7)")
plt.show()
check("with back faces, a thin Thickness keeps most hits",
      sweep[True, 0.05][1][1]["correct"] > 2 * frac_of[0.05]["correct"])

# %% [markdown]
# ## 6. Binary search (§1.3)
#
# With few steps, the first sample behind the surface can be most of a step past the true hit. Bisecting the
# last step — probe its middle, keep the half where the ray crosses the surface, repeat — costs a few extra
# reads and pins the hit down. (`CORRECT` means within 1.5 px of the true hit pixel.)

# %%
bisect = {}
for n in (0, 2, 4, 8):
    result = ssr_linear(g, LinearSSRParams(iterations=20, thickness=0.5, binary_search_iterations=n))
    classes, frac = classes_of(result)
    pairs = torch.isin(classes, torch.tensor([ssr_metrics.CORRECT, ssr_metrics.FALSE_HIT, ssr_metrics.MISPLACED_HIT],
                                             dtype=classes.dtype))
    err = ssr_metrics.hit_error(result, truth, pairs)
    bisect[n] = (result, frac, err)

fig, ax = plt.subplots(1, 3, figsize=(15, 3.4), layout="constrained")
for a, n in zip(ax[:2], (0, 8)):
    err_px, _ = ssr_metrics.hit_error_maps(bisect[n][0], truth)
    h_ = a.imshow(torch.where(mirror, err_px, torch.nan)[0, 0], cmap="magma", vmin=0, vmax=3)
    a.set_title(f"{n} bisection steps: hit error (px)"), a.set_xticks([]), a.set_yticks([])
fig.colorbar(h_, ax=ax[:2], shrink=0.8)
ax[2].plot(list(bisect), [bisect[n][2]["px_median"] for n in bisect], "o-", label="median hit error (px)")
ax[2].plot(list(bisect), [bisect[n][1]["correct"] for n in bisect], "s-", label="share correct")
ax[2].set_xlabel("BinarySearchIterations (20 march steps)"), ax[2].legend()
fig.suptitle("Step 6 — a few bisection steps instead of many march steps (§1.3)")
plt.show()
check("bisection shrinks the hit error", bisect[8][2]["px_median"] < 0.25 * bisect[0][2]["px_median"])
check("and turns near-misses into correct hits", bisect[8][1]["correct"] > bisect[0][1]["correct"])

# %% [markdown]
# ## 7. Fading out what the march cannot do (§1.4–1.5, Figs. 8–9)
#
# Near the screen edge the reflected ray soon leaves the image; a far hit is less trustworthy. Both are hidden
# by fading the reflection out rather than fixed:
#
# * circular edge fade (Fig. 8): `uvFactor = (2·|hitPixel − 0.5|)²`, `edge = max(0, 1 − uvFactor)`;
# * vignette (Fig. 9): `edge = saturate((u(1 − u)·v(1 − v)·EdgeDistance)^EdgeExponent)` at the pixel's own uv;
# * distance: `saturate(1 − (d / FadeDistance)^FadeExponent)`, `d = |rayOrg − hitPoint|`.

# %%
uv = cam.uv_grid(torch.float64)[None]
u_, v_ = uv[:, 0:1], uv[:, 1:2]
circular = (1 - (2 * ((u_ - 0.5) ** 2 + (v_ - 0.5) ** 2).sqrt()) ** 2).clamp_min(0)
vignette = (u_ * (1 - u_) * v_ * (1 - v_) * 50.0).abs().pow(1.0).clamp(0, 1)
pixels = cam.pixel_centers(torch.float64)[None]
check("the circular fade by hand equals edge_fade(mode='circular')",
      torch.allclose(circular, edge_fade(pixels, W, H, mode="circular"), atol=1e-12))
check("the vignette by hand equals edge_fade(mode='vignette')",
      torch.allclose(vignette, edge_fade(pixels, W, H, 50.0, 1.0, mode="vignette"), atol=1e-12))
d_ = torch.linspace(0, 15, 151, dtype=torch.float64)
check("the distance fade by hand equals distance_fade",
      torch.allclose((1 - (d_ / 10.0) ** 1.0).clamp(0, 1), distance_fade(d_, 10.0, 1.0)))

final = ssr_linear(g, LinearSSRParams(thickness=0.5, use_back_face_depth=True))
fig, ax = plt.subplots(1, 5, figsize=(18, 3.2), layout="constrained")
ax[0].imshow(circular[0, 0], cmap="gray"), ax[0].set_title("circular edge fade (Fig. 8)")
ax[1].imshow(vignette[0, 0], cmap="gray"), ax[1].set_title("vignette, EdgeDistance 50 (Fig. 9)")
ax[2].imshow(srgb(final.raw_color * mirror)), ax[2].set_title("SSR on the mirror, unfaded (raw_color)")
ax[3].imshow(srgb(final.color * mirror)), ax[3].set_title("SSR × fades (color)")
ax[4].imshow(srgb(truth.radiance * mirror)), ax[4].set_title("exact mirror reflection")
for a in ax:
    a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 7 — fades hide, they do not fix: compare the raw and faded reflection with the truth")
plt.show()
check("the pass's colour is its raw colour times its fade", torch.allclose(final.color, final.raw_color * final.fade))

# %% [markdown]
# ## Checks

# %%
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * `ssbench/passes/ssr/linear.py` (and its per-pixel twin `passes/teaching/ssr_linear_basic.py`),
#   `ssr/common.py`, `ssr/fade.py`; `ssbench/metrics/ssr.py` for the classes; `ssbench/metrics/thickness.py` for
#   how other engines spell `Thickness`.
# * `ssbench/reference/reflections.py` — the exact mirror ray; `ssbench ssr reflective_floor --method linear`.
# * Next: **lesson 5** (why the DDA interpolates `1/z`) and **lesson 6** (the DDA march and SSR's failure cases).
