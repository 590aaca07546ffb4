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
# # Lesson 6 — DDA screen-space reflections, and where SSR must fail
#
# ## Overview
#
# McGuire and Mara's *Efficient GPU Screen-Space Ray Tracing* (SSR article §2) marches the reflected ray across
# the **screen**, one pixel per step, with a line-drawing algorithm (a DDA). Lesson 5 showed the arithmetic that
# makes it possible: `P`, `Q = c·k` and `k = 1/w` are linear on the screen. This lesson draws lines the way
# §2.1 does, counts which pixels each march reads (Fig. 11), trades steps for speed with `PixelStride` and
# `Jitter` (Fig. 12), opens up the "half step" depth interval, refines coarse hits — and ends with the three
# situations of §4 (Figs. 14–16) where no screen-space method can find the reflection, as classified maps
# against the exact mirror ray.
#
# > **You will learn**
# > 1. DDA and Bresenham line drawing (§2.1), and why one pixel per column is the right budget;
# > 2. visit maps: the linear march skips and re-reads pixels, the DDA does neither (Fig. 11) — but it skips
# >    the corner pixels its line clips, which a supercover walk reads;
# > 3. `PixelStride` and `Jitter`: fewer steps, staircase vs noise (Fig. 12);
# > 4. the per-step depth interval `[rayZMin, rayZMax]` and the hit test, traced by hand for one ray;
# > 5. refining a strided hit by binary search or a short re-march;
# > 6. the three failure cases of §4: off-screen (Fig. 14), back-face (Fig. 15) and hidden targets (Fig. 16).

# %% [markdown]
# ## Setup

# %%
import math

import matplotlib.pyplot as plt
import numpy as np
import torch

from ssbench import reference
from ssbench.metrics import ssr as ssr_metrics
from ssbench.passes.ssr.common import HIT, TERMINATION_NAMES, clip_ray_length, reflection_rays
from ssbench.passes.ssr.dda import DDASSRParams, ssr_dda
from ssbench.passes.ssr.dda_rays import project_to_pixel_matrix
from ssbench.passes.ssr.dda_supercover import SupercoverDDASSRParams, ssr_dda_supercover
from ssbench.passes.ssr.visits import crossed_pixels, visit_map
from ssbench.scenes import load
from _setup import pick, size

W, H = size()
scene = load("reflective_floor")
g = reference.gbuffer(scene, W, H, channels=("view_z", "normal", "position", "mask", "color", "shape_id",
                                             "metallic"), spp=pick(256, 64))
cam, mask = g.camera, g.mask
truth = reference.reflections(scene, g, spp=pick(32, 8))
mirror = mask & (g.metallic > 0.5)
Z_THICKNESS = 0.5

checks = {}


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name


perfect = ssr_metrics.truth_classes(truth, g, reflective=mirror)       # what a perfect pass would get


def classes_of(result):
    classes, _ = ssr_metrics.classify(result, truth, g, reflective=mirror)
    return classes, ssr_metrics.class_fractions(classes, perfect)


def srgb(x):
    return x[0].permute(1, 2, 0).clamp(0, 1).pow(1 / 2.2).numpy()

# %% [markdown]
# ## 1. Drawing a line: DDA and Bresenham (§2.1)
#
# §2.1 gives two classic ways to draw a line on a grid (in Processing). Both take **one step along the major
# axis per pixel** and decide with an error term whether to step the minor axis too, so a line of length `n`
# along its major axis sets exactly `n + 1` pixels — no gaps, no doubles. Here they are, transliterated,
# drawing the article's two lines on a 20 × 20 canvas.

# %%
def draw_dda(p0, p1):
    """The article's 'DDA' (an integer error-term line): returns the pixels in drawing order."""
    (x, y), (x1, y1) = p0, p1
    dx, dy = abs(x1 - x), abs(y1 - y)
    step_x, step_y = (1 if x < x1 else -1), (1 if y < y1 else -1)
    err, out = dx - dy, []
    while True:
        out.append((x, y))
        if (x, y) == (x1, y1):
            return out
        err2 = 2 * err
        if err2 > -dy:
            err, x = err - dy, x + step_x
        if err2 < dx:
            err, y = err + dx, y + step_y


