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
# # Lesson 2 — Screen-space ambient occlusion (SSAO)
#
# ## Overview
#
# Ambient occlusion asks: of all the directions above a point, how many are blocked by nearby geometry?
# A ray tracer answers exactly; Crytek's **SSAO** (Crysis, 2007) answers from the G-buffer alone, by scattering
# a few points around each pixel and counting how many land *behind* the depth buffer. SSAO article §1–2 builds it
# up one fix at a time, and so does this lesson:
#
# Crytek's sphere → the hemisphere → a centre-weighted kernel → per-pixel noise rotation (Gram–Schmidt) → the
# range check against halos → the minimum distance against self-occlusion → the sample count → the blur →
# the composite.
#
# Each step is measured against **ray-traced ground truth** that Mitsuba computes from the same scene at the same
# pixel centres (`ssbench.reference.ambient_occlusion`), so "better" is a number, not a feeling.
#
# > **You will learn**
# > 1. why Crytek's sphere makes everything grey, and what the normal-oriented hemisphere fixes (Figs. 1–3);
# > 2. the SSAO fragment shader of §2.2, written out in a dozen lines and checked against `hemisphere_ssao`;
# > 3. why the kernel crowds its samples near the centre (Fig. 4) and how the 4×4 noise texture plus
# >    Gram–Schmidt turns banding into noise;
# > 4. where halos (Figs. 7–9) and self-occlusion (Fig. 10) come from, and the two depth thresholds that fight them;
# > 5. how the sample count trades banding and noise for time (Fig. 5), and why a 5×5 blur follows (Fig. 6);
# > 6. how the AO buffer is composited over the colour (§2.4).

# %% [markdown]
# ## Setup

# %%
import math

import matplotlib.pyplot as plt
import numpy as np
import torch
import torch.nn.functional as F

from ssbench import metrics, reference
from ssbench.passes.blur import box_blur
from ssbench.passes.common import fetch_uv
from ssbench.passes.composite import composite
from ssbench.passes.sampling import hemisphere_kernel, noise_texel, noise_texture, sphere_kernel
from ssbench.passes.ao.ssao import HemisphereSSAOParams, hemisphere_ssao
from ssbench.passes.ao.crytek import CrytekSSAOParams, crytek_ssao
from ssbench.scenes import load
from _setup import pick, size

W, H = size()
RADIUS = 0.5                                         # KernelRadius, and the ground truth's ray length
RAYS = pick(256, 128)                                # ground-truth rays per pixel

scene = load("cornell_box")
g = reference.gbuffer(scene, W, H)                   # view_z, normal, mask, ... at the pixel centres
mask = g.mask
truth = reference.ambient_occlusion(scene, g, RADIUS, rays=RAYS, weighting="uniform", seed=0)
gt = truth.ao                                        # (1, 1, H, W), 1 = unoccluded

checks = {}


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name


def score(ao, target=gt, m=mask):
    """RMSE against the ground truth, and the occlusion added where the truth has none (flat bias)."""
    return float(metrics.rmse(ao, target, m)), float(metrics.flat_bias(ao, target, m))


def show(images, titles, suptitle, cmap="gray", vmin=0.0, vmax=1.0):
    fig, ax = plt.subplots(1, len(images), figsize=(3.6 * len(images), 3.2), layout="constrained")
    for a, im, t in zip(np.atleast_1d(ax), images, titles):
        a.imshow(im[0, 0] if im.dim() == 4 else im, cmap=cmap, vmin=vmin, vmax=vmax)
        a.set_title(t, fontsize=9), a.set_xticks([]), a.set_yticks([])
    fig.suptitle(suptitle)
    plt.show()


print(f"{W}x{H}, ground truth: {RAYS} rays, standard error {float(metrics.masked_mean(truth.stderr, mask)):.3f}")

