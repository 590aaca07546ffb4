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
# # Lesson 10 — Hi-Z and glossy reflections
#
# ## Overview
#
# The SSR article's marchers (lessons 4–6) read the depth buffer once per step: a long ray over an empty floor
# costs as many reads as it crosses pixels. Engines do not ship that. AMD's FidelityFX SSSR (2020) and Unity's
# HDRP trace against a **hierarchical depth buffer** (Hi-Z): a pyramid where each texel of level *m* holds the
# closest depth of the 2^m × 2^m texels under it. A ray in front of a whole tile skips it in one read and climbs a
# level; a ray that reaches a tile's closest depth descends, until a single texel decides (Uludag, "Hi-Z
# Screen-Space Cone-Traced Reflections", GPU Pro 5, 2014).
#
# This lesson builds the pyramid, walks one ray through it with the per-pixel teaching twin
# (`ssbench.passes.teaching.ssr_hiz_basic`), then runs the vectorised pass (`ssbench.passes.ssr.hiz`) and compares
# the three traversals at equal numbers of depth reads (`ssbench.analysis.equal_reads`). Then the surfaces get
# rough: a glossy reflection averages a *lobe* of directions. We sample it the way engines do (GGX visible
# normals), trace it with Hi-Z, and score two glossy methods against a path-traced lobe.
#
# > **You will learn**
# > 1. why a ray is a straight line in screen space *and* depth when depth is stored as 1/z (reversed Z);
# > 2. how the closest-depth pyramid is built, at any image size;
# > 3. the two moves of the traversal — skip and climb, or descend — read by read;
# > 4. how many reads Hi-Z spends compared with the DDA, and what it gets right for them;
# > 5. three pitfalls of the shipped versions, and how the library avoids them;
# > 6. how a glossy lobe is sampled, what its ground truth is, and which part of a glossy method's error is the
# >    marcher, the G-buffer's missing information, and the resolve.

# %% [markdown]
# ## Setup
#
# The scene is `reflective_floor`: a mirror floor, objects cut by the frame, one hidden behind another. The size
# is 320 × 240 (160 × 120 in the tests).

# %%
import math

import matplotlib.patches as patches
import matplotlib.pyplot as plt
import torch

import _setup
from ssbench.analysis.equal_reads import equal_read_rows
from ssbench.evaluate import GLOSSY_GT_CHANNELS, SSR_GT_CHANNELS, run_glossy
from ssbench.passes.ssr.common import BEHIND_SURFACE, HIT, OUT_OF_STEPS, reflection_rays
from ssbench.passes.ssr.dda import DDASSRParams, ssr_dda
from ssbench.passes.ssr.ggx import alpha_of, sample_vndf
from ssbench.passes.ssr.hiz import HiZSSRParams, ssr_hiz
from ssbench.passes.ssr.hiz_pyramid import depth_pyramid, reversed_depth
from ssbench.passes.teaching.ssr_hiz_basic import trace_pixel
from ssbench.reference import gbuffer, reflections
from ssbench.reference.glossy import glossy_reflections

torch.set_num_threads(1)
W, H = _setup.size()
SCENE = "reflective_floor"
chans = tuple(dict.fromkeys(("view_z", "normal", "mask", "color", "metallic", "roughness") + SSR_GT_CHANNELS))
g = gbuffer(SCENE, W, H, channels=chans, spp=8)
cam = g.camera
print(f"{SCENE} at {W}×{H}, near {cam.near}, far {cam.far}")

# %% [markdown]
# ## Step 1 — Depth as 1/z: a ray is a straight line
#
# McGuire and Mara's observation (lesson 5): along a projected ray, `k = 1/w` is linear in screen space. So is
# `rz = near/(−z) = near · k`, the **infinite reversed Z** HDRP stores (1 at the near plane, 0 at infinity). In
# `(px, py, rz)` a view-space ray is a straight segment, so the traversal can find where it crosses a tile's
# border or its depth with one division each. Below: points along one floor pixel's mirror ray, projected; the
# `rz` of each lies on the line through the two ends.

