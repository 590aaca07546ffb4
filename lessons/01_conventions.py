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
# # Lesson 1 — Conventions and the G-buffer
#
# ## Overview
#
# A screen-space effect never sees the scene. It sees a **G-buffer**: a few images that hold, for every pixel,
# what the rasteriser found there — a depth, a normal, a colour. Everything in lessons 2–6 (SSAO, HBAO, SSR) is
# arithmetic on those images, so before any effect we need to be exact about what the numbers *mean*: which
# way the axes point, how a pixel maps to a ray, and how depth is stored.
#
# The source articles rebuild positions and normals from the depth buffer in two different ways: mebiusbox,
# 「スクリーンスペース・アンビエント・オクルージョン (SSAO)」, 2022, https://zenn.dev/mebiusbox/articles/c7ea4871698ada
# (demo code https://github.com/mebiusbox/ssao; *SSAO article* below), §2.2 and §3.3, and mebiusbox,
# 「スクリーンスペース・リフレクション (SSR)」, 2022, https://zenn.dev/mebiusbox/articles/43ecf1bb12831c
# (demo code https://github.com/mebiusbox/ssr; *SSR article*), §1.1 — `ssbench/REFERENCES.md` lists them all. We derive both
# ways, check them against each other and against a G-buffer
# that Mitsuba 3 ray traced **at the same pixel centres**, and meet the one place where Mitsuba's camera frame
# differs from OpenGL's. The rules are collected on one page, `ssbench/CONVENTIONS.md`; `ssbench/camera.py`
# implements all of them.
#
# > **You will learn**
# > 1. what a G-buffer holds, and how ssbench stores it (`GBuffer`, `(B, C, H, W)` tensors);
# > 2. the chain world → view → clip → NDC → UV → pixel, and its one row flip;
# > 3. the three depth encodings of SSAO article §2.2, and why a depth buffer loses precision far away;
# > 4. position from depth, the SSAO way (inverse projection) and the HBAO way (`UvToViewParams`, derived);
# > 5. the normal encoding `(n + 1) / 2`, and normals rebuilt from depth with HBAO's `minDiff`;
# > 6. where Mitsuba's camera frame differs from GL's, and how ssbench hides it.

# %% [markdown]
# ## Setup
#
# `SSBENCH_LESSON_SIZE=small` renders at half size (what the tests do); leave it unset for the full 320 × 240.

# %%
import math

import matplotlib.pyplot as plt
import numpy as np
import torch

from ssbench import reconstruct
from ssbench import reference
from ssbench.scenes import load
from _setup import pick, size

W, H = size()
scene = load("sphere_on_plane")
g = reference.gbuffer(scene, W, H)                   # one Mitsuba ray per pixel centre -> GBuffer
cam = g.camera
color = reference.color(scene, W, H, spp=pick(64, 16), seed=0)
mask = g.mask                                        # (1, 1, H, W) bool: the pixel hits geometry

checks = {}                                          # every claim this lesson makes, asserted at the end


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name


def rgb(x):
    """(1, 3, H, W) linear RGB -> (H, W, 3) displayable sRGB-ish image."""
    return x[0].permute(1, 2, 0).clamp(0, 1).pow(1 / 2.2).numpy()


print(cam)
print("channels:", {name: tuple(t.shape) for name, t in g.as_dict().items()})

# %% [markdown]
# ## 1. What a screen-space pass sees
#
# SSAO article §2.1 renders colour, depth and normals into render targets first; every later pass reads only those.
# ssbench's `GBuffer` is the same idea as a frozen dataclass of `(B, C, H, W)` tensors, all in **view space**,
# row 0 at the top. The background (`mask` False) holds what a cleared GPU buffer would: depth on the far plane,
# a zero normal.

# %%
def on_geometry(x):
    """(1, 1, H, W) -> (H, W) with the background blanked, for display."""
    return torch.where(mask[0, 0], x[0, 0], torch.nan).numpy()