def draw_bresenham(p0, p1):
    """The article's Bresenham: swap to a shallow line, walk x, carry the error in y."""
    (x0, y0), (x1, y1) = p0, p1
    steep = abs(y1 - y0) > abs(x1 - x0)
    if steep:
        x0, y0, x1, y1 = y0, x0, y1, x1
    if x0 > x1:
        x0, x1, y0, y1 = x1, x0, y1, y0
    dx, dy = x1 - x0, abs(y1 - y0)
    err, y, step_y, out = dx // 2, y0, (1 if y0 < y1 else -1), []
    for x in range(x0, x1 + 1):
        out.append((y, x) if steep else (x, y))
        err -= dy
        if err < 0:
            y, err = y + step_y, err + dx
    return out


lines = [((2, 2), (18, 5)), ((5, 2), (8, 18))]
fig, ax = plt.subplots(1, 2, figsize=(10, 4.6), layout="constrained")
for a, draw, name in [(ax[0], draw_dda, "DDA (§2.1)"), (ax[1], draw_bresenham, "Bresenham (§2.1)")]:
    canvas = np.ones((20, 20, 3))
    for (p0, p1), colr in zip(lines, ([0, 0, 0], [1, 0, 0])):
        pixels = draw(p0, p1)
        for x, y in pixels:
            canvas[y, x] = colr
        crossed = crossed_pixels((p0[0] + 0.5, p0[1] + 0.5), (p1[0] + 0.5, p1[1] + 0.5), 20, 20)
        major = max(abs(p1[0] - p0[0]), abs(p1[1] - p0[1]))
        check(f"{name} sets one pixel per major-axis step on {p0}->{p1}", len(set(pixels)) == len(pixels) == major + 1)
        check(f"{name}: every pixel it sets is one the segment crosses ({p0}->{p1})",
              all(bool(crossed[y, x]) for x, y in pixels))
        a.plot([p0[0], p1[0]], [p0[1], p1[1]], "-", color="C0", lw=1)
    a.imshow(canvas, extent=(-0.5, 19.5, 19.5, -0.5))
    a.set_xticks(range(0, 20, 2)), a.set_yticks(range(0, 20, 2)), a.set_title(name)
fig.suptitle("Step 1 — one pixel per column (or row): the budget a screen-space march wants")
plt.show()

# %% [markdown]
# (`crossed_pixels` is the library's independent list of every pixel a segment passes through; a line-drawing
# algorithm picks a subset of it, one per major-axis step.)
#
# ## 2. Visit maps (Fig. 11)
#
# Fig. 11 compares how often each pixel's depth is read by one ray. Lesson 4's march takes equal steps in view
# space: close to the camera a step spans several pixels (**skipped** pixels — a thin object there is stepped
# over), far away many steps land in the same pixel (**oversampling**, wasted reads). The DDA reads exactly one
# pixel per row of its line (per column, for a flatter line): the line-drawing budget of Step 1. That is not
# every pixel the ray *crosses*: where the line passes from one column to the next inside a row, it clips the
# corner of a pixel the DDA never reads. A **supercover** walk (Amanatides & Woo's grid traversal,
# `ssr_dda_supercover`) steps across whichever pixel edge the segment meets next, so it reads each crossed pixel
# exactly once — a few more reads per ray, and no thin occluder hides in a clipped corner.