# %%
j, i = int(0.8 * H), W // 2
o = g.position[0, :, j, i]
d = reflection_rays(g.position, g.normal)[0, :, j, i]
s = torch.linspace(0.0, 3.0, 7, dtype=torch.float64)[:, None]
pts = (o + s * d).double()
px = cam.view_to_pixel(pts, dim=-1)
rz = cam.near / -pts[:, 2]
u = (px - px[0]).norm(dim=1) / (px[-1] - px[0]).norm()          # where along the screen segment
line = rz[0] + u * (rz[-1] - rz[0])
dev_rz = float((rz - line).abs().max())
print(f"|rz − straight line| ≤ {dev_rz:.1e} over {len(s)} points; view z would bend by "
      f"{float((pts[:, 2] - (pts[0, 2] + u * (pts[-1, 2] - pts[0, 2]))).abs().max()):.3f}")

# %% [markdown]
# ## Step 2 — The pyramid of closest depths
#
# Level 0 is `rz` (background 0: it never occludes). Each next level keeps the **largest** `rz` — the closest
# surface — of up to 2 × 2 cells, rounding the size up. Cell `(cx, cy)` of level *m* covers texels
# `[cx·2^m, (cx+1)·2^m)`, whatever the image size: FidelityFX addresses mips in uv at `size >> m`, which puts cell
# borders between texels when a side is not a power of two.

# %%
pyr = depth_pyramid(reversed_depth(g.view_z, g.mask, cam.near))
print("level sizes:", [tuple(lv.shape[-2:]) for lv in pyr.levels])
fig, ax = plt.subplots(1, 4, figsize=(13, 2.8))
for a, m in zip(ax, (0, 2, 4, 6)):
    a.imshow(pyr.levels[m][0, 0], cmap="viridis", vmin=0, vmax=float(pyr.levels[0].max()))
    a.set_title(f"level {m}: {tuple(pyr.levels[m].shape[-2:])}")
    a.axis("off")
plt.show()
m = 3
block = pyr.levels[0][0, 0, 8:16, 16:24]
assert float(pyr.levels[m][0, 0, 1, 2]) == float(block.max())   # cell (2, 1) of level 3 = max of its 8×8 texels

# %% [markdown]
# ## Step 3 — One ray, read by read
#
# `trace_pixel` runs FidelityFX's `FFX_SSSR_HierarchicalRaymarch` for one pixel, one function per step:
#
# * `InitialAdvanceRay` moves the ray just past its own texel's border (no self-hit);
# * each read fetches the cell under the ray at its level. `AdvanceRay`: if the ray is **in front** of the cell
#   (`rz` larger than the cell's), it moves to where it leaves the cell — sideways (the tile is skipped: climb a
#   level) or down to the cell's closest depth (descend). If it is **behind**, it stays and descends;
# * behind a level-0 texel is a candidate: within the thickness behind the surface, it is a hit.

# %%
p = HiZSSRParams(max_ray_distance=20.0, depth_buffer_thickness=0.1)
t = trace_pixel(g, p, (i, j))
print(f"termination {t['termination']} after {t['steps']} reads")
print(" read  level  cell        t       in front  skipped")
for n, (mip, cell, tt, above, skipped) in enumerate(t["path"]):
    print(f"{n:5d}  {mip:5d}  {str(cell):10s} {tt:8.4f}  {str(above):8s}  {skipped}")
fig, a = plt.subplots(figsize=(7, 5.2))
a.imshow(g.view_z[0, 0], cmap="gray")
colours = plt.cm.plasma(torch.linspace(0, 0.9, pyr.count).tolist())
for mip, cell, _, _, _ in t["path"]:
    size = 2 ** mip
    a.add_patch(patches.Rectangle((cell[0] * size - 0.5, cell[1] * size - 0.5), size, size, fill=False,
                                  edgecolor=colours[mip], linewidth=1.5))