fig, ax = plt.subplots(2, 3, figsize=(12, 6.2), layout="constrained")
panels = [(rgb(color), "color (path traced, 'ColorSampler')", None),
          (on_geometry(g.view_z), "view_z  (< 0 in front; background: −far)", "viridis"),
          ((g.normal[0].permute(1, 2, 0) * 0.5 + 0.5).numpy(), "normal, shown as (n + 1) / 2", None),
          (on_geometry(g.position[:, :1]), "position.x (view space: + right)", "coolwarm"),
          (g.albedo[0].permute(1, 2, 0).numpy(), "albedo", None),
          (g.mask[0, 0].numpy(), "mask (the pixel-centre ray hits)", "gray")]
for a, (im, title, cmap) in zip(ax.flat, panels):
    h = a.imshow(im, cmap=cmap)
    a.set_title(title, fontsize=9)
    a.set_xticks([]), a.set_yticks([])
    if cmap not in (None, "gray"):
        fig.colorbar(h, ax=a, shrink=0.8)
fig.suptitle("Step 1 — the G-buffer of sphere_on_plane (SSAO article §2.1)")
plt.show()

# %% [markdown]
# ## 2. From world to pixel, and the one row flip
#
# View space is OpenGL's: the camera sits at the origin and looks down **−z**, +x right, +y up, so visible
# points have `z < 0`. The projection is `gluPerspective` (SSAO article §3.3 writes it out as `M_perspective`),
# NDC is clip ÷ w with `w = −z`, UV is `ndc · 0.5 + 0.5` with **v pointing up** (as in every shader of the
# articles), and pixels count rows **down** from the top. That last step is the only flip in ssbench:
#
# ```
# px = u · W            py = (1 − v) · H            centre of pixel (i, j) = (i + ½, j + ½)
# ```
#
# Let us push three world points through the chain by hand, with the matrices, and let the camera do the same.

# %%
world = torch.tensor([[0.0, 2.0, 0.0],      # top of the ball
                      [0.0, 1.0, 0.0],      # its centre (hidden inside it)
                      [1.5, 0.0, 1.0]],     # a point on the floor
                     dtype=torch.float64)
V, P = cam.view_matrix(), cam.projection_matrix()             # 4x4, float64
homog = torch.cat([world, torch.ones(3, 1, dtype=torch.float64)], 1)
view = (V @ homog.T).T                                         # world -> view
clip = (P @ view.T).T                                          # view  -> clip
ndc = clip[:, :3] / clip[:, 3:]                                # perspective divide by w = -z
uv = ndc[:, :2] * 0.5 + 0.5                                    # v up
pixel = torch.stack([uv[:, 0] * W, (1 - uv[:, 1]) * H], 1)      # rows down: the flip

library = cam.view_to_pixel(cam.world_to_view(world, dim=-1), dim=-1)
print("w = -z:", clip[:, 3].tolist(), " view z:", view[:, 2].tolist())
print("by hand:", pixel.numpy().round(3).tolist())
print("camera :", library.numpy().round(3).tolist())
check("world->pixel by hand equals Camera.view_to_pixel", torch.allclose(pixel, library, atol=1e-9))

# %% [markdown]
# The G-buffer was ray traced by Mitsuba, not rasterised, yet its positions must land exactly on the pixel
# centres our camera defines — otherwise every comparison in this project would measure a misalignment instead
# of an error. Project every stored position back to the image:

# %%
back = cam.view_to_pixel(g.position.double())                  # (1, 2, H, W) continuous pixel coordinates
centres = cam.pixel_centers(torch.float64)                     # (2, H, W): (i + 0.5, j + 0.5)
offset = (back - centres).norm(dim=1)[mask[:, 0]]
print(f"largest distance from a pixel centre: {offset.max():.2e} px (float32 positions)")
check("G-buffer positions project onto the pixel centres", offset.max() < 1e-3)

fig, ax = plt.subplots(1, 2, figsize=(11, 4), layout="constrained")
ax[0].imshow(rgb(color), extent=(0, W, H, 0))
for (x, y), name in zip(library.tolist(), ["ball top", "ball centre (hidden)", "floor point"]):
    ax[0].plot(x, y, "o", mfc="none", mec="yellow", ms=10)
    ax[0].annotate(name, (x, y), (x + 8, y - 8), color="yellow", fontsize=9)