# %%
px, py = W // 2 + W // 5, int(0.85 * H)                                   # a floor pixel; its ray runs up the screen
origin = cam.uv_to_view(cam.uv_grid(torch.float64)[None], g.view_z.double())[0, :, py, px]         # rayOrg
direction = reflection_rays(origin.view(1, 3, 1, 1), g.normal.double()[:, :, py:py + 1, px:px + 1])[0, :, 0, 0]
stride1 = ssr_dda(g, DDASSRParams(z_thickness=Z_THICKNESS))                # every pixel, stride 1 (reused below)
hit_distance = float((stride1.hit_view[0, :, py, px].double() - origin).norm())

# lesson 4's march along the same ray, up to the same hit: equal steps in view space
step = 0.06 * 160 / W                                                      # ~2 px per step near, ~0.3 px far
samples = origin + torch.arange(1, int(hit_distance / step) + 1, dtype=torch.float64)[:, None] * step * direction
lin_visits = torch.zeros(H, W, dtype=torch.int32)
for x, y in cam.view_to_pixel(samples, dim=-1).floor().long().tolist():
    if 0 <= x < W and 0 <= y < H:
        lin_visits[y, x] += 1
dda = visit_map(g, DDASSRParams(z_thickness=Z_THICKNESS), (px, py))
sc = visit_map(g, SupercoverDDASSRParams(z_thickness=Z_THICKNESS), (px, py))

def per_row(visits):
    """Reads per image row, over the rows between the first and the last pixel read (the ray runs up the screen)."""
    rows = (visits > 0).any(1).nonzero().squeeze(1)
    return visits[int(rows.min()):int(rows.max()) + 1].sum(1)


check("this ray runs mostly up the screen (rows are its major axis)",
      abs(dda["p1"][1] - dda["p0"][1]) > abs(dda["p1"][0] - dda["p0"][0]))
fig, ax = plt.subplots(1, 3, figsize=(15, 4.2), layout="constrained")
for a, visits, title in [(ax[0], lin_visits, "linear view-space march (lesson 4)"), (ax[1], dda["visits"], "DDA"),
                         (ax[2], sc["visits"], "supercover DDA")]:
    rows, cols = (visits > 0).nonzero(as_tuple=True)
    window = (slice(max(0, int(rows.min()) - 2), int(rows.max()) + 3),
              slice(max(0, int(cols.min()) - 6), int(cols.max()) + 7))
    reads = per_row(visits)
    img = np.zeros((H, W, 3))
    img[(visits == 1).numpy()] = (0.2, 0.6, 0.2)                            # read once
    img[(visits > 1).numpy()] = (0.9, 0.1, 0.1)                             # read more than once
    empty_rows = torch.arange(int(rows.min()), int(rows.max()) + 1)[reads == 0]
    for r in empty_rows.tolist():
        img[r, window[1]] = np.maximum(img[r, window[1]], 0.35)              # a row the march never read
    a.imshow(img[window], interpolation="nearest", aspect="auto")
    a.set_title(f"{title}\nrows read twice or more: {int((reads > 1).sum())}, rows skipped (grey): {len(empty_rows)}",
                fontsize=9)
    a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 2 — which pixels one ray reads (Fig. 11): green once, red several times")
plt.show()
check("the DDA reads each row of its line exactly once", bool((per_row(dda["visits"]) == 1).all()))
check("every pixel the DDA reads lies on its segment", bool((dda["crossed"] | (dda["visits"] == 0)).all()))
sc_params = SupercoverDDASSRParams(z_thickness=Z_THICKNESS)
sc_hit = ssr_dda_supercover(g, sc_params).hit_pixel[0, :, py, px].tolist()   # where this ray stopped (its hit)
supercover_crossed = crossed_pixels(sc["p0"], sc_hit if sc["termination"] == HIT else sc["p1"], H, W)
supercover_crossed[py, px] = False                                          # the origin pixel is never read
check("the supercover reads each pixel at most once", int(sc["visits"].max()) == 1)
check("... and exactly the pixels its segment crosses up to where it stopped",
      bool(torch.equal(sc["visits"].bool(), supercover_crossed)))