# %% [markdown]
# ## 1. The ground truth
#
# For every pixel Mitsuba shoots `RAYS` rays uniformly over the hemisphere around the surface normal and counts
# the ones that hit something within `RADIUS`: **uniform-weighted, binary visibility** (`weighting="uniform"`),
# ambient occlusion as shading means it. It is *not* quite what SSAO's counting estimates — Step 4 shows the
# quantity SSAO converges to (a volume fraction, `weighting="volume_hemisphere"`, the flavour the pass module
# declares with `FLAVOUR`), and why the two differ. Corners and the bases of the blocks are dark; open walls are white. (The few white pixels exactly on the
# room's edges are rays that slip through the seam where two wall rectangles meet: a quirk of how this scene is
# modelled, not of AO.)

# %%
show([g.normal[0].permute(1, 2, 0) * 0.5 + 0.5, gt, truth.stderr / 0.1],
     ["normal", f"ray-traced AO (uniform, R = {RADIUS})", "its standard error (black 0, white 0.1)"],
     "Step 1 — what we compare against")

# %% [markdown]
# ## 2. Crytek's sphere (§1, Figs. 1–2)
#
# The original needs no normal: sample points fill a **ball** around the pixel's view position, and a sample
# counts as occluded when it lies behind the depth buffer. On an open wall half of the ball is behind the wall,
# so the answer is 0.5 — the "everything is grey" look of Fig. 2. Corners go darker, edges lighter.

# %%
crytek = crytek_ssao(g, CrytekSSAOParams(kernel_size=16, kernel_radius=RADIUS)).ao
rmse_crytek, flat_crytek = score(crytek)

fig, ax = plt.subplots(1, 3, figsize=(12, 3.6), layout="constrained")
k = sphere_kernel(64, torch.Generator().manual_seed(0))
ax[0].scatter(k[:, 0], k[:, 2], c=k[:, 1], s=12, cmap="coolwarm")
ax[0].add_patch(plt.Circle((0, 0), 1, fill=False)), ax[0].axhline(0, color="k", lw=3)
ax[0].set_aspect("equal"), ax[0].set_title("sphere kernel (side view);\nthe thick line is the surface")
ax[1].imshow(crytek[0, 0], cmap="gray", vmin=0, vmax=1), ax[1].set_title(f"Crytek SSAO, RMSE {rmse_crytek:.3f}")
ax[2].imshow(gt[0, 0], cmap="gray", vmin=0, vmax=1), ax[2].set_title("ground truth")
for a in ax[1:]:
    a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 2 — Crytek's sphere: half of every ball is behind the surface (Fig. 2's grey)")
plt.show()
print(f"mean occlusion where the truth sees none (flat bias): {flat_crytek:.3f}")
check("Crytek's sphere greys open surfaces (flat bias > 0.3)", flat_crytek > 0.3)

# %% [markdown]
# ## 3. The hemisphere, and the shader written out (§1 Fig. 3, §2.2)
#
# Orient the samples with the surface normal and keep only the half above the surface (Fig. 3). Now a sample
# below the depth buffer really means something is in the way. Here is the fragment shader of §2.2 for all
# pixels at once, in the article's names:
#
# 1. `viewPosition` and `viewNormal` of the pixel;
# 2. `random` from the 4×4 noise texture, Gram–Schmidt: `tangent = normalize(random − n·(random·n))`,
#    `bitangent = n × tangent`, `kernelMatrix = (tangent, bitangent, n)`;
# 3. for every kernel point: `samplePoint = viewPosition + kernelMatrix·Kernel[i]·KernelRadius`, project it,
#    read the depth buffer there (`realDepth`), compare **linear** depths: it occludes when
#    `MinDistance < sampleDepth − realDepth < MaxDistance`;
# 4. `AO = 1 − count / KERNEL_SIZE`.
#
# `fetch_uv` and `noise_texel` are the library's texture reads (nearest texel, clamp / repeat), the rules a
# GPU sampler follows.