ax[0].set_title("world points through the camera\n(pixel axes: x right, y down)", fontsize=10)
ax[1].set_xlim(-0.15, 1.15), ax[1].set_ylim(-0.15, 1.15)
ax[1].add_patch(plt.Rectangle((0, 0), 1, 1, fill=False, ls=":"))
ax[1].annotate("", (1, 0), (0, 0), arrowprops=dict(arrowstyle="->", color="C0", lw=2))
ax[1].annotate("", (0, 1), (0, 0), arrowprops=dict(arrowstyle="->", color="C0", lw=2))
ax[1].text(0.45, -0.1, "u", color="C0"), ax[1].text(-0.1, 0.35, "v (up)", color="C0", rotation=90)
ax[1].annotate("", (1, 0.97), (0.03, 0.97), arrowprops=dict(arrowstyle="->", color="C3", lw=2))
ax[1].annotate("", (0.03, 0.03), (0.03, 0.97), arrowprops=dict(arrowstyle="->", color="C3", lw=2))
ax[1].text(0.35, 1.03, "px = u·W", color="C3"), ax[1].text(0.07, 0.45, "py = (1−v)·H  (down)", color="C3")
ax[1].text(-0.12, -0.1, "uv (0, 0)", fontsize=8, color="C0")
ax[1].text(-0.12, 1.05, "pixel (0, 0)", fontsize=8, color="C3")
ax[1].set_title("UV (shaders) vs pixels (images): the one flip", fontsize=10)
ax[1].axis("off")
plt.show()

# %% [markdown]
# ## 3. Three encodings of depth (SSAO article §2.2)
#
# The SSAO shader reads a **GL depth buffer** `d ∈ [0, 1]` and turns it into view z (`perspectiveDepthToViewZ`)
# or into **linear depth** `l = (z + n)/(n − f)` (`viewZToOrthographicDepth`). Where does `d` come from? Row 3 of
# the projection gives `clip.z = −(f+n)/(f−n)·z − 2fn/(f−n)`, the divide by `w = −z` gives `ndc.z`, and
# `d = ndc.z/2 + 1/2`. The result is a *hyperbola* in z: most of `[0, 1]` is spent just beyond the near plane.

# %%
z = -torch.logspace(math.log10(cam.near), math.log10(cam.far), 400, dtype=torch.float64)
n, f = cam.near, cam.far
ndc_z = (-(f + n) / (f - n) * z - 2 * f * n / (f - n)) / (-z)        # row 3 of P, divided by w = -z
d_by_hand = ndc_z * 0.5 + 0.5
check("d(z) from the projection matrix equals Camera.view_z_to_depth",
      torch.allclose(d_by_hand, cam.view_z_to_depth(z), atol=1e-12))
check("depth_to_view_z inverts view_z_to_depth",
      torch.allclose(cam.depth_to_view_z(cam.view_z_to_depth(z)), z, rtol=1e-10))

fig, ax = plt.subplots(1, 3, figsize=(14, 3.8), layout="constrained")
ax[0].semilogx(-z, cam.view_z_to_depth(z), label="GL depth d (hyperbolic)")
ax[0].semilogx(-z, cam.view_z_to_orthographic_depth(z), label="linear depth l")
ax[0].axvspan(-float(g.view_z[mask].max()), -float(g.view_z[mask].min()), color="C2", alpha=0.2,
              label="this scene's range")
ax[0].set_xlabel("distance −z"), ax[0].legend(fontsize=8), ax[0].set_title(f"near {n}, far {f}")
h = ax[1].imshow(g.depth[0, 0], cmap="magma", vmin=0.96, vmax=1.0)
ax[1].set_title("GL depth buffer d (stretched to [0.96, 1])"), fig.colorbar(h, ax=ax[1], shrink=0.8)
h = ax[2].imshow(g.linear_depth[0, 0], cmap="magma", vmax=0.2)
ax[2].set_title("linear depth l = (z + n)/(n − f)"), fig.colorbar(h, ax=ax[2], shrink=0.8)
for a in ax[1:]:
    a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 3 — depth encodings (SSAO article §2.2, three.js packing.glsl)")
plt.show()

# %% [markdown]
# ### Why far things lose precision
#
# Because `d` is a hyperbola, one float32 step of `d` (one *ulp*, 2⁻²⁴ ≈ 6·10⁻⁸ for `d ∈ [0.5, 1)`) is a
# view-z step of `|Δz| = ulp(d)·(f − n)·z²/(f·n)` — it grows with **z²** and with **1/near**. Store the scene's
# z as a float32 depth buffer and read it back: the error follows the bound. This is the precision every SSAO
# and SSR pass of the article works with (and the reason the SSAO article's Fig. 10 needs a `MinDistance`).