a.plot([t["origin"][0] - 0.5, t["p1"][0] - 0.5], [t["origin"][1] - 0.5, t["p1"][1] - 0.5], "c--", linewidth=1)
a.set_xlim(-0.5, W - 0.5), a.set_ylim(H - 0.5, -0.5)
a.set_title("cells read, coloured by level (dashed: the ray)")
plt.show()

# %% [markdown]
# ## Step 4 — The whole image: reads per pixel
#
# The vectorised pass marches every pixel at once and is proven equal to the twin
# (`tests/passes/ssr/test_hiz.py`). Its `steps` are pyramid reads. The DDA (lesson 6) reads one texel per step.

# %%
hz = ssr_hiz(g, p, debug=True)
dd = ssr_dda(g, DDASSRParams(max_ray_distance=20.0, z_thickness=0.1, refinement="none"))
both = hz.hit & dd.hit
print(f"where both hit ({int(both.sum())} px): mean reads Hi-Z {float(hz.steps[both].float().mean()):.1f}, "
      f"DDA {float(dd.steps[both].float().mean()):.1f}")
print("reads per level, all rays:", hz.debug["reads_per_level"].tolist())
fig, ax = plt.subplots(1, 2, figsize=(11, 3.6))
for a, r, name in ((ax[0], hz, "Hi-Z"), (ax[1], dd, "DDA")):
    im = a.imshow(torch.where(g.mask, r.steps.float(), math.nan)[0, 0], cmap="magma", vmin=0, vmax=64)
    a.set_title(f"{name}: depth reads per pixel")
    a.axis("off")
fig.colorbar(im, ax=ax, shrink=0.8)
plt.show()

# %% [markdown]
# ## Step 5 — Equal reads: what each traversal gets right
#
# Cost on a GPU is mostly reads, so the fair comparison caps every marcher at the same number of reads per ray,
# at the same ray length and thickness (each method declares how: `READ_BUDGET` beside its code). The classes
# come from the exact mirror hits traced by Mitsuba (lesson 4).

# %%
truth = reflections(SCENE, g, spp=8)
budgets = _setup.pick([8, 16, 32, 64, 128], [8, 32, 128])
rows = equal_read_rows(SCENE, g, truth, budgets=budgets, methods=["linear", "dda", "hiz"], progress=False)
plt.figure(figsize=(6, 3.5))
for m in ("linear", "dda", "hiz"):
    mine = [r for r in rows if r["method"] == m]
    plt.plot([r["budget"] for r in mine], [r["frac_correct"] for r in mine], "o-", label=m)
plt.xscale("log", base=2)
plt.xlabel("depth reads per ray (budget)"), plt.ylabel("correct share of reflective pixels")
plt.legend()
plt.show()
for r in rows:
    print(f"{r['method']:>7} {r['budget']:4d} reads: correct {r['frac_correct']:.1%}, missed {r['frac_missed']:.1%}, "
          f"reads made {r['reads_mean']:.1f}")

# %% [markdown]
# ## Step 6 — Three pitfalls of the shipped code
#
# 1. **Running out of iterations.** FidelityFX's `valid_hit = i <= max_traversal_intersections` is true on every
#    exit of its loop, so a ray that ran out of reads is returned as a hit wherever it stopped. Here such rays are
#    `OUT_OF_STEPS`, never a hit.
# 2. **Rays toward the camera.** FidelityFX projects `o + d` to find the screen direction. For a surface closer
#    than one unit, a ray toward the camera puts `o + d` behind the eye (`w ≤ 0`) and the projection flips. Here
#    the ray is clipped at the near plane before it is projected (as in the article).
# 3. **Behind a thin object.** FidelityFX ends the ray at the first texel it passes behind; HDRP steps past it at
#    level 0 and goes on (`trace_behind`): linear cost behind objects, but the ray can reach what lies behind.