# %%
def ssao_count(gb, kernel, noise, radius=RADIUS, min_distance=0.0005, max_distance=0.02):
    """SSAO article §2.2's SSAO fragment shader for every pixel; returns the number of occluding samples."""
    cam = gb.camera
    view_z = gb.view_z.double()
    uv = cam.uv_grid(torch.float64)[None]                                   # (1, 2, H, W) vUv
    P = cam.uv_to_view(uv, view_z)                                          # viewPosition
    n = gb.normal.double()                                                  # viewNormal
    col, row = noise_texel(uv, cam.width, cam.height, noise.shape[-1])
    random = noise[:, row[0], col[0]][None]                                 # (1, 3, H, W)
    tangent = random - n * (random * n).sum(1, keepdim=True)                # Gram-Schmidt
    tangent = tangent / tangent.norm(dim=1, keepdim=True)
    bitangent = torch.cross(n, tangent, dim=1)
    count = torch.zeros_like(view_z, dtype=torch.int64)
    for kx, ky, kz in kernel.tolist():                                      # for (i < KERNEL_SIZE)
        sample = P + (tangent * kx + bitangent * ky + n * kz) * radius      # samplePoint
        sample_uv = cam.ndc_to_uv(cam.view_to_ndc(sample)[:, :2])           # project, * 0.5 + 0.5
        real_z = fetch_uv(view_z, sample_uv)                                # the depth buffer there
        delta = (cam.view_z_to_orthographic_depth(sample[:, 2:3])          # sampleDepth
                 - cam.view_z_to_orthographic_depth(real_z))                # - realDepth
        count += (delta > min_distance) & (delta < max_distance)
    return torch.where(gb.mask, count, 0)


def uniform_hemisphere(n_samples, generator):
    """Points uniform in the unit half-ball z >= 0 (no centre weighting)."""
    d = torch.randn(n_samples, 3, generator=generator, dtype=torch.float64)
    d[:, 2] = d[:, 2].abs()
    r = torch.rand(n_samples, generator=generator, dtype=torch.float64) ** (1 / 3)
    return d / d.norm(dim=1, keepdim=True) * r[:, None]


K = 16
gen = torch.Generator().manual_seed(0)
kernel_uniform = uniform_hemisphere(K, gen)
noise4 = noise_texture(4, gen)
ao_hemi_uniform = 1 - ssao_count(g, kernel_uniform, noise4).double() / K
rmse_hemi_u, flat_hemi_u = score(ao_hemi_uniform)

show([crytek, ao_hemi_uniform, gt],
     [f"sphere: RMSE {rmse_crytek:.3f}, flat bias {flat_crytek:.2f}",
      f"hemisphere: RMSE {rmse_hemi_u:.3f}, flat bias {flat_hemi_u:.3f}", "ground truth"],
     "Step 3 — the normal-oriented hemisphere (Fig. 3) removes the grey")
check("the hemisphere removes the grey of open surfaces (flat bias < 0.05)", flat_hemi_u < 0.05)
check("the hemisphere beats the sphere against the ground truth", rmse_hemi_u < rmse_crytek)

# %% [markdown]
# ## 4. A kernel that crowds the centre (§1 Fig. 4)
#
# The SSAO article makes the distribution "concentrate near the target point": the library's `hemisphere_kernel` draws a
# random direction and length, then scales sample `i` by `lerp(0.1, 1.0, (i/N)²)` (J. Chapman's construction).
# Near occluders matter most — they block the widest cone of directions — so they deserve the most samples.
#
# This is also where the hand-written shader meets the library: with the same kernel and the same noise (both
# drawn from one generator, kernel first), `ssao_count` must equal the pass's own count, pixel for pixel. (Our
# version reads positions from `view_z`; the pass's default, like the article, rebuilds them from the GL depth
# buffer — `position_from="view_z"` makes the two read the same numbers.)

# %%
gen = torch.Generator().manual_seed(0)
kernel = hemisphere_kernel(K, gen)                                           # drawn first ...
noise = noise_texture(4, gen)                                                # ... then the noise
by_hand = ssao_count(g, kernel, noise)