# %%
z32 = -torch.logspace(-0.5, 2, 300, dtype=torch.float64)[:-1]
d32 = cam.view_z_to_depth(z32).float()                                   # what a float32 target stores
z_back = cam.depth_to_view_z(d32.double())
ulp = torch.nextafter(d32, torch.tensor(2.0)).double() - d32.double()
bound = ulp * (f - n) * z32 ** 2 / (f * n)
err = (z_back - z32).abs()
print(f"worst error / bound = {float((err / bound).max()):.2f}")
check("float32 depth round trip stays within one ulp-step bound", bool((err <= bound).all()))

plt.figure(figsize=(6, 3.8))
plt.loglog(-z32, err, ".", ms=3, label="|z − z(d₃₂)|  measured")
plt.loglog(-z32, bound, label="ulp(d)·(f−n)·z²/(f·n)")
plt.xlabel("distance −z"), plt.ylabel("view-z error"), plt.legend()
plt.title("float32 depth buffer: error grows like z²")
plt.show()

# %% [markdown]
# ## 4. Position from depth, the SSAO way: inverse projection (SSAO article §2.2)
#
# `getViewPosition` undoes the projection: build the clip position `((uv, d) − 0.5)·2` with `w = 1`, multiply it
# by `clipW` (the `w` the vertex had, `−z`), and apply `P⁻¹`. Here it is on the whole depth buffer, in float64,
# against `reconstruct.position_from_depth(method="inverse_projection")`.

# %%
depth = g.depth.double()                                                  # (1, 1, H, W) GL depth buffer
uv_img = cam.uv_grid(torch.float64)                                       # (2, H, W), v up
view_z = cam.depth_to_view_z(depth)[0, 0]                                 # getViewZ(depth)
clip_w = -view_z                                                          # P[3] . (x, y, z, 1) = -z
clip_pos = torch.stack([(uv_img[0] - 0.5) * 2, (uv_img[1] - 0.5) * 2, (depth[0, 0] - 0.5) * 2,
                        torch.ones_like(view_z)]) * clip_w                # (4, H, W), "unprojection"
P_inv = cam.inverse_projection_matrix()
ssao_way = torch.einsum("ij,jhw->ihw", P_inv, clip_pos)[:3]               # (3, H, W)

library_ssao = reconstruct.position_from_depth(depth, cam, method="inverse_projection")[0]
check("getViewPosition by hand equals position_from_depth('inverse_projection')",
      torch.allclose(ssao_way, library_ssao, atol=1e-12))

# the same thing from a float32 depth buffer, against Mitsuba's positions
p32 = reconstruct.position_from_depth(g.depth.float(), cam, method="inverse_projection")
rel = ((p32.double() - g.position.double()).norm(dim=1) / g.position.double().norm(dim=1))[0]
rel = torch.where(mask[0, 0], rel, torch.nan)
plt.figure(figsize=(6, 3.8))
plt.imshow(torch.log10(rel.clamp_min(1e-9)), cmap="inferno")
plt.colorbar(label="log10 relative position error")
plt.title("Step 4 — position from a float32 depth buffer:\nthe far floor is known less well (Step 3)")
plt.xticks([]), plt.yticks([])
plt.show()
check("float32 reconstruction within 1e-4 relative", float(np.nanmax(rel.numpy())) < 1e-4)

# %% [markdown]
# ## 5. Position from depth, the HBAO way: deriving `UvToViewParams` (SSAO article §3.3)
#
# HBAO's `uvToView` needs no matrix: `xy = (A·uv + B)·z`. The article derives `A` and `B` by running the
# projection of x backwards. With `F = 1/tan(fov/2)`:
#
# ```
# x_clip = x·F/aspect     x_ndc = x_clip/(−z)     u = (x_ndc + 1)/2
#  ⇒  x = (2u − 1)·(−z)/(F/aspect) = (−2/F₁·u + 1/F₁)·z          F₁ = F/aspect = F·H/W
#      y = (2v − 1)·(−z)/F          = (−2/F₂·v + 1/F₂)·z          F₂ = F
# UvToViewParams = (A.x, A.y, B.x, B.y) = (−2/F₁, −2/F₂, 1/F₁, 1/F₂)
# ```
#
# (the article's JavaScript: `focal1 = 1/tan(fov/2)·(Height/Width)`, `uvToVA0 = −2·invFocal1`, …).

