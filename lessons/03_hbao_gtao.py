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
# # Lesson 3 — Horizon-based AO (HBAO), GTAO, and what screen space cannot know
#
# ## Overview
#
# SSAO (lesson 2) throws points into a half-ball and counts. NVIDIA's **HBAO** (Bavoil & Sainz 2008, SSAO article
# §3) marches along a few lines in the image instead, and for each direction keeps the highest **horizon** the
# depth buffer rises to: whatever lies below the horizon is hidden from the sky. Its blur is depth-aware (a
# **cross-bilateral** filter) so shadows stop at silhouettes. We then meet **GTAO**, its modern,
# cosine-weighted descendant, and ask a question no single pass can answer: how much of the error is the
# *estimator's*, and how much is the information a depth buffer simply does not contain?
#
# > **You will learn**
# > 1. horizon angles, `sin h − sin t` and the falloff `W(r) = 1 − r²` (§3.1, Figs. 13–15), by marching one
# >    direction by hand;
# > 2. what `TanAngleBias` is for, on a faceted tunnel (Figs. 16–17);
# > 3. how `NUM_STEPS`, `calculateNumSteps` and `snapUVOffset` spend and place the samples (§3.3);
# > 4. the separable cross-bilateral blur of §3.2, and why it does not bleed across depth edges;
# > 5. GTAO, the three ground-truth *flavours* (uniform, cosine, obscurance) and which pass estimates which;
# > 6. the screen-space oracle: splitting the error into information loss and estimator error.

# %% [markdown]
# ## Setup

# %%
import math

import matplotlib.pyplot as plt
import numpy as np
import torch

from ssbench import evaluate, metrics, reference
from ssbench.passes.blur import box_blur, cross_bilateral_blur, default_blur_falloff
from ssbench.passes.common import fetch_uv
from ssbench.passes.ao.gtao import GTAOParams, gtao
from ssbench.passes.ao.hbao import HBAOParams, hbao
from ssbench.passes.ao.ssao import HemisphereSSAOParams, hemisphere_ssao
from ssbench.scenes import load
from _setup import pick, size

W, H = size()
R = 0.5                                              # the AO radius, for every pass and every ground truth
RAYS = pick(256, 128)

scene = load("cornell_box")
g = reference.gbuffer(scene, W, H)
cam, mask = g.camera, g.mask
obscurance = reference.ambient_occlusion(scene, g, R, rays=RAYS, weighting="obscurance", seed=0).ao

checks = {}


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name


def rmse(ao, target, m=mask):
    return float(metrics.rmse(ao, target, m))


def show(images, titles, suptitle, vmin=0.0, vmax=1.0):
    fig, ax = plt.subplots(1, len(images), figsize=(3.6 * len(images), 3.2), layout="constrained")
    for a, im, t in zip(np.atleast_1d(ax), images, titles):
        a.imshow(im[0, 0], cmap="gray", vmin=vmin, vmax=vmax)
        a.set_title(t, fontsize=9), a.set_xticks([]), a.set_yticks([])
    fig.suptitle(suptitle)
    plt.show()

# %% [markdown]
# ## 1. Horizons (§3.1, Fig. 13)
#
# Take a floor pixel just in front of a ball and walk up the screen, toward the ball, reading the depth buffer
# as we go. For each sample `S`, the vector `D = S − P` has an **elevation** above the view-space xy plane:
# `tan(elevation) = D.z / |D.xy|` (the article's `getTangent`). The **horizon** `h` is the highest elevation met
# so far within the radius; the **tangent** `t` is the elevation of the surface itself in that direction (from
# the depth-derived tangent vector, lesson 1 Step 7). Everything between `t` and `h` is blocked.

# %%
ball = load("sphere_on_plane")
g_ball = reference.gbuffer(ball, W, H)
cam_b = g_ball.camera
view_z_b = g_ball.view_z.double()
i0 = W // 2 + W // 40
lowest_ball_row = int((g_ball.shape_id[0, 0, :, i0] == 1).nonzero().max())
j0 = lowest_ball_row + H // 40                             # a floor pixel ~0.1 units in front of the ball
uv0 = cam_b.uv_grid(torch.float64)[:, j0, i0]               # its uv (v up)


def view_pos(uv):
    """HBAO's viewPos(uv): read the depth buffer (nearest texel), then uvToView."""
    uv = uv.reshape(1, 2, -1, 1)
    return cam_b.uv_to_view(uv, fetch_uv(view_z_b, uv), dim=1)[0, :, :, 0].T     # (N, 3)