params = HemisphereSSAOParams(kernel_size=K, kernel_radius=RADIUS, position_from="view_z", seed=0)
library = hemisphere_ssao(g.to(dtype=torch.float64), params, debug=True)
check("the shader by hand counts exactly what hemisphere_ssao counts",
      torch.equal(by_hand, library.debug["samples"].to(torch.int64)))
check("and AO = 1 - count / K", torch.allclose(library.ao, 1 - by_hand.double() / K))

ao_hemi = library.ao
rmse_hemi, flat_hemi = score(ao_hemi)
fig, ax = plt.subplots(1, 3, figsize=(12, 3.4), layout="constrained")
big_u, big_c = uniform_hemisphere(4096, torch.Generator().manual_seed(1)), hemisphere_kernel(4096)
ax[0].hist([big_u.norm(dim=1).numpy(), big_c.norm(dim=1).numpy()], bins=30, density=True,
           label=["uniform in the half-ball", "hemisphere_kernel (Chapman)"])
ax[0].set_xlabel("sample distance / KernelRadius"), ax[0].legend(fontsize=8)
ax[1].imshow(ao_hemi_uniform[0, 0], cmap="gray", vmin=0, vmax=1)
ax[1].set_title(f"uniform kernel: RMSE {rmse_hemi_u:.3f}")
ax[2].imshow(ao_hemi[0, 0], cmap="gray", vmin=0, vmax=1), ax[2].set_title(f"centre-weighted: RMSE {rmse_hemi:.3f}")
for a in ax[1:]:
    a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 4 — non-uniform hemisphere sampling (Fig. 4)")
plt.show()
check("the library kernel crowds the centre (median radius below the uniform half-ball's)",
      big_c.norm(dim=1).median() < 0.5 * big_u.norm(dim=1).median())

# %% [markdown]
# Against this ground truth the centre-weighted kernel is *further* off: most of its samples sit within a
# third of `KernelRadius`, where they rarely fall inside an occluder, so only contact creases darken. What it
# buys is crisp contact shading and less influence from distant geometry — a *look*, not a better estimate of
# ray-traced AO. And both are brighter than the truth, for a deeper reason: counting the **volume** of a
# half-ball that lies inside geometry is not counting **blocked rays** (a thin wall at distance R blocks many
# rays but fills almost no volume). SSAO estimates a cousin of ambient occlusion: the fraction of the kernel's
# points that lie inside geometry. The library traces that cousin too — `weighting="volume_hemisphere"` draws
# points from the same law as `hemisphere_kernel` (with the noise's turn about the normal) and asks Mitsuba
# whether each lies inside geometry (`ssbench.reference.ao_volume`; Crytek's ball is `"volume_sphere"`). With
# many samples the pass converges to it; the gap to the directional truth is a *definition*, not an error the
# pass could shrink. `ssbench ao` and the report score SSAO against its own flavour **and** against cosine AO
# (what shading needs). The rest of the lesson uses the library kernel, as the article does, and the uniform
# truth, because that is what the picture should look like.

# %%
volume = reference.ambient_occlusion(scene, g, RADIUS, rays=RAYS, weighting="volume_hemisphere", seed=0).ao
many = hemisphere_ssao(g, HemisphereSSAOParams(kernel_size=64, kernel_radius=RADIUS)).ao
bias_volume, bias_uniform = float(metrics.bias(many, volume, mask)), float(metrics.bias(many, gt, mask))
show([many, volume, gt], [f"SSAO, 64 samples", f"volume truth: bias {bias_volume:+.3f}",
                          f"uniform truth: bias {bias_uniform:+.3f}"],
     "Step 4b — what SSAO converges to: the volume fraction, not blocked rays")
check("with many samples SSAO sits on its own (volume) flavour, far closer than on the uniform one",
      abs(bias_volume) < 0.5 * abs(bias_uniform))