# %%
F = 1.0 / math.tan(math.radians(cam.fovy_deg) / 2)
focal1, focal2 = F * H / W, F
uv_to_view_params = (-2 / focal1, -2 / focal2, 1 / focal1, 1 / focal2)
print("by hand:", np.round(uv_to_view_params, 6))
print("camera :", np.round(cam.uv_to_view_params(), 6))
check("UvToViewParams by hand equal Camera.uv_to_view_params",
      np.allclose(uv_to_view_params, cam.uv_to_view_params(), rtol=1e-14))

A = torch.tensor(uv_to_view_params[:2], dtype=torch.float64).view(2, 1, 1)
B = torch.tensor(uv_to_view_params[2:], dtype=torch.float64).view(2, 1, 1)
hbao_way = torch.cat([(A * uv_img + B) * view_z, view_z[None]])           # (3, H, W)
library_hbao = reconstruct.position_from_depth(depth, cam, method="uv_to_view")[0]
check("uvToView by hand equals position_from_depth('uv_to_view')", torch.allclose(hbao_way, library_hbao, atol=1e-12))
gap = float((library_hbao - library_ssao).abs().max())
print(f"largest difference between the two SSAO-article ways: {gap:.1e} (float64 round-off)")
check("the SSAO and HBAO reconstructions agree", gap < 1e-9)

fig, ax = plt.subplots(1, 3, figsize=(14, 3.5), layout="constrained")
for a, im, title in [(ax[0], A[0] * uv_img[0] + B[0], "A.x·u + B.x  (= x/z of the pixel ray)"),
                     (ax[1], A[1] * uv_img[1] + B[1], "A.y·v + B.y  (= y/z)"),
                     (ax[2], (library_hbao - library_ssao).abs().amax(0), "|HBAO way − SSAO way|")]:
    fig.colorbar(a.imshow(im, cmap="coolwarm" if "way" not in title else "gray"), ax=a, shrink=0.8)
    a.set_title(title, fontsize=9), a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 5 — the pixel ray is linear in uv; z scales it onto the surface")
plt.show()

# %% [markdown]
# ## 6. Storing a normal in a colour: `(n + 1)/2` (SSAO article §2.2)
#
# three.js's `MeshNormalMaterial` writes `gl_FragColor = (n + 1)·0.5` into an 8-bit RGB target, and the SSAO
# shader reads it back with `getViewNormal = 2·rgb − 1`. ssbench stores float normals in [−1, 1], so the
# passes skip that step — but the 8-bit round trip is worth seeing: it tilts normals by a fraction of a degree.

# %%
normal = g.normal.double()
encoded = (normal + 1) * 0.5                                             # what MeshNormalMaterial writes
decoded = 2 * encoded - 1                                                # getViewNormal
check("decode(encode(n)) == n in floating point", torch.allclose(decoded, normal, atol=1e-12))

rgb8 = torch.round(encoded * 255) / 255                                  # an RGB8 render target
n8 = 2 * rgb8 - 1
n8 = n8 / n8.norm(dim=1, keepdim=True)
tilt = torch.rad2deg(torch.acos((n8 * normal).sum(1).clamp(-1, 1)))[0]
tilt_on = tilt[mask[0, 0]]
print(f"8-bit normals: median tilt {tilt_on.median():.3f} deg, worst {tilt_on.max():.3f} deg")
check("8-bit normal quantisation tilts by less than half a degree", tilt_on.max() < 0.5)

fig, ax = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
ax[0].imshow(encoded[0].permute(1, 2, 0)), ax[0].set_title("(n + 1)/2 as RGB (MeshNormalMaterial)")
h = ax[1].imshow(torch.where(mask[0, 0], tilt, torch.nan), cmap="viridis")
fig.colorbar(h, ax=ax[1], shrink=0.8, label="degrees")
ax[1].set_title("tilt of an RGB8 round trip")
for a in ax:
    a.set_xticks([]), a.set_yticks([])