check("the DDA's reads are a subset of the supercover's", bool((dda["visits"].bool() <= sc["visits"].bool()).all()))
print(f"reads along this ray: DDA {int(dda['visits'].sum())}, supercover {int(sc['visits'].sum())} "
      f"(corner pixels the DDA skips: {int((sc['visits'].bool() & ~dda['visits'].bool()).sum())})")
check("the linear march reads some rows several times (far away)", int((per_row(lin_visits) > 1).sum()) > 0)
check("and skips rows (close by)", int((per_row(lin_visits) == 0).sum()) > 0)

# %% [markdown]
# ## 3. `PixelStride` and `Jitter` (§2.2, Fig. 12)
#
# One read per pixel is still a lot. `PixelStride` steps several pixels at a time (less and less for origins
# farther than `PixelStrideZCutoff`), cutting the cost by the stride — and stepping over anything thinner than
# a stride. Every pixel's march then starts in the same phase, so the misses line up into a **staircase**.
# `Jitter` offsets each pixel's start by a random fraction of a stride: the staircase becomes noise.

# %%
strides = [1, 4, 8, 16]
runs = {(1, 0.0): (stride1, classes_of(stride1))}
for s, j in [(4, 0.0), (8, 0.0), (16, 0.0), (8, 1.0)]:
    result = ssr_dda(g, DDASSRParams(pixel_stride=s, jitter=j, refinement="none", z_thickness=Z_THICKNESS))
    runs[s, j] = (result, classes_of(result))
steps_of = {s: float(runs[s, 0.0][0].steps[mirror].float().mean()) for s in strides}

crop = (slice(int(0.55 * H), H), slice(int(0.35 * W), int(0.85 * W)))
fig, ax = plt.subplots(1, 4, figsize=(17, 3.4), layout="constrained", width_ratios=[1, 1, 1, 1.1])
for a, key, title in [(ax[0], (1, 0.0), "stride 1"), (ax[1], (8, 0.0), "stride 8, no jitter"),
                      (ax[2], (8, 1.0), "stride 8, jitter 1")]:
    result = runs[key][0]
    a.imshow(srgb(result.raw_color * mirror)[crop], interpolation="nearest")
    a.set_title(f"{title}: correct {runs[key][1][1]['correct']:.0%}", fontsize=9), a.set_xticks([]), a.set_yticks([])
ax[3].plot(strides, [steps_of[s] for s in strides], "o-", label="reads per ray")
ax[3].set_xlabel("PixelStride"), ax[3].set_ylabel("mean depth reads per ray")
ax3b = ax[3].twinx()
ax3b.plot(strides, [runs[s, 0.0][1][1]["correct"] for s in strides], "s--", color="C3")
ax3b.set_ylabel("share correct (no refinement)", color="C3")
fig.suptitle("Step 3 — stride trades reads for accuracy; jitter trades the staircase for noise (Fig. 12)")
plt.show()
check("a stride of 8 costs under a quarter of the reads of stride 1", steps_of[8] < 0.25 * steps_of[1])
check("and, unrefined, finds fewer correct hits", runs[8, 0.0][1][1]["correct"] < runs[1, 0.0][1][1]["correct"])

# %% [markdown]
# ## 4. The half-step depth interval, by hand (§2.2)
#
# At every step the DDA asks: over the footprint of this sample, `[P − ½dP, P + ½dP]`, does the ray's depth
# range `[rayZMin, rayZMax]` overlap the texel, seen as a solid box `[sceneZMax − zThickness, sceneZMax]`?
# `rayZMax` is lesson 5's half step, `(Q.z + ½dQ.z)/(k + ½dk)`; `rayZMin` is the previous step's `rayZMax`.
#
# ```
# hit ⇔ rayZMax ≥ sceneZMax − zThickness  and  rayZMin ≤ sceneZMax
# ```
#
# Here is the whole march for one ray at stride 1, written out (with the library's documented choices: the
# interval starts at the first footprint's edge, z is clamped to the segment, and the march stops at `P1`).