#
# ## 5. Noise rotation and Gram–Schmidt (§2.2)
#
# With 16 samples per pixel, using the *same* 16 directions everywhere makes every pixel make the same mistakes,
# and neighbouring pixels' mistakes line up into **bands**. §2.2 rotates the kernel per pixel with a vector
# `random` from a tiled 4×4 noise texture (z = 0, in the tangent plane), and builds an orthonormal frame
# around the normal by **Gram–Schmidt**: remove from `random` its component along `n`, normalise, and cross.
# Sixteen pixels in a 4×4 tile now use sixteen different rotations, so the error becomes a fine, regular
# noise that a 4–5 pixel blur removes (Step 9).

# %%
n = g.normal.double()[0, :, H // 2, W // 2]                                  # one pixel's normal
n = n / n.norm()                                                             # (stored in float32)
r = noise[:, 1, 2]                                                           # one texel of the noise
t = r - n * (r @ n)
t = t / t.norm()
b = torch.linalg.cross(n, t)
tbn = torch.stack([t, b, n], 1)                                              # kernelMatrix
check("Gram-Schmidt gives an orthonormal frame (kernelMatrix^T kernelMatrix = I)",
      torch.allclose(tbn.T @ tbn, torch.eye(3, dtype=torch.float64), atol=1e-12))
check("and a right-handed one around the normal", torch.allclose(torch.linalg.det(tbn), torch.tensor(1.0, dtype=torch.float64)))

fixed = hemisphere_ssao(g, HemisphereSSAOParams(kernel_size=8, kernel_radius=RADIUS, noise_size=1)).ao
rotated = hemisphere_ssao(g, HemisphereSSAOParams(kernel_size=8, kernel_radius=RADIUS, noise_size=4)).ao
fig, ax = plt.subplots(1, 3, figsize=(13, 3.6), layout="constrained")
ax[0].quiver(np.zeros(16), np.zeros(16), noise[0].flatten(), noise[1].flatten(), angles="xy", scale_units="xy",
             scale=1, color=plt.cm.hsv(np.linspace(0, 1, 16)))
ax[0].set_xlim(-1.1, 1.1), ax[0].set_ylim(-1.1, 1.1), ax[0].set_aspect("equal")
ax[0].set_title("the 16 vectors of the 4×4 noise texture")
crop = (slice(H // 2, 9 * H // 10), slice(W // 10, W // 2))                # floor, left wall, tall block
for a, ao, title in [(ax[1], fixed, "one rotation for all pixels (noise_size=1)"),
                     (ax[2], rotated, "4×4 noise texture (noise_size=4)")]:
    a.imshow(ao[0, 0][crop], cmap="gray", vmin=0.4, vmax=1, interpolation="nearest")
    a.set_title(title + f"\nbanding {float(metrics.banding(ao, volume, g.view_z, mask)):.3f}, "
                f"tile energy {float(metrics.tile_energy(ao, mask)):.3f}", fontsize=9)
    a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 5 — 8 samples, zoomed: the same directions everywhere draw bands; rotations draw a 4-pixel pattern")
plt.show()
check("per-pixel rotation puts more energy at the 4x4 tile frequency (that the blur will remove)",
      metrics.tile_energy(rotated, mask) > metrics.tile_energy(fixed, mask))
check("and leaves less structured error (banding) than one kernel for all pixels",
      metrics.banding(rotated, volume, g.view_z, mask) < metrics.banding(fixed, volume, g.view_z, mask))

# %% [markdown]
# Two numbers tell the two pictures apart. `metrics.banding` is the error against the truth (here SSAO's own,
# volume flavour) after a 1.5-pixel blur, where the truth shows occlusion: what a small blur cannot remove, the
# bands. `metrics.tile_energy` is the share of the image's detail at the 4-pixel tile frequency: the noise
# texture *moves* the error there on purpose, where Step 9's blur can take it out.
#
# ## 6. The range check: halos (§1, Figs. 7–9)
#
# A sample behind a foreground object reads that object's depth, which can be metres in front of it. Counting
# it darkens the background in a band around every silhouette — the **halo** of Fig. 8. The article's fix is a
# range check: only `delta < MaxDistance` counts (Fig. 9). Thin slats in front of a wall (the `fence` scene)
# show it best. Distances are in linear depth `(z + n)/(n − f)`, so with near 0.1 and far 100, `0.01` is about
# one scene unit.

# %%
fence = load("fence")
g_fence = reference.gbuffer(fence, W, H)
gt_fence = reference.ambient_occlusion(fence, g_fence, RADIUS, rays=RAYS, weighting="uniform").ao
halo_rows = {}
for name, max_distance in [("no range check", 1.0), ("MaxDistance 0.02 (default)", 0.02),
                           ("MaxDistance 0.005", 0.005)]:
    ao = hemisphere_ssao(g_fence, HemisphereSSAOParams(kernel_size=32, kernel_radius=RADIUS,
                                                       max_distance=max_distance)).ao
    h = metrics.halo(ao, gt_fence, g_fence.view_z, g_fence.mask, band=4)
    halo_rows[name] = (ao, float(h.dark), float(h.missing))
show([v[0] for v in halo_rows.values()] + [gt_fence],
     [f"{k}\ndark halo {v[1]:.3f}, missing {v[2]:.3f}" for k, v in halo_rows.items()] + ["ground truth"],
     "Step 6 — halos behind thin slats (Fig. 8) and the range check (Fig. 9)")
check("the range check cuts the dark halo (false occlusion next to depth edges)",
      halo_rows["MaxDistance 0.02 (default)"][1] < 0.8 * halo_rows["no range check"][1])
check("a tighter range check cuts it further, but misses more real occlusion there",
      halo_rows["MaxDistance 0.005"][1] <= halo_rows["MaxDistance 0.02 (default)"][1]
      and halo_rows["MaxDistance 0.005"][2] >= halo_rows["MaxDistance 0.02 (default)"][2])

# %% [markdown]
# `metrics.halo` splits the error in the band around depth edges by sign: the **dark halo** (false occlusion,
# `max(GT − AO, 0)`) and the **missing** occlusion (`max(AO − GT, 0)`). A looser range check only ever adds the
# first; adding the two together (the band MAE) would hide which one a setting trades for the other.
#
# A tighter `MaxDistance` removes more halo but also real occlusion: at a grazing angle the depth gap behind a
# surface grows, and genuine occluders get rejected too. There is no value that is right everywhere.
#
# ## 7. The minimum distance: self-occlusion (§1, Fig. 10)
#
# The depth buffer stores one depth per pixel; a sample that lies just above a flat surface can project onto a
# texel whose centre is a hair *further forward* and count as occluded. The result is a grey film over every
# flat surface, worst on far and grazing ones. §1 suggests ignoring a thin layer just above the surface
# (Fig. 10's red region): `delta > MinDistance`.

# %%
ao_min0 = hemisphere_ssao(g, HemisphereSSAOParams(kernel_size=32, kernel_radius=RADIUS, min_distance=0.0)).ao
ao_min = hemisphere_ssao(g, HemisphereSSAOParams(kernel_size=32, kernel_radius=RADIUS, min_distance=0.0005)).ao
(rmse_min0, flat_min0), (rmse_min, flat_min) = score(ao_min0), score(ao_min)
show([ao_min0, ao_min, gt],
     [f"MinDistance 0: flat bias {flat_min0:.3f}", f"MinDistance 0.0005: flat bias {flat_min:.3f}", "ground truth"],
     "Step 7 — self-occlusion on flat walls, and the minimum distance (Fig. 10)")
check("MinDistance removes self-occlusion from flat surfaces", flat_min < 0.5 * flat_min0)

# %% [markdown]
# ## 8. Sample count: banding and noise (§1, Fig. 5)
#
# Too few samples show as banding (one fixed kernel) or noise (rotated kernels), and more samples cost time
# linearly. To measure the *sampling* error alone — not the estimator's bias of Step 4 — compare each run with
# the same pass converged at 256 samples. Its RMSE falls as the count rises, for both kinds of kernel.

# %%
counts = [4, 8, 16, 32, 64]
converged = hemisphere_ssao(g, HemisphereSSAOParams(kernel_size=256, kernel_radius=RADIUS, seed=99)).ao
runs = {(k, size_): hemisphere_ssao(g, HemisphereSSAOParams(kernel_size=k, kernel_radius=RADIUS,
                                                              noise_size=size_)).ao
        for k in counts for size_ in (1, 4)}


def sampling_error(ao):
    return float(metrics.rmse(ao, converged, mask))


fig = plt.figure(figsize=(15, 3.4), layout="constrained")
sub = fig.subfigures(1, 2, width_ratios=[3, 1.2])
axs = sub[0].subplots(1, 3)
for a, k in zip(axs, [4, 16, 64]):
    a.imshow(runs[k, 4][0, 0][crop], cmap="gray", vmin=0.4, vmax=1, interpolation="nearest")
    a.set_title(f"KERNEL_SIZE {k} (rotated)"), a.set_xticks([]), a.set_yticks([])
a = sub[1].subplots()
for size_, label in [(4, "rotated (4×4 noise)"), (1, "one fixed kernel")]:
    a.loglog(counts, [sampling_error(runs[k, size_]) for k in counts], "o-", label=label)
a.set_xticks(counts, [str(k) for k in counts]), a.minorticks_off()
a.set_xlabel("samples per pixel"), a.set_ylabel("RMSE vs 256 samples"), a.legend(fontsize=8)
fig.suptitle("Step 8 — samples per pixel vs sampling error (Fig. 5)")
plt.show()
check("more samples, less sampling error (4 -> 64 samples)",
      sampling_error(runs[64, 4]) < 0.7 * sampling_error(runs[4, 4]))

# %% [markdown]
# The error against the *ray-traced* truth hardly moves with the count (it is dominated by Step 4's
# volume-vs-rays gap), which is why real-time SSAO spends few samples and then blurs.
#
# ## 9. The 5×5 box blur (§2.3, Fig. 6)
#
# The blur pass averages the 25 texels around each pixel (`texelSize = 1/Resolution`, `i, j ∈ [−2, 2]`).
# Written out with `avg_pool2d` over a clamped (`CLAMP_TO_EDGE`) border, then with the library:

# %%
raw = runs[16, 4]
padded = F.pad(raw, (2, 2, 2, 2), mode="replicate")                        # CLAMP_TO_EDGE
blur_by_hand = F.avg_pool2d(padded, kernel_size=5, stride=1)               # result / (5.0 * 5.0)
blurred = box_blur(raw, 5)
check("the 5x5 mean by hand equals box_blur", torch.allclose(blur_by_hand, blurred, atol=1e-6))

# %% [markdown]
# Why blur *and* rotate? The window is wider than the 4-pixel noise tile, so 25 taps see all 16 rotations:
# the rotated kernel's error averages out. The fixed kernel's error is the same at neighbouring pixels (that is
# what a band is), so a blur cannot average it away. Compare with the converged pass once both are blurred:

# %%
conv_blur = box_blur(converged, 5)
err = {(k, size_): float(metrics.rmse(box_blur(runs[k, size_], 5), conv_blur, mask)) for k in counts for size_ in (1, 4)}
band_raw, band_blur = float(metrics.tile_energy(raw, mask)), float(metrics.tile_energy(blurred, mask))

fig, ax = plt.subplots(1, 4, figsize=(15, 3.3), layout="constrained", width_ratios=[1, 1, 1, 1.2])
for a, im, title in [(ax[0], raw, f"16 samples, rotated\ntile energy {band_raw:.1e}"),
                     (ax[1], blurred, f"after the 5×5 blur\ntile energy {band_blur:.1e}"),
                     (ax[2], gt, "ground truth")]:
    a.imshow(im[0, 0], cmap="gray", vmin=0, vmax=1), a.set_title(title, fontsize=9)
    a.set_xticks([]), a.set_yticks([])
for size_, label in [(4, "rotated + blur"), (1, "fixed kernel + blur")]:
    ax[3].loglog(counts, [err[k, size_] for k in counts], "o-", label=label)
ax[3].loglog(counts, [sampling_error(runs[k, 4]) for k in counts], ":", color="gray", label="rotated, no blur")
ax[3].set_xticks(counts, [str(k) for k in counts]), ax[3].minorticks_off()
ax[3].set_xlabel("samples per pixel"), ax[3].set_ylabel("RMSE vs converged (blurred)"), ax[3].legend(fontsize=8)
fig.suptitle("Step 9 — blur instead of more samples (Fig. 6)")
plt.show()
check("the blur removes the 4x4 tile pattern", band_blur < 0.5 * band_raw)
check("blurred, 16 rotated samples are closer to convergence than unblurred ones",
      err[16, 4] < 0.7 * sampling_error(runs[16, 4]))
check("rotation + blur beats a fixed kernel + blur at 16 samples", err[16, 4] < err[16, 1])

# %% [markdown]
# The box blur is not depth-aware: it also smears AO across silhouettes. Lesson 3's cross-bilateral blur fixes
# that.
#
# ## 10. Composite (§2.4)
#
# The last pass multiplies the colour by the blurred visibility, with two artistic knobs:
# `mix(OcclusionColor, color, pow(ao, OcclusionPower))`. With a black `OcclusionColor` and power 1 it is
# simply `color · ao`. A rasteriser applies AO to its *ambient* light, so we composite over the albedo under
# uniform white light — what an unshadowed ambient term looks like. (A path-traced image already contains the
# shadowing AO imitates.)

# %%
ambient = g.albedo                                                         # ColorSampler: ambient-lit colour
occlusion_color, occlusion_power = torch.tensor([0.05, 0.02, 0.0]), 1.5
t_mix = blurred.float() ** occlusion_power
by_hand_mix = occlusion_color.view(1, 3, 1, 1) * (1 - t_mix) + ambient * t_mix   # GLSL mix(a, b, t)
out = composite(ambient, blurred.float(), occlusion_color, occlusion_power)
check("mix() by hand equals composite()", torch.allclose(by_hand_mix, out, atol=1e-6))
out_gt = composite(ambient, gt, occlusion_color, occlusion_power)


def to_display(x):
    return x[0].permute(1, 2, 0).clamp(0, 1).pow(1 / 2.2)


fig, ax = plt.subplots(1, 3, figsize=(12, 3.4), layout="constrained")
for a, im, title in [(ax[0], ambient, "ambient-lit albedo"), (ax[1], out, "composited with SSAO (16, blurred)"),
                     (ax[2], out_gt, "composited with ray-traced AO")]:
    a.imshow(to_display(im)), a.set_title(title), a.set_xticks([]), a.set_yticks([])
fig.suptitle("Step 10 — composite: mix(OcclusionColor, color, ao^OcclusionPower)")
plt.show()

# %% [markdown]
# ## Checks

# %%
print(f"RMSE vs ray-traced AO: Crytek {rmse_crytek:.3f}, hemisphere {rmse_hemi_u:.3f}, centre-weighted "
      f"{rmse_hemi:.3f}, blurred {float(metrics.rmse(blurred, gt, mask)):.3f}")
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * `ssbench/passes/ao/ssao.py`, `ao/crytek.py`, `sampling.py`, `blur.py`, `composite.py` — the passes used here;
#   `ssbench/passes/teaching/ssao_basic.py` — the same shader one pixel at a time, tested equal to the pass.
# * `ssbench/reference/ao.py` — the ground truth and its three flavours; `ssbench/metrics/ao.py` — halo, flat
#   bias, banding, noise.
# * `ssbench ao cornell_box --method ssao` (command line) and `ssbench.evaluate.ao(...)` for one tidy row.
# * Next: **lesson 3**, HBAO — horizons instead of points, and a blur that respects depth edges.