# %%
short = ssr_hiz(g, HiZSSRParams(max_ray_distance=20.0, depth_buffer_thickness=0.1, max_traversal_intersections=6))
spent = short.termination == OUT_OF_STEPS
print(f"6 reads: {int(spent.sum())} rays ran out, hits among them: {int(short.hit[spent].sum())}")
behind = ssr_hiz(g, HiZSSRParams(max_ray_distance=20.0, depth_buffer_thickness=0.1, trace_behind=True))
stopped = hz.termination == BEHIND_SURFACE
print(f"stopped behind a surface: {int(stopped.sum())} px; with trace_behind, {int((stopped & behind.hit).sum())} "
      f"of them find a hit further on, at {float(behind.steps[stopped].float().mean()):.1f} reads on average")

# %% [markdown]
# ## Step 7 — Glossy rays: sampling the GGX lobe
#
# A rough surface reflects about *microfacet* normals `m` spread around `n` with the GGX distribution,
# `α = roughness²`. Sampling only the normals the viewer can see (Heitz, "Sampling the GGX Distribution of Visible
# Normals", JCGT 2018) wastes no ray on back-facing microfacets; each reflected direction `l = 2(v·m)m − v` is
# then marched like a mirror ray. At roughness 0 the only normal is `n`: the mirror.