# %%
g64 = g.to(dtype=torch.float64)
params = DDASSRParams(z_thickness=Z_THICKNESS, refinement="none")
end = origin + direction * float(clip_ray_length(origin[2:], direction[2:], params.max_ray_distance, cam.near))
M = project_to_pixel_matrix(cam)
one = torch.ones(1, dtype=torch.float64)
H0, H1 = M @ torch.cat([origin, one]), M @ torch.cat([end, one])
k0, k1 = 1 / H0[3], 1 / H1[3]
Q0, Q1 = origin * k0, end * k1
P0, P1 = H0[:2] * k0, H1[:2] * k1
delta = P1 - P0
permute = bool(delta[0].abs() < delta[1].abs())                          # a more-vertical line: step in y
if permute:
    delta, P0, P1 = delta.flip(0), P0.flip(0), P1.flip(0)
step_dir = float(torch.sign(delta[0]))
inv_dx = step_dir / delta[0]
dP = torch.stack([torch.tensor(step_dir, dtype=torch.float64), delta[1] * inv_dx])
dQ, dk = (Q1 - Q0) * inv_dx, (k1 - k0) * inv_dx
z_lo, z_hi = min(origin[2], end[2]), max(origin[2], end[2])


def ray_z(qz, k):                                                         # Q.z / k, clamped to the segment
    return float(min(max(qz / k, z_lo), z_hi))


P, Qz, k = P0.clone(), float(Q0[2]), float(k0)
prev_z = ray_z(Qz + 0.5 * dQ[2], k + 0.5 * dk)                            # the first footprint's near edge
log, hit_pixel = [], None
scene_z, geometry = g64.view_z[0, 0], g64.mask[0, 0]
for step in range(params.max_steps):
    P, Qz, k = P + dP, Qz + float(dQ[2]), k + float(dk)                   # pqk += dPQK
    if P[0] * step_dir > P1[0] * step_dir:
        break                                                             # past the end point
    x, y = (P[1], P[0]) if permute else (P[0], P[1])                      # hitPixel
    if not (0 <= x < W and 0 <= y < H):
        break                                                             # off screen
    z_min, z_max = prev_z, ray_z(Qz + 0.5 * float(dQ[2]), k + 0.5 * float(dk))   # the half step
    prev_z = z_max
    z_min, z_max = min(z_min, z_max), max(z_min, z_max)                   # swapGEQ
    texel_z = float(scene_z[int(y), int(x)])
    log.append((z_min, z_max, texel_z))
    if geometry[int(y), int(x)] and z_max >= texel_z - params.z_thickness and z_min <= texel_z:
        hit_pixel = torch.tensor([float(x), float(y)], dtype=torch.float64)
        break

library = visit_map(g64, params, (px, py))                                # the pass's march of this one ray
print(f"hand march: hit at step {len(log)}, pixel {hit_pixel.numpy().round(3)}; ssr_dda: "
      f"{TERMINATION_NAMES[library['termination']]} after {int(library['visits'].sum())} reads, at "
      f"{stride1.hit_pixel[0, :, py, px].numpy().round(3)}")
check("the hand DDA hits, like ssr_dda", hit_pixel is not None and library["termination"] == HIT)
check("after the same number of depth reads", len(log) == int(library["visits"].sum()))
check("at the same pixel (the float32 pass agrees to 0.01 px)",
      torch.allclose(hit_pixel, stride1.hit_pixel[0, :, py, px].double(), atol=1e-2))

zs = np.array(log)
fig, ax = plt.subplots(figsize=(11, 3.6), layout="constrained")
n_ = np.arange(1, len(zs) + 1)
ax.bar(n_, zs[:, 1] - zs[:, 0], bottom=-zs[:, 1], width=0.6, color="C0", label="ray: [−rayZMax, −rayZMin]")
ax.bar(n_, np.full(len(zs), params.z_thickness), bottom=-zs[:, 2], width=0.9, color="C1", alpha=0.3,
       label="texel: [−sceneZMax, −sceneZMax + zThickness]")