plt.show()

# %% [markdown]
# ## 7. Normals from depth: HBAO's `minDiff` (SSAO article §3.3)
#
# SSAO article §1 notes that normals "can be rebuilt from depth, at a cost". HBAO does it with four neighbours:
# `dPdu = minDiff(P, Pr, Pl)`, `dPdv = minDiff(P, Pt, Pb)`, where `minDiff` keeps **the shorter** of the two
# one-sided differences, and `n = normalize(dPdu × dPdv)`. Why the shorter one? At a silhouette one neighbour
# lies on another surface, far behind; the central difference `Pr − Pl` would mix the two and tilt the normal.
# Below: both, by hand, against the G-buffer's exact (analytic) shading normals.

# %%
pos = library_hbao[None]                                                   # (1, 3, H, W) float64
pad = torch.nn.functional.pad(pos, (1, 1, 1, 1), mode="replicate")
Pr, Pl = pad[..., 1:-1, 2:], pad[..., 1:-1, :-2]                           # right / left neighbours
Pt, Pb = pad[..., :-2, 1:-1], pad[..., 2:, 1:-1]                           # upper (row - 1) / lower (row + 1)


def min_diff(P, Pa, Pb):
    """The shorter of (Pa - P) and (P - Pb)."""
    v1, v2 = Pa - P, P - Pb
    return torch.where((v1 * v1).sum(1, keepdim=True) < (v2 * v2).sum(1, keepdim=True), v1, v2)


def unit(v):
    return v / v.norm(dim=1, keepdim=True).clamp_min(1e-300)


n_central = unit(torch.cross(Pr - Pl, Pt - Pb, dim=1))
n_mindiff = unit(torch.cross(min_diff(pos, Pr, Pl), min_diff(pos, Pt, Pb), dim=1))
n_library = reconstruct.normals_from_depth(depth, cam, mask)
inner = mask[0, 0].clone()
inner[[0, -1], :] = False
inner[:, [0, -1]] = False                                                  # the library also handles borders
check("minDiff normals by hand equal reconstruct.normals_from_depth (inside the image)",
      torch.allclose(n_mindiff[0][:, inner], n_library[0][:, inner], atol=1e-9))


def angle_deg(a, b):
    return torch.rad2deg(torch.acos((a * b).sum(1).clamp(-1, 1)))[0]


err_central, err_min = angle_deg(n_central, normal), angle_deg(n_library, normal)
sid = reference.gbuffer(scene, W, H, channels=("shape_id",)).shape_id[0, 0]
on_floor, on_ball = inner & (sid == 0), inner & (sid == 1)
print(f"floor: minDiff median {err_min[on_floor].median():.3f} deg   central {err_central[on_floor].median():.3f} deg")
print(f"ball : minDiff median {err_min[on_ball].median():.3f} deg   central {err_central[on_ball].median():.3f} deg")
print(f"pixels off by more than 10 deg: minDiff {(err_min[inner] > 10).sum()}, central {(err_central[inner] > 10).sum()}")
check("a plane gets its exact normal from depth (< 0.1 deg)", err_min[on_floor].max() < 0.1)
check("minDiff has fewer broken (> 10 deg) normals than central differences",
      (err_min[inner] > 10).sum() < (err_central[inner] > 10).sum())

fig, ax = plt.subplots(1, 3, figsize=(14, 3.8), layout="constrained")
for a, e, title in [(ax[0], err_central, "central difference Pr − Pl, Pt − Pb"),
                    (ax[1], err_min, "minDiff (the shorter side)")]:
    h = a.imshow(torch.where(inner, e, torch.nan), cmap="magma", vmin=0, vmax=10)
    a.set_title(title), a.set_xticks([]), a.set_yticks([])
fig.colorbar(h, ax=ax[:2], shrink=0.8, label="angle to the true normal (deg)")
ax[2].hist([err_central[inner].numpy(), err_min[inner].numpy()], bins=np.linspace(0, 45, 46), log=True,
           label=["central", "minDiff"])
ax[2].set_xlabel("degrees"), ax[2].legend(), ax[2].set_title("error histogram (log count)")
fig.suptitle("Step 7 — normals from depth: silhouettes break central differences")
plt.show()