# %%
v = torch.tensor([[0.5, 0.0, math.sqrt(0.75)]], dtype=torch.float64)      # 30° from the normal, local frame
u = torch.rand(2, 2000, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
fig, ax = plt.subplots(1, 3, figsize=(11, 3.4))
spreads = {}
for a, rough in zip(ax, (0.1, 0.3, 0.5)):
    alpha = alpha_of(torch.full((2000,), rough, dtype=torch.float64))
    m = sample_vndf(v.expand(2000, 3), alpha, u[0], u[1])
    l = 2.0 * (v * m).sum(1, keepdim=True) * m - v
    spreads[rough] = float(torch.acos((l * torch.tensor([-0.5, 0.0, math.sqrt(0.75)], dtype=torch.float64)).sum(1)
                                      .clamp(-1, 1)).median())
    a.scatter(l[:, 0], l[:, 1], s=1, alpha=0.3)
    a.plot([-0.5], [0.0], "r+", ms=12)
    a.set_xlim(-1, 1), a.set_ylim(-1, 1), a.set_aspect("equal")
    a.set_title(f"roughness {rough}: median {math.degrees(spreads[rough]):.1f}° off the mirror")
plt.show()
mirror = sample_vndf(v, torch.zeros(1, dtype=torch.float64), u[0, :1], u[1, :1])

# %% [markdown]
# ## Step 8 — The glossy truth, and what screen space cannot see
#
# `ssbench.reference.glossy` traces each pixel's lobe in Mitsuba: many directions per pixel, one path each. The
# **lobe** is the radiance arriving along them, averaged (what a glossy reflection buffer should hold). The
# **oracle** uses the same directions but reads the G-buffer colour where each first hit lands, if the camera sees
# it — the best any screen-space method could do. Their difference is information the G-buffer does not have:
# the sky, what is off screen, what is hidden. The scene `glossy_ramp` has floor strips and spheres of rising
# roughness.

# %%
GW, GH = _setup.size((160, 120))
gg = gbuffer("glossy_ramp", GW // 2, GH // 2, channels=tuple(dict.fromkeys(chans + GLOSSY_GT_CHANNELS)), spp=8)
truth_g = glossy_reflections("glossy_ramp", gg, rays=_setup.pick(64, 32))
fig, ax = plt.subplots(1, 3, figsize=(11, 3))
show = lambda x: (x[0].permute(1, 2, 0).clamp(0, 1) ** (1 / 2.2))       # noqa: E731
ax[0].imshow(show(gg.color)), ax[0].set_title("the image")
ax[1].imshow(show(truth_g.lobe)), ax[1].set_title("lobe (path traced)")
ax[2].imshow(show(truth_g.oracle)), ax[2].set_title("oracle (G-buffer only)")
for a in ax:
    a.axis("off")
plt.show()

# %% [markdown]
# ## Step 9 — Three answers on rough surfaces, and where their error comes from
#
# The mirror DDA ignores roughness. `glossy_blur` is the article's way: the mirror march, then a blur that
# widens with roughness. `glossy_stochastic` traces GGX rays with Hi-Z and reuses the neighbours' hits
# (Stachowiak, "Stochastic Screen-Space Reflections", 2015). `run_glossy` splits each error: against the oracle
# (the marcher and its filter) and against the lobe (everything); the article's resolve `F·(1 − roughness)` is
# scored on its own with the true lobe.

# %%
evs, g_, t_ = {}, gg, truth_g
for m in ("dda", "glossy_blur", "glossy_stochastic"):
    evs[m] = run_glossy("glossy_ramp", m, gbuffer=g_, truth=t_, warmup=False)
mids = [0.5 * (b["lo"] + b["hi"]) for b in evs["dda"].row["bins"]]
plt.figure(figsize=(6, 3.5))
for m, ev in evs.items():
    plt.plot(mids, [b["mae_vs_oracle"] for b in ev.row["bins"]], "o-", label=m)
plt.fill_between(mids, 0, [b["truth_se_mean"] for b in evs["dda"].row["bins"]], color="0.85", label="truth's error bar")
plt.xlabel("roughness"), plt.ylabel("mean |reflection − oracle|")
plt.legend()
plt.show()
for m, ev in evs.items():
    r = ev.row
    print(f"{m:>18}: vs oracle {r['mae_vs_oracle']:.3f}, vs lobe {r['mae_lobe']:.3f} "
          f"(information loss alone {r['mae_oracle']:.3f}); resolve model alone {r['mae_resolve_only']:.3f}")

# %% [markdown]
# ## Checks

# %%
assert dev_rz < 1e-9
assert t["termination"] == HIT and max(step[0] for step in t["path"]) >= 2
assert int(hz.termination[0, 0, j, i]) == HIT and int(hz.steps[0, 0, j, i]) == t["steps"]
assert float(hz.steps[both].float().mean()) < 0.5 * float(dd.steps[both].float().mean())
assert int(hz.debug["reads_per_level"].sum()) == int(hz.steps.sum())
best = {m: max(r["frac_correct"] for r in rows if r["method"] == m) for m in ("linear", "dda", "hiz")}
assert min(best.values()) > 0.3
mid = {r["method"]: r for r in rows if r["budget"] == 32}
assert mid["hiz"]["frac_correct"] > mid["linear"]["frac_correct"]
assert int(spent.sum()) > 0 and not bool(short.hit[spent].any())
assert int((stopped & behind.hit).sum()) > 0
assert torch.equal(mirror, torch.tensor([[0.0, 0.0, 1.0]], dtype=torch.float64))
assert spreads[0.1] < spreads[0.3] < spreads[0.5]
assert float(truth_g.lobe_se[truth_g.valid.expand(-1, 3, -1, -1)].mean()) < 0.1
rough_err = {m: sum(b["mae_vs_oracle"] for b in ev.row["bins"] if b["lo"] >= 0.15 and b["n"] > 0) for m, ev in evs.items()}
assert rough_err["glossy_blur"] < rough_err["dda"] and rough_err["glossy_stochastic"] < rough_err["dda"]
print("all checks passed")

# %% [markdown]
# ## See also
#
# - `ssbench/passes/ssr/hiz.py`, `hiz_march.py`, `hiz_pyramid.py`: the pass, its traversal and the pyramid.
# - `ssbench/passes/teaching/ssr_hiz_basic.py`: the per-pixel twin used in step 3.
# - `ssbench/passes/ssr/ggx.py`, `glossy_stochastic.py`, `glossy_blur.py`, `ssbench/reference/glossy.py`: steps 7–9;
#   the report's **Glossy reflections** section runs every SSR method on `glossy_ramp`.
# - `benchmarks/bench_ssr_reads.py` and the report's SSR section: the equal-reads table on every scene.
# - Lesson 6 (the DDA) and lesson 9 (reading a report).