ax.plot(n_[-1], -zs[-1, 2], "r*", ms=14, label="hit: the intervals overlap")
ax.set_xlabel("step (one pixel each)"), ax.set_ylabel("distance from the camera"), ax.legend(fontsize=8)
ax.set_title("Step 4 — the ray's depth over each footprint against the texel's box (§2.2)")
plt.show()

# %% [markdown]
# ## 5. Refining a strided hit (§1.3 applied to §2.2)
#
# With a stride of 8 the first sample that overlaps a texel can be up to 8 pixels past the true crossing.
# Two refinements, both reading a few more texels: **binary search** over the hit sample's footprint (the
# article's ±stride walk of §1.3), or G3D's **re-march** — back off one stride and walk single pixels.

# %%
refined = {}
for r in ("none", "binary", "remarch"):
    result = ssr_dda(g, DDASSRParams(pixel_stride=8, refinement=r, z_thickness=Z_THICKNESS))
    classes, frac = classes_of(result)
    pairs = torch.isin(classes, torch.tensor([ssr_metrics.CORRECT, ssr_metrics.FALSE_HIT, ssr_metrics.MISPLACED_HIT],
                                             dtype=classes.dtype))
    err = ssr_metrics.hit_error(result, truth, pairs)
    refined[r] = (result, classes, frac, err, float(result.steps[mirror].float().mean()))

fig, ax = plt.subplots(1, 3, figsize=(14, 3.6), layout="constrained")
for a, r in zip(ax, refined):
    result, classes, frac, err, reads = refined[r]
    a.imshow(ssr_metrics.class_rgb(classes)[crop], interpolation="nearest")
    a.set_title(f"stride 8, refinement '{r}'\ncorrect {frac['correct']:.0%}, misplaced {frac['misplaced_hit']:.0%}, "
                f"median error {err['px_median']:.2f} px, {reads:.0f} reads", fontsize=9)
    a.set_xticks([]), a.set_yticks([])
ax[0].legend(handles=ssr_metrics.legend_handles([1, 2, 3, 9, 4]), fontsize=7, loc="upper left")
fig.suptitle("Step 5 — refinement turns coarse hits back into correct ones for a few reads more")
plt.show()
check("binary refinement cuts the hit error of stride 8",
      refined["binary"][3]["px_median"] < 0.5 * refined["none"][3]["px_median"])
check("both refinements find more correct hits than none",
      min(refined["binary"][2]["correct"], refined["remarch"][2]["correct"]) > refined["none"][2]["correct"])

# %% [markdown]
# ## 6. Where SSR must fail (§4, Figs. 14–16)
#
# §4 lists three situations that no screen-space march can handle, because the answer is not in the depth
# buffer at all:
#
# * **Fig. 14 — the target is off screen** (or outside the frustum): the reflected ray leaves the image;
# * **Fig. 15 — the target is a back face**: the mirror sees the side of an object that faces away from the
#   camera; the depth buffer only has front faces;
# * **Fig. 16 — the target is hidden**: something nearer the camera covers it in the depth buffer.
#
# `ssbench.metrics.ssr.classify` labels them from the exact mirror ray (`on_screen`, `back_face`, `visible`),
# *before* looking at what the pass did — they stay failures however good the march. Where the pass still
# reported a hit there, the colour it shows is necessarily wrong: that is an error class of its own, *hit on
# an unfixable target* (dark magenta).

