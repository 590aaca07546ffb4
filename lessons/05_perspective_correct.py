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
# # Lesson 5 — Perspective-correct interpolation
#
# ## Overview
#
# Lesson 4 marched in **view space**: equal steps along the 3-D ray. On screen those steps are not equal — they
# bunch up in the distance and spread out up close, so the march reads some pixels many times and skips others
# (SSR article Fig. 11, left). McGuire and Mara's DDA (lesson 6) marches in **screen space** instead, one pixel at
# a time. But then it must know, at each pixel, where on the 3-D ray it is — and depth is *not* linear in
# screen space. SSR article's appendix A derives what is: `1/z`, and any attribute divided by `z`. This lesson
# checks the derivation numerically, then shows why the DDA interpolates exactly `Q = c/w` and `k = 1/w`.
#
# > **You will learn**
# > 1. why equal steps on the screen are unequal steps on a surface (Fig. 17);
# > 2. that `1/z` is linear in screen space (appendix A, eqs. 1–6), to machine precision;
# > 3. the perspective-correct attribute `b' = z'·((1 − t)·b₁/z₁ + t·b₂/z₂)` (eqs. 7–15), and what the naive
# >    linear blend gets wrong;
# > 4. why the DDA carries `Q = c·k` and `k = 1/H.w`, and recovers the view-space point as `Q/k`;
# > 5. the "half step" `(Q.z + ½dQ.z)/(k + ½dk)` that the SSR article (§2.2) admits it does not understand.

# %% [markdown]
# ## Setup

# %%
import matplotlib.pyplot as plt
import numpy as np
import torch

from ssbench import reference
from ssbench.passes.ssr.common import clip_ray_length, reflection_rays
from ssbench.passes.ssr.dda import DDASSRParams
from ssbench.passes.ssr.dda_rays import project_to_pixel_matrix
from ssbench.passes.ssr.visits import visit_map
from ssbench.scenes import load
from _setup import size

F64 = torch.float64                                   # every number here in double precision
W, H = size()

checks = {}


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name

# %% [markdown]
# ## 1. Equal steps on the screen are unequal on the surface (Fig. 17)
#
# The appendix's picture, in the x–z plane: the eye `O` at the origin, the projection plane at `z = −e`, and a
# surface segment from `(x₁, z₁)` to `(x₂, z₂)`. A point `(x, z)` projects to `p = −e·x/z` (similar triangles,
# eq. 2). Walk the screen in equal steps between `p₁` and `p₂` and see where the rays land on the segment.

# %%
e = 1.0
x1, z1, x2, z2 = -2.0, -1.5, 7.0, -6.0                   # a surface receding from the camera
p1, p2 = -e * x1 / z1, -e * x2 / z2                        # eq. (2)
t = torch.linspace(0, 1, 9, dtype=F64)
p_t = (1 - t) * p1 + t * p2                                # eq. (5): equal steps on the screen

# the line through the two points: a·x + b·z = c (eq. 1)
a, b = z2 - z1, x1 - x2
c = a * x1 + b * z1
z_hit = c / (-a * p_t / e + b)                             # eq. (3) solved for z
x_hit = -p_t * z_hit / e

fig, ax = plt.subplots(figsize=(9, 4.2), layout="constrained")
ax.plot([x1, x2], [z1, z2], "k-", lw=3, label="surface")
for xh, zh in zip(x_hit, z_hit):
    ax.plot([0, xh], [0, zh], color="C0", lw=0.7)
ax.plot(x_hit, z_hit, "o", color="C3", label="where equal screen steps land")
ax.plot(p_t, torch.full_like(p_t, -e), "s", color="C0", label="equal steps on the screen (z = −e)")
ax.axhline(-e, color="C0", lw=0.5), ax.plot(0, 0, "k*", ms=12)
ax.set_xlabel("x"), ax.set_ylabel("z (view space, −z is forward)"), ax.set_aspect("equal"), ax.legend(fontsize=8)
ax.set_title("Step 1 — screen-space steps stretch with distance (Fig. 17)")
plt.show()

gaps = (torch.diff(x_hit) ** 2 + torch.diff(z_hit) ** 2).sqrt()
print("distance between consecutive landing points:", gaps.numpy().round(3))
check("equal screen steps land farther apart on the far part of the surface", bool((torch.diff(gaps) > 0).all()))

# %% [markdown]
# ## 2. `1/z` is linear on the screen (eqs. 1–6)
#
# Substitute `x = −p·z/e` into the line `a·x + b·z = c`: `(−a·p/e + b)·z = c`, so `1/z = −a·p/(c·e) + b/c` —
# an affine function of `p`. Any affine function of `p` is interpolated exactly by the same weights as `p`:
#
# `1/z' = (1 − t)/z₁ + t/z₂`  (eq. 6)
#
# while `z` itself is not. Check it on a thousand screen positions:

# %%
t = torch.linspace(0, 1, 1001, dtype=F64)
p_t = (1 - t) * p1 + t * p2
z_true = c / (-a * p_t / e + b)                             # intersect each pixel's ray with the surface
inv_z_lerp = (1 - t) / z1 + t / z2                          # eq. (6)
z_lerp = (1 - t) * z1 + t * z2                              # the naive guess
err_inv = float((1 / z_true - inv_z_lerp).abs().max())
err_naive = float((z_true - z_lerp).abs().max())
print(f"max |1/z − lerp(1/z)| = {err_inv:.1e}    max |z − lerp(z)| = {err_naive:.2f}")
check("1/z is linear in screen space (eq. 6)", err_inv < 1e-12)
check("z is not", err_naive > 0.5)

fig, ax = plt.subplots(1, 2, figsize=(12, 3.4), layout="constrained")
ax[0].plot(t, -z_true, label="true depth −z'"), ax[0].plot(t, -z_lerp, "--", label="linear blend of z")
ax[0].set_xlabel("t (screen)"), ax[0].legend(), ax[0].set_title("depth is curved in screen space")
ax[1].plot(t, -1 / z_true, label="−1/z'"), ax[1].plot(t[::50], -inv_z_lerp[::50], "o", label="lerp of −1/z")
ax[1].set_xlabel("t (screen)"), ax[1].legend(), ax[1].set_title("its reciprocal is a straight line")
fig.suptitle("Step 2 — interpolate 1/z, not z (appendix A, eq. 6)")
plt.show()

# %% [markdown]
# ## 3. Any attribute: divide by `z`, interpolate, multiply back (eqs. 7–15)
#
# Give the endpoints an attribute `b₁`, `b₂` (a texture coordinate, a colour, a view-space position). On the
# surface it varies linearly with distance along the segment. The appendix's algebra ends in
#
# `b' = z'·((1 − t)·b₁/z₁ + t·b₂/z₂)`    with `1/z'` from eq. (6)   (eq. 15)
#
# — interpolate `b/z` and `1/z` linearly on the screen, then divide. Let `b` be a texture coordinate running
# from 0 to 8 along the surface and compare with the truth (where the ray really lands) and with a naive blend.

# %%
b1, b2 = 0.0, 8.0
s_true = (z_true - z1) / (z2 - z1)                           # where on the segment each ray lands
b_true = (1 - s_true) * b1 + s_true * b2
z_prime = 1 / inv_z_lerp
b_correct = z_prime * ((1 - t) * b1 / z1 + t * b2 / z2)      # eq. (15)
b_naive = (1 - t) * b1 + t * b2
check("the perspective-correct attribute matches the truth (eq. 15)", float((b_correct - b_true).abs().max()) < 1e-12)

fig, ax = plt.subplots(1, 2, figsize=(12, 3.2), layout="constrained")
ax[0].plot(t, b_true, label="true"), ax[0].plot(t, b_naive, "--", label="naive lerp of b")
ax[0].plot(t[::50], b_correct[::50], "o", label="z'·lerp(b/z)")
ax[0].set_xlabel("t (screen)"), ax[0].set_ylabel("b"), ax[0].legend()
stripes = lambda v: (np.floor(v.numpy()) % 2)[None].repeat(30, 0)      # noqa: E731  a checkerboard row
ax[1].imshow(np.concatenate([stripes(b_correct), np.ones((4, len(t))), stripes(b_naive)]), cmap="gray",
             aspect="auto"), ax[1].set_yticks([15, 49], ["perspective-correct", "naive"]), ax[1].set_xticks([])
ax[1].set_title("stripes on the receding surface, on screen")
fig.suptitle("Step 3 — perspective-correct attributes (eqs. 7–15)")
plt.show()

# %% [markdown]
# ## 4. Why the DDA carries `Q` and `k` (§2.2)
#
# The DDA projects both ends of the reflected ray with a matrix that maps view space to **pixels**
# (`project_to_pixel_matrix`: `gluPerspective`, then NDC → pixels), `H = M·(c, 1)`, and keeps
#
# ```
# k = 1 / H.w          (= −1/z: eq. 6's 1/z)         Q = c · k     (eq. 13's numerator: the attribute c over z)
# P = H.xy · k         (the pixel)
# ```
#
# `P`, `Q` and `k` are all linear in screen space, so the DDA can step them with constant increments
# `dP, dQ, dk`, and at any step recover the exact view-space point on the ray as `Q / k` (eq. 15). Let us do it
# for a real reflection ray of the mirror floor — and check our end points against the library's.

# %%
scene = load("reflective_floor")
g = reference.gbuffer(scene, W, H, channels=("view_z", "normal", "mask", "color"), spp=16)
cam = g.camera
px, py = W // 2 + W // 5, int(0.85 * H)                                       # a floor pixel
origin = cam.uv_to_view(cam.uv_grid(F64)[None], g.view_z.double())[0, :, py, px]  # rayOrg
direction = reflection_rays(origin.view(1, 3, 1, 1), g.normal.double()[:, :, py:py + 1, px:px + 1])[0, :, 0, 0]
params = DDASSRParams()
length = float(clip_ray_length(origin[2:], direction[2:], params.max_ray_distance, cam.near))
end = origin + direction * length                                              # rayEnd