# %% [markdown]
# Read the two error maps together. Inside the ball the central difference is *more* accurate (it is
# second-order; `minDiff` is a one-sided, first-order difference, off by a degree or two). But on every
# silhouette the central difference straddles two surfaces and the normal breaks by tens of degrees, while
# `minDiff` stays on the pixel's own surface. A pass would rather be a little wrong everywhere than very wrong
# at edges — that is where AO and reflections are looked at. And a plane (the floor) comes out exact either
# way. This is the price the SSAO article mentions (§1) for skipping a normal buffer.
#
# ## 8. Mitsuba's camera frame is not OpenGL's
#
# The ground truth comes from Mitsuba 3, whose camera-local frame looks down **+z** with **+x pointing to the
# image left**. ssbench writes the conversion once, in `Camera.mitsuba_sensor()`:
# `to_world_mitsuba = camera_to_world · diag(−1, 1, −1, 1)`, a 180° turn about y. Two more traps are handled
# there: Mitsuba's `fov` is *horizontal* unless `fov_axis='y'`, and its rays start on the near plane, so the
# hit distance `si.t` is not the distance from the eye (ssbench reads hit points, never `si.t`).

# %%
sensor = cam.mitsuba_sensor()
to_world = torch.tensor(sensor["to_world"], dtype=torch.float64)
gl = cam.camera_to_world()
right, up, back_axis = (torch.tensor(v, dtype=torch.float64) for v in cam.basis)
forward = torch.tensor(cam.target, dtype=torch.float64) - torch.tensor(cam.eye, dtype=torch.float64)
forward = forward / forward.norm()
print("sensor:", {k: v for k, v in sensor.items() if k != "to_world"})
check("Mitsuba to_world = GL camera_to_world . diag(-1, 1, -1, 1)",
      torch.allclose(to_world, gl @ torch.diag(torch.tensor([-1.0, 1, -1, 1], dtype=torch.float64))))
check("Mitsuba +x is the image left, +z the view direction",
      torch.allclose(to_world[:3, 0], -right) and torch.allclose(to_world[:3, 2], forward))
check("the sensor is given a vertical fov", sensor["fov_axis"] == "y" and sensor["fov"] == cam.fovy_deg)

fig, ax = plt.subplots(1, 2, figsize=(11, 4.2), layout="constrained")
eye = np.array(cam.eye)
frames = [((gl[:3, 0], gl[:3, 2]), ("+x  right", "+z  back"), "OpenGL / ssbench view frame"),
          ((to_world[:3, 0], to_world[:3, 2]), ("+x  LEFT", "+z  forward"), "Mitsuba camera frame")]
for a, (cols, names, title) in zip(ax, frames):
    for c, name, colr in zip(cols, names, ("C3", "C0")):
        c = c.numpy()
        a.annotate("", (eye[0] + 2 * c[0], eye[2] + 2 * c[2]), (eye[0], eye[2]),
                   arrowprops=dict(arrowstyle="->", color=colr, lw=2))
        a.text(eye[0] + 2.2 * c[0] - 0.6, eye[2] + 2.3 * c[2], name, color=colr)
    a.add_patch(plt.Circle((0, 0), 1, color="C0", alpha=0.3)), a.text(-0.4, -0.1, "ball")
    a.plot(eye[0], eye[2], "ko"), a.text(eye[0] + 0.2, eye[2] - 0.5, "eye")
    a.set_aspect("equal"), a.set_xlim(-4, 4), a.set_ylim(-1.5, 9.5)
    a.set_xlabel("world x"), a.set_ylabel("world z"), a.set_title(title + " (top view; y is out of the page)")
fig.suptitle("Step 8 — same camera, two frames: x and z flip (a 180° turn about y)")
plt.show()

# %% [markdown]
# ## Checks
#
# Every claim above, in one place. The lesson passes when all of them hold.

# %%
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * `ssbench/CONVENTIONS.md` — the conventions page; `ssbench/camera.py` and `ssbench/reconstruct.py`.
# * SSAO article §2.2 (`getViewPosition`, depth helpers, `getViewNormal`) and §3.3 (`uvToView`, `minDiff`).
# * `tests/test_camera.py`, `tests/test_reconstruct.py` — the same facts as unit tests.
# * Next: **lesson 2**, SSAO — the first pass that reads this G-buffer.