# %%
best = runs[1, 0.0]
result, (classes, frac) = best
class_img = ssr_metrics.class_rgb(classes)
names = ["off_screen_target", "back_face_target", "occluded_target"]
fig = plt.figure(figsize=(16, 4.4), layout="constrained")
sub = fig.subfigures(1, 3, width_ratios=[1.3, 1.5, 1.1])
a = sub[0].subplots()
a.imshow(class_img, interpolation="nearest"), a.set_xticks([]), a.set_yticks([])
a.set_title("DDA (stride 1) against the exact mirror ray")
sub[0].legend(handles=ssr_metrics.legend_handles([1, 2, 3, 9, 4, 5, 6, 7, 10]), fontsize=7, loc="lower center",
              ncol=4)
zoom = sub[1].subplots(1, 3)
for z_, code, title in zip(zoom, ssr_metrics.UNFIXABLE, ["Fig. 14: off screen", "Fig. 16: hidden", "Fig. 15: back face"]):
    ys, xs = (perfect[0, 0] == code).nonzero(as_tuple=True)
    cy, cx = int(ys.float().median()), int(xs.float().median())
    r_ = max(6, H // 10)
    z_.imshow(class_img[max(0, cy - r_):cy + r_, max(0, cx - r_):cx + r_], interpolation="nearest")
    z_.set_title(title, fontsize=9), z_.set_xticks([]), z_.set_yticks([])
a = sub[2].subplots()
x_ = np.arange(len(names))
a.bar(x_ - 0.2, [frac[n] for n in names], 0.4, label="the pass rightly returned nothing")
a.bar(x_ + 0.2, [frac[n + "_pass_hit"] for n in names], 0.4, label="the pass still 'hit' (an error)")
a.set_xticks(x_, ["Fig. 14\noff screen", "Fig. 15\nback face", "Fig. 16\nhidden"]), a.legend(fontsize=8)
a.set_title(f"unfixable {frac['unfixable']:.1%}, correct {frac['correct']:.1%}", fontsize=10)
fig.suptitle("Step 6 — the three failures of §4 as a classified map (dark magenta: the pass reported a hit anyway)")
plt.show()
perfect_frac = ssr_metrics.class_fractions(perfect)
print({n: f"{frac[n] + frac[n + '_pass_hit']:.3f}" for n in names}, "  perfect pass:",
      {n: f"{perfect_frac[n]:.3f}" for n in names})
check("all three failure cases occur in this scene", all(perfect_frac[n] > 0 for n in names))
unfixable_or_hit = torch.tensor(ssr_metrics.UNFIXABLE + (ssr_metrics.UNFIXABLE_HIT,), dtype=classes.dtype)
check("they are the same pixels for the pass (returning nothing or a wrong hit) and for a perfect pass",
      torch.equal(torch.isin(classes, unfixable_or_hit),
                  torch.isin(perfect, torch.tensor(ssr_metrics.UNFIXABLE, dtype=perfect.dtype))))
check("the split adds up: per target, nothing + hit = the perfect pass's share",
      all(abs(frac[n] + frac[n + "_pass_hit"] - perfect_frac[n]) < 1e-12 for n in names))

# %% [markdown]
# Off screen (Fig. 14): mirror rays from the near floor climb to the wall above the top of the frame, and the
# green ball is cut by the left edge. Back faces (Fig. 15): the undersides of both balls, which the mirror shows
# and the camera never sees. Hidden (Fig. 16): the red box behind the blue ball, and the patches of wall behind
# the balls and the pillar — the mirror sees them, the depth buffer holds the object in front. SSR article §4's
# conclusion stands: SSR still looks good, but only a fallback (reflection probes, ray tracing) can fill these
# pixels.
#
# ## Checks

# %%
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * `ssbench/passes/ssr/dda.py` (module docstring: every fix to the article's code, with reasons) and its
#   per-pixel twin `passes/teaching/ssr_dda_basic.py`; `ssbench/metrics/ssr.py` for the classes.
# * `ssbench ssr reflective_floor --method dda` and the SSR section of `make report`;
#   `benchmarks/` for marchers against the gather floor.
# * Lesson 4 (the linear march), lesson 5 (why `Q` and `k`).