M = project_to_pixel_matrix(cam)
one = torch.ones(1, dtype=F64)
H0, H1 = M @ torch.cat([origin, one]), M @ torch.cat([end, one])
k0, k1 = 1 / H0[3], 1 / H1[3]
Q0, Q1 = origin * k0, end * k1
P0, P1 = H0[:2] * k0, H1[:2] * k1
print("P0, P1 by hand:", P0.numpy().round(3), P1.numpy().round(3))
library = visit_map(g, params, (px, py))
print("P0, P1 of ssr_dda:", np.round(library["p0"], 3), np.round(library["p1"], 3))
check("our end points equal the DDA's", np.allclose(P0.numpy(), library["p0"], atol=1e-6)
      and np.allclose(P1.numpy(), library["p1"], atol=1e-6))
check("k = 1/H.w = -1/z", torch.isclose(k0, -1 / origin[2]) and torch.isclose(k1, -1 / end[2]))

# walk the screen in equal steps: P, Q, k all move linearly
s = torch.linspace(0, 1, 33, dtype=F64)[:, None]
P_s = (1 - s) * P0 + s * P1
Q_s, k_s = (1 - s) * Q0 + s * Q1, (1 - s) * k0 + s * k1
point = Q_s / k_s                                                              # the view-space point, eq. (15)
to_ray = point - origin
along = to_ray @ direction
off_ray = (to_ray - along[:, None] * direction).norm(dim=1)
reprojected = cam.view_to_pixel(point, dim=-1)
check("Q/k lies on the 3-D ray", float(off_ray.max()) < 1e-9)
check("and projects back onto the screen position P", float((reprojected - P_s).abs().max()) < 1e-8)

# the linear view-space march of lesson 4, for comparison: equal steps in 3-D
march = origin + (s * length) * direction
march_px = cam.view_to_pixel(march, dim=-1)
fig, ax = plt.subplots(1, 2, figsize=(13, 3.8), layout="constrained")
ax[0].imshow(g.color[0].permute(1, 2, 0).clamp(0, 1).pow(1 / 2.2))
ax[0].plot(*march_px.T, "o", mfc="none", color="C1", ms=5, label="equal steps in view space")
ax[0].plot(*P_s.T, ".", color="C0", ms=5, label="equal steps on screen (DDA)")
ax[0].legend(fontsize=8), ax[0].set_xticks([]), ax[0].set_yticks([]), ax[0].set_title("one reflected ray")
ax[1].plot(torch.diff(march_px, dim=0).norm(dim=1), "o-", color="C1", label="view-space steps, in pixels")
ax[1].plot(torch.diff(P_s, dim=0).norm(dim=1), ".-", color="C0", label="DDA steps, in pixels")
ax[1].set_xlabel("step"), ax[1].set_ylabel("pixels per step"), ax[1].legend(fontsize=8)
ax[1].set_title("view-space steps shrink on screen as the ray recedes")
fig.suptitle("Step 4 — the DDA steps P, Q, k linearly on screen and reads the 3-D point as Q/k")
plt.show()

# %% [markdown]
# Equal view-space steps cover many pixels near the camera (skipping pixels — a thin object there is stepped
# over) and a fraction of a pixel far away (reading the same texel again and again). Equal screen steps do
# neither: that is the whole point of the DDA, and `Q`, `k` are what make it possible.
#
# ## 5. The half step (§2.2)
#
# In the DDA loop the article computes the ray's depth as `zB = (dPQK.z·0.5 + pqk.z) / (dPQK.w·0.5 + pqk.w)`
# and says it does not know why the half. By Step 4 this is simply `Q.z/k` evaluated **half a step ahead** —
# at `P + ½dP`, the far edge of the pixel-wide footprint the sample stands for. Together with the previous
# sample's value it brackets the ray's depth over the whole footprint (lesson 6 Step 4).

# %%
n = 32
dQ, dk = (Q1 - Q0) / n, (k1 - k0) / n
Q_i, k_i = Q0 + 5 * dQ, k0 + 5 * dk                                            # after 5 steps
z_half = (dQ[2] * 0.5 + Q_i[2]) / (dk * 0.5 + k_i)                             # the article's zB
s_half = (5 + 0.5) / n
exact = ((1 - s_half) * Q0 + s_half * Q1)[2] / ((1 - s_half) * k0 + s_half * k1)
check("the half step is the ray's depth half a step ahead", torch.isclose(z_half, exact, rtol=1e-12))
print(f"z at step 5: {float(Q_i[2] / k_i):.4f}, half a step ahead: {float(z_half):.4f}, "
      f"step 6: {float((Q_i[2] + dQ[2]) / (k_i + dk)):.4f}")

# %% [markdown]
# ## Checks

# %%
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * SSR article appendix A (the derivation), §2.2 (the DDA set-up with `H0`, `H1`, `k0`, `k1`, `Q0`, `Q1`, `P0`, `P1`).
# * `ssbench/passes/ssr/dda_rays.py` (`project_to_pixel_matrix`, `dda_rays`) and `passes/teaching/ssr_dda_basic.py`.
# * Next: **lesson 6**, the DDA march itself.