P = view_pos(uv0)[0]
direction = torch.tensor([0.0, 1.0], dtype=torch.float64)                  # +v: up the screen
steps = torch.arange(1, H // 4 + 1, dtype=torch.float64)
S = view_pos(uv0[:, None] + direction[:, None] * steps / H)               # one texel per step
D = S - P                                                                  # (N, 3)
tan_s = D[:, 2] / D[:, :2].norm(dim=1)                                     # getTangent(D)
dist = D.norm(dim=1)

up = view_pos(uv0 + torch.tensor([0.0, 1.0 / H], dtype=torch.float64))[0] - P   # dPdv (one texel up)
tan_t = up[2] / up[:2].norm()                                              # the tangent's elevation
inside = dist < R
horizon = torch.cummax(torch.where(inside, tan_s, -torch.inf), 0).values.clamp_min(tan_t)

fig, ax = plt.subplots(1, 2, figsize=(13, 3.8), layout="constrained")
ax[0].imshow(g_ball.normal[0].permute(1, 2, 0) * 0.5 + 0.5)
ax[0].plot([i0, i0], [j0, j0 - len(steps)], "y-", lw=2), ax[0].plot(i0, j0, "yo")
ax[0].set_title("the pixel and the direction we march"), ax[0].set_xticks([]), ax[0].set_yticks([])
xy = D[:, :2].norm(dim=1)
ax[1].plot(xy[inside], D[inside, 2], "o", color="C0", label="samples within R")
ax[1].plot(xy[~inside], D[~inside, 2], "o", mfc="none", color="gray", label="beyond R (ignored)")
for tan_, name, c in [(tan_t, "tangent t", "C2"), (horizon[-1], "horizon h", "C3")]:
    ax[1].plot([0, R], [0, R * float(tan_)], "-", color=c, lw=2, label=f"{name}: {math.degrees(math.atan(tan_)):.1f}°")
ax[1].plot(0, 0, "k*", ms=12), ax[1].set_aspect("equal"), ax[1].set_xlim(0, 1.2 * R), ax[1].set_ylim(-R, R)
ax[1].set_xlabel("|D.xy|  (distance across the view)"), ax[1].set_ylabel("D.z  (toward the camera)")
ax[1].legend(fontsize=8, loc="upper left"), ax[1].set_title("the depth buffer seen from P, along the march")
fig.suptitle("Step 1 — the horizon: the highest the depth buffer rises within R (Fig. 13)")
plt.show()

# %% [markdown]
# ## 2. `sin h − sin t`, and the falloff `W(r) = 1 − r²` (§3.1, Figs. 14–15)
#
# The unblocked part of the sky in this direction runs from `h` up to the zenith; relative to the open case
# (from `t` up), the blocked fraction is `sin h − sin t` (Fig. 14: the sine measures solid angle for a uniform
# hemisphere). The march adds it up as the horizon rises, each rise weighted by `W(r) = 1 − r²`, `r = |S−P|/R`,
# so that an occluder fades out smoothly instead of popping at the radius (Fig. 15). The shader never calls
# `sin` or `atan`: `TanToSin(x) = x / √(1 + x²)`.

# %%
def tan_to_sin(x):
    return x / torch.sqrt(1 + x * x)


x = torch.linspace(-5, 5, 101, dtype=torch.float64)
check("TanToSin(x) = sin(atan(x))", torch.allclose(tan_to_sin(x), torch.sin(torch.atan(x)), atol=1e-12))

ao_dir, tan_h = 0.0, tan_t
contributions = []
for k in range(len(steps)):
    if inside[k] and tan_s[k] > tan_h:                                     # the horizon rises
        w = 1 - (dist[k] / R) ** 2                                         # W(r) = 1 - r^2
        ao_dir += float(w * (tan_to_sin(tan_s[k]) - tan_to_sin(tan_h)))
        contributions.append((float(xy[k]), float(w), ao_dir))
        tan_h = tan_s[k]
print(f"this direction is {ao_dir:.3f} occluded ({len(contributions)} rises of the horizon); "
      f"without the falloff it would be {float(tan_to_sin(horizon[-1]) - tan_to_sin(tan_t)):.3f}")

fig, ax = plt.subplots(1, 3, figsize=(14, 3.4), layout="constrained")
r_ = np.linspace(0, 1, 100)
ax[0].plot(r_, 1 - r_ ** 2, label="W(r) = 1 − r²"), ax[0].plot(r_, 1 - r_, "--", label="linear 1 − r")
ax[0].set_xlabel("r = |S − P| / R"), ax[0].legend(), ax[0].set_title("falloff (Fig. 15)")
ax[1].plot(xy[inside], tan_to_sin(tan_s[inside]), ".", color="C0", label="sin(elevation) of each sample")
ax[1].step(xy[inside], tan_to_sin(horizon[inside]), where="post", color="C3", label="sin h (running horizon)")
ax[1].axhline(float(tan_to_sin(tan_t)), color="C2", label="sin t")
ax[1].step([0] + [c[0] for c in contributions], [0] + [c[2] for c in contributions], where="post", color="k",
           label="Σ W(r)·(sin h − sin h_prev)")
ax[1].set_xlabel("|D.xy| of the sample"), ax[1].legend(fontsize=7), ax[1].set_title("one direction, step by step")
uniform = reference.ambient_occlusion(scene, g, R, rays=RAYS, weighting="uniform", seed=0).ao
ax[2].imshow(torch.cat([uniform, obscurance], 3)[0, 0], cmap="gray", vmin=0, vmax=1)
ax[2].set_title("ray-traced: binary (uniform) | weighted by 1 − (t/R)² (obscurance)", fontsize=9)
ax[2].set_xticks([]), ax[2].set_yticks([])
fig.suptitle("Step 2 — sin h − sin t, weighted by W(r) (Figs. 14–15)")
plt.show()
check("obscurance (hits weighted by W) is never darker than binary AO, ray for ray",
      bool((obscurance >= uniform - 1e-6).all()))

# %% [markdown]
# Why can one direction be more than 1 occluded? Elevations are measured from the view-space xy plane, not from
# the surface. Seen from above, this floor falls away steeply up the screen (`t ≈ −77°`) and rises just as
# steeply in the opposite direction, so `sin h − sin t` lies in [0, 2] per direction and only the average over
# all directions of a full circle is the occluded fraction in [0, 1].
#
# The falloff changes *what is being estimated*: the ground truth that matches HBAO is not binary visibility but
# **obscurance**, where a ray that hits at distance `t` counts `1 − (t/R)²` blocked (`weighting="obscurance"`;
# `ssbench.passes.ao.hbao.FLAVOUR`). Traced with the same rays it is never darker than the binary one.
#
# ## 3. The pass (§3.3)
#
# `hbao()` runs the article's shader for every pixel: `NUM_DIRECTIONS` directions rotated per pixel by a 4×4
# noise texture, `calculateNumSteps` samples each, horizon accumulation as above, `AO = 1 − ao/NUM_DIRECTIONS`.
# The march length is the disk of radius `R` projected to the screen: `radiusInPixels = 0.5·R·FocalLength /
# −P.z · AORes.x`, with `FocalLength = 1/tan(fov/2)·H/W` — close things get long marches, far things short.

# %%
params = HBAOParams(radius=R)
result = hbao(g, params, debug=True)
view_z = g.view_z.double()
ao_hbao = result.ao
focal_length = 1 / math.tan(math.radians(cam.fovy_deg) / 2) * H / W
radius_px = 0.5 * R * focal_length / -view_z * W                                   # diskRadiusInUV * AORes.x
check("radiusInPixels by hand equals the pass's (which reads z back from a float32 depth buffer)",
      torch.allclose(radius_px[mask], result.debug["radius_pixels"].double()[mask], rtol=1e-4))

fig, ax = plt.subplots(1, 4, figsize=(15, 3.2), layout="constrained")
for a, im, title, kw in [(ax[0], radius_px[0, 0], "radiusInPixels", dict(cmap="viridis")),
                         (ax[1], torch.rad2deg(result.debug["horizons"][0].mean(0)), "mean horizon elevation (deg)",
                          dict(cmap="magma")),
                         (ax[2], ao_hbao[0, 0], f"HBAO, RMSE {rmse(ao_hbao, obscurance):.3f}", dict(cmap="gray", vmin=0, vmax=1)),
                         (ax[3], obscurance[0, 0], "ray-traced obscurance", dict(cmap="gray", vmin=0, vmax=1))]:
    h_ = a.imshow(im, **kw)
    a.set_title(title, fontsize=9), a.set_xticks([]), a.set_yticks([])
    if "cmap" in kw and kw["cmap"] != "gray":
        fig.colorbar(h_, ax=a, shrink=0.8)
fig.suptitle("Step 3 — HBAO on the Cornell box")
plt.show()

# %% [markdown]
# ## 4. `TanAngleBias` on faceted geometry (§3.1, Figs. 16–17)
#
# A mesh is usually a stand-in for a smooth surface. Between two facets of a concave, coarsely tessellated
# surface, each facet sees its neighbour rise a few degrees above its own tangent plane, and HBAO darkens every
# edge (Fig. 16). The fix is to ignore occluders within an angle of the tangent (Fig. 17):
# `tanH = T.z/|T.xy| + TanAngleBias`. Below, a tunnel built from 16 flat strips (each bends 22.5° from the
# next) against a smooth cylinder of the same radius — scene descriptions are plain data.

# %%
def tunnel(facets=None, radius=1.5, length=30.0):
    """A tunnel along z: a smooth open cylinder, or `facets` rectangles around the same circle."""
    camera = {"eye": [0.3, 1.0, 4], "target": [0, 0.4, -2], "up": [0, 1, 0], "fovy": 50,
              "width": W, "height": H, "near": 0.1, "far": 100}
    lights = [{"type": "environment", "radiance": 1.0}]
    if facets is None:
        shapes = [{"type": "cylinder", "id": "tube", "p0": [0, radius, -length / 2], "p1": [0, radius, length / 2],
                   "radius": radius, "caps": False}]
    else:
        step = 2 * math.pi / facets
        inner = radius * math.cos(step / 2)                         # distance from the axis to a strip
        shapes = [{"type": "rectangle", "id": f"strip{k}", "size": [2 * radius * math.sin(step / 2) * 1.001, length],
                   "rotate": [-90, 0, math.degrees(k * step)],
                   "translate": [inner * math.sin(k * step), radius - inner * math.cos(k * step), 0]}
                  for k in range(facets)]
    return {"name": "tunnel", "camera": camera, "lights": lights, "shapes": shapes}


smooth, faceted = tunnel(), tunnel(facets=16)
g_smooth, g_faceted = reference.gbuffer(smooth, W, H), reference.gbuffer(faceted, W, H)
truth_smooth = reference.ambient_occlusion(smooth, g_smooth, R, rays=RAYS, weighting="obscurance").ao

# where the strips meet: a band around shape-id changes
sid = g_faceted.shape_id.float()
seam = torch.zeros_like(g_faceted.mask)
seam[..., :, 1:] |= sid[..., :, 1:] != sid[..., :, :-1]
seam[..., 1:, :] |= sid[..., 1:, :] != sid[..., :-1, :]
seam = torch.nn.functional.max_pool2d(seam.float(), 5, 1, 2) > 0
both = g_faceted.mask & g_smooth.mask


def line_contrast(ao):
    """Mean AO away from the seams minus mean AO on them: > 0 when the seams are drawn darker."""
    return float(ao[both & ~seam].mean() - ao[both & seam].mean())


biases = [0, 10, 20, 30, 40]
runs = {b: hbao(g_faceted, HBAOParams(radius=R, tan_angle_bias=math.tan(math.radians(b)))).ao for b in biases}
contrast = {b: line_contrast(runs[b]) for b in biases}
print("seam contrast of the smooth tunnel's truth:", round(line_contrast(truth_smooth), 4))

fig, ax = plt.subplots(1, 4, figsize=(15, 3.3), layout="constrained", width_ratios=[1, 1, 1, 1.1])
for a, im, title in [(ax[0], runs[0], "16 strips, TanAngleBias 0°"), (ax[1], runs[30], "16 strips, TanAngleBias 30°"),
                     (ax[2], truth_smooth, "smooth tunnel, ray traced")]:
    a.imshow(im[0, 0], cmap="gray", vmin=0.6, vmax=1), a.set_title(title, fontsize=9)
    a.set_xticks([]), a.set_yticks([])
ax[3].plot(biases, [contrast[b] for b in biases], "o-"), ax[3].axhline(0, color="k", lw=0.5)
ax[3].set_xlabel("TanAngleBias (degrees)"), ax[3].set_ylabel("seam darkening (mean AO off − on seams)")
fig.suptitle("Step 4 — facets darken their seams; the angle bias ignores occluders near the tangent (Figs. 16–17)")
plt.show()
check("a 30 degree bias removes most of the seam darkening", contrast[30] < 0.6 * contrast[0])
check("and the darkening falls steadily with the bias", all(contrast[a] > contrast[b] for a, b in zip(biases, biases[1:])))

# %% [markdown]
# The bias is not free: it removes *all* occlusion within 30° of the tangent, real or not. That is one reason
# HBAO comes out brighter than the ray-traced truth in Step 3's room, whose creases are 90°.
#
# ## 5. Step counts and snapping (§3.3)
#
# `calculateNumSteps` spends `numSteps = min(NUM_STEPS, radiusInPixels)` samples per direction (never more
# than one per pixel) of `stepSizeInPixels = radiusInPixels / (numSteps + 1)`, and when the projected radius
# exceeds `MaxRadiusPixels` it clamps the step size and dithers the step count with the noise texture.
# `snapUVOffset` then rounds every offset to a texel centre: `round(uv·AORes)/AORes`, so each sample reads a
# texel exactly instead of a filtered blend of two depths.

# %%
num_steps = torch.minimum(torch.full_like(radius_px, float(params.num_steps)), radius_px)
step_px = radius_px / (num_steps + 1)
unclamped = mask & (radius_px > 1) & (params.max_radius_pixels / step_px >= num_steps)
print(f"{float(unclamped.sum() / mask.sum()):.0%} of the pixels need no MaxRadiusPixels clamp")
check("calculateNumSteps by hand equals the pass's numSteps",
      torch.allclose(num_steps[unclamped], result.debug["num_steps"].double()[unclamped], rtol=1e-5))

counts = [2, 3, 4, 6, 8, 12, 16]
step_rmse = [rmse(hbao(g, HBAOParams(radius=R, num_steps=n)).ao, obscurance) for n in counts]

fig, ax = plt.subplots(1, 2, figsize=(12, 3.6), layout="constrained")
ax[0].plot(counts, step_rmse, "o-"), ax[0].set_xlabel("NUM_STEPS"), ax[0].set_ylabel("RMSE vs obscurance")
ax[0].set_title("more steps, fewer missed occluders")
angle = math.radians(25)
t_ = np.arange(1, 7) * 2.3
raw_xy = np.stack([3.5 + t_ * math.cos(angle), 2.5 + t_ * math.sin(angle)], 1)
snapped = np.floor(raw_xy) + 0.5                                    # the texel centres the samples read
for k in range(15):
    ax[1].axhline(k, color="0.85", lw=0.8), ax[1].axvline(k, color="0.85", lw=0.8)
ax[1].plot(*raw_xy.T, "o", mfc="none", ms=9, label="unsnapped sample positions")
ax[1].plot(*snapped.T, "s", color="C3", ms=6, label="snapUVOffset: texel centres")
ax[1].plot([3.5, raw_xy[-1, 0]], [2.5, raw_xy[-1, 1]], "k-", lw=0.8)
ax[1].set_xlim(2, 17), ax[1].set_ylim(1, 9), ax[1].set_aspect("equal"), ax[1].legend(fontsize=8)
ax[1].set_title("snapping: every sample reads exactly one texel")
fig.suptitle("Step 5 — NUM_STEPS, calculateNumSteps and snapUVOffset (§3.3)")
plt.show()
check("more steps help: 16 steps beat 2 steps", step_rmse[-1] < step_rmse[0])

# %% [markdown]
# ## 6. The cross-bilateral blur (§3.2)
#
# HBAO's noise is removed by a separable blur: a horizontal pass, then a vertical one, each
#
# ```
# weight(i) = exp(−i²·blurFalloff) · (|z_i − z_0| < threshold)          i = −KERNEL_RADIUS … KERNEL_RADIUS − 1
# out = (ao_0 + Σ weight(i)·ao_i) / (1 + Σ weight(i))
# ```
#
# — a Gaussian that refuses to average across a depth jump. On an image one pixel tall, the vertical pass sees
# only the pixel itself and changes nothing, so the library on a single row *is* one horizontal pass — which we
# can write out, exactly as the article's loop (the centre counts twice, the loop stops one short on the right):

# %%
row = H // 2
ao_row, z_row = ao_hbao[:, :, row:row + 1].double(), view_z[:, :, row:row + 1]
K_R, threshold = 15, 0.1
falloff = default_blur_falloff(K_R)
by_hand = torch.empty(W, dtype=torch.float64)
for x0 in range(W):
    total, weight_total = float(ao_row[0, 0, 0, x0]), 1.0
    for i in range(-K_R, K_R):                                             # for (i = -R; i < R; i++)
        xi = min(max(x0 + i, 0), W - 1)                                    # CLAMP_TO_EDGE
        w = math.exp(-i * i * falloff) * (abs(z_row[0, 0, 0, xi] - z_row[0, 0, 0, x0]) < threshold)
        total += float(ao_row[0, 0, 0, xi]) * w
        weight_total += w
    by_hand[x0] = total / weight_total
library_row = cross_bilateral_blur(ao_row, z_row, K_R, falloff, threshold)
check("the article's blur loop by hand equals cross_bilateral_blur on one row",
      torch.allclose(by_hand, library_row[0, 0, 0], atol=1e-12))

# a toy: AO that is 0.3 in front of a depth step and 1.0 behind it
toy_z = torch.full((1, 1, 8, 24), -2.0, dtype=torch.float64)
toy_z[..., 12:] = -5.0
toy_ao = torch.where(toy_z > -3, 0.3, 1.0)
check("a depth step stops the cross-bilateral blur completely",
      torch.equal(cross_bilateral_blur(toy_ao, toy_z, 4), toy_ao))
check("while a box blur smears across it", not torch.allclose(box_blur(toy_ao, 5), toy_ao))

boxed, bilateral = box_blur(ao_hbao, 5), cross_bilateral_blur(ao_hbao, g.view_z)
fig, ax = plt.subplots(1, 4, figsize=(16, 3.3), layout="constrained", width_ratios=[1, 1, 1, 1.3])
for a, im, title in [(ax[0], ao_hbao, "HBAO, raw"), (ax[1], boxed, "5×5 box blur"),
                     (ax[2], bilateral, "cross-bilateral (R 15)")]:
    a.imshow(im[0, 0], cmap="gray", vmin=0, vmax=1), a.axhline(int(0.86 * H), color="y", lw=0.8)
    a.set_title(title), a.set_xticks([]), a.set_yticks([])
prof = int(0.86 * H)
for im, name in [(ao_hbao, "raw"), (boxed, "box"), (bilateral, "cross-bilateral")]:
    ax[3].plot(im[0, 0, prof].numpy(), label=name, lw=1)
ax3b = ax[3].twinx()
ax3b.plot(torch.where(mask[0, 0, prof], -g.view_z[0, 0, prof], torch.nan).numpy(), "k:", lw=1)
ax3b.set_ylabel("depth −z (dotted)")
ax[3].legend(fontsize=8), ax[3].set_title("the yellow row"), ax[3].set_xlabel("column")
fig.suptitle("Step 6 — the cross-bilateral blur keeps shadows on their own side of a depth edge (§3.2)")
plt.show()

# %% [markdown]
# ## 7. GTAO, and the three flavours of ground truth
#
# **GTAO** (Jimenez et al. 2016; ssbench follows Intel's XeGTAO) also finds two horizons per slice, but
# integrates the visible arc analytically with a **cosine** weight — the physically based ambient occlusion.
# Each pass estimates a particular *flavour* of AO, declared as `FLAVOUR` in its module:
#
# | pass | estimates | ground truth |
# |---|---|---|
# | SSAO (lesson 2) | volume fraction, unweighted | `uniform`: binary, uniform over the hemisphere |
# | HBAO | `sin h − sin t` with `W(r)` | `obscurance`: uniform, hits weighted `1 − (t/R)²` |
# | GTAO | cosine-weighted visible arc | `cosine`: binary, cosine-weighted |
#
# Comparing every pass with every flavour shows how much the choice of yardstick matters.

# %%
flavours = {"uniform": uniform, "cosine": reference.ambient_occlusion(scene, g, R, rays=RAYS, weighting="cosine").ao,
            "obscurance": obscurance}
passes = {"ssao": hemisphere_ssao(g, HemisphereSSAOParams(kernel_radius=R, kernel_size=32)).ao,
          "hbao": ao_hbao, "gtao": gtao(g, GTAOParams(radius=R)).ao}
table = np.array([[rmse(passes[p], flavours[f]) for f in flavours] for p in passes])

fig, ax = plt.subplots(1, 4, figsize=(16, 3.4), layout="constrained", width_ratios=[1, 1, 1, 1.2])
for a, (name, im) in zip(ax, flavours.items()):
    a.imshow(im[0, 0], cmap="gray", vmin=0, vmax=1), a.set_title(f"ray traced: {name}")
    a.set_xticks([]), a.set_yticks([])
h_ = ax[3].imshow(table, cmap="viridis_r")
for (p_, f_), v in np.ndenumerate(table):
    ax[3].text(f_, p_, f"{v:.3f}", ha="center", va="center", color="w" if v > table.mean() else "k")
ax[3].set_xticks(range(3), list(flavours)), ax[3].set_yticks(range(3), list(passes))
ax[3].set_title("RMSE: pass (row) vs flavour (column)")
fig.suptitle("Step 7 — one scene, three kinds of 'correct'")
plt.show()
check("GTAO is the closest pass to the cosine ground truth", table[2, 1] == table[:, 1].min())
check("HBAO is closer to obscurance than to binary visibility", table[1, 2] < table[1, 0])

# %% [markdown]
# In this room every pass is on average *brighter* than every flavour, so the brightest flavour (obscurance)
# is nearest to all of them: the heuristics — `TanAngleBias`, range checks, falloffs — each remove a little
# occlusion. GTAO, with the fewest heuristics, is the most accurate against the physically based (cosine) truth.
# A pass's `FLAVOUR` says what it converges to without its heuristics, not which yardstick it scores best on.
#
# ## 8. Information loss vs estimator error: the screen-space oracle
#
# A pass sees only the depth buffer. `reference.screen_space_oracle` traces the *same rays* as the ground truth,
# but against the depth buffer turned into a height-field mesh — exactly, and only, what a screen-space pass
# could know (everything behind a visible surface is assumed solid). So the error of a pass splits in two:
#
# * **information loss** = oracle − truth: what no screen-space method can fix (hidden and off-screen geometry);
# * **estimator error** = pass − oracle: what a better screen-space method could fix.

# %%
cosine = flavours["cosine"]
oracle = reference.screen_space_oracle(g, R, rays=RAYS, weighting="cosine", seed=0).ao
info_loss, estimator = rmse(oracle, cosine), rmse(passes["gtao"], oracle)
print(f"GTAO vs truth {rmse(passes['gtao'], cosine):.3f}: information loss {info_loss:.3f}, estimator {estimator:.3f}")

fig, ax = plt.subplots(1, 4, figsize=(16, 3.3), layout="constrained")
for a, im, title, kw in [(ax[0], cosine, "truth (cosine)", dict(cmap="gray", vmin=0, vmax=1)),
                         (ax[1], oracle, "oracle: same rays vs the depth buffer", dict(cmap="gray", vmin=0, vmax=1)),
                         (ax[2], oracle - cosine, "information loss: oracle − truth", dict(cmap="RdBu", vmin=-0.5, vmax=0.5)),
                         (ax[3], passes["gtao"] - oracle, "estimator error: GTAO − oracle",
                          dict(cmap="RdBu", vmin=-0.5, vmax=0.5))]:
    h_ = a.imshow(im[0, 0], **kw)
    a.set_title(title, fontsize=9), a.set_xticks([]), a.set_yticks([])
fig.colorbar(h_, ax=ax[2:], shrink=0.8, label="red: too dark, blue: too bright")
fig.suptitle("Step 8 — what the depth buffer cannot know, and what the estimator gets wrong")
plt.show()

# %% [markdown]
# The oracle is *darker* than the truth around the blocks: a height field has no gap behind a silhouette, so
# every depth edge becomes a wall reaching back to whatever lies behind. Real passes fight exactly that with
# range checks and falloffs (lesson 2 Step 6), which is one more reason they end up brighter.
#
# `ssbench.evaluate.ao` does all of this in one call and returns one tidy row; its numbers are the ones above.

# %%
row_ = evaluate.ao(scene, "gtao", {"radius": R}, width=W, height=H, rays=RAYS, weighting="cosine", repeats=1,
                   warmup=False, flip=False, gbuffer=g)
print({k: round(row_[k], 4) for k in ("rmse_cos", "info_loss_rmse", "estimator_rmse")})
check("evaluate.ao reports the same information loss", math.isclose(row_["info_loss_rmse"], info_loss, rel_tol=1e-5))
check("and the same estimator error", math.isclose(row_["estimator_rmse"], estimator, rel_tol=1e-5))

# %% [markdown]
# ## 9. Beyond the horizon: visibility bitmasks (Therrien et al. 2023)
#
# Step 8's oracle is darker than the truth because a depth buffer turns every silhouette into a wall reaching
# back forever, and a *horizon* method (HBAO, GTAO) inherits that: one high sample hides the whole sky behind
# it. **Visibility-bitmask AO** gives every sample a constant `thickness` instead. Per slice, the half circle
# around the projected normal is cut into 32 sectors; a sample occludes only the sectors between its front face
# and a back face `thickness` farther from the camera (`UpdateSectors`), and the slice's visibility is the share
# of sectors left clear. Light passes behind thin things; with an infinite thickness it is a horizon method
# again. `ssbench/passes/ao/vbao.py` is the pass; `ssbench/passes/teaching/vbao_basic.py` the same loop one
# pixel at a time, one function per step (slice frame, sample pixel, front/back angles, update sectors,
# slice visibility), tested equal to it.

# %%
from ssbench.passes.ao.vbao import VBAOParams, vbao

thick = {t: vbao(g, VBAOParams(radius=R, thickness=t, weighting="cosine")).ao for t in (0.05, 0.25, 1.0, 1e3)}
for t, ao in thick.items():
    print(f"VBAO thickness {t:>6}: RMSE vs cosine truth {rmse(ao, cosine):.3f}, mean AO {float(ao[mask].mean()):.3f}")
print(f"GTAO (for scale):          RMSE vs cosine truth {rmse(passes['gtao'], cosine):.3f}")
show([thick[0.05], thick[1e3], thick[0.05] - thick[1e3]],
     ["VBAO, thickness 0.05", "VBAO, thickness 1000 (a horizon)", "thin − thick (light behind things)"],
     "Step 9 — thickness decides what a sample hides", vmin=0.0, vmax=1.0)
ts = sorted(thick)
darker = [float((thick[b] <= thick[a] + 1e-6)[mask].float().mean()) for a, b in zip(ts, ts[1:])]
print("share of pixels no brighter after each thickness step:", [f"{x:.1%}" for x in darker])
check("a thicker sample hides more: on average, and at 9 pixels in 10",
      all(float(thick[b][mask].mean()) < float(thick[a][mask].mean()) for a, b in zip(ts, ts[1:]))
      and min(darker) > 0.9)
check("an infinitely thick sample over-occludes like a height field",
      float(thick[1e3][mask].mean()) < float(cosine[mask].mean()) - 0.05)
uniform_count = vbao(g, VBAOParams(radius=R, thickness=0.25)).ao
check("the paper's uniform count is darker than its cosine-weighted variant",
      float(uniform_count[mask].mean()) < float(thick[0.25][mask].mean()))

# %% [markdown]
# The paper counts sectors uniformly (`1 − countbits/32`); `weighting="cosine"` weights each clear sector by its
# share of GTAO's cosine integral, so it targets the same truth as GTAO. Two things to notice: the thickness is a
# scene-scale guess (too thin: things float; too thick: halos come back), and the paper's `ceil` marks a sector a
# sample merely touches, so samples on the pixel's own plane darken open floors a little (pinned in
# `tests/passes/ao/test_vbao.py`). `UpdateSectors` also marks `ceil(width·32)` sectors from the first one rather
# than every sector up to the arc's end, so a longer arc can drop its last sector: thickness is monotone on
# average, not pixel by pixel (above: about one pixel in twenty gets brighter at a step). `benchmarks/sweeps/vbao_fence.yaml` sweeps thickness against GTAO on the fence.

# %% [markdown]
# ## Checks

# %%
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * `ssbench/passes/ao/hbao.py` and its per-pixel twin `ssbench/passes/teaching/hbao_basic.py` (the shader of §3.3
#   line by line, tested equal to the pass); `ssbench/passes/ao/gtao.py`, `ao/gtao_denoise.py`, `blur.py`.
# * `ssbench/reference/ao.py` — the three flavours and `screen_space_oracle`; `ssbench/evaluate/_ao.py`.
# * `ssbench/passes/ao/vbao.py` and `ssbench/passes/teaching/vbao_basic.py` — visibility bitmasks (Step 9).
# * `ssbench ao cornell_box --method hbao --param radius=0.5` and the AO section of `make report`.
# * Next: **lesson 4**, screen-space reflections.
