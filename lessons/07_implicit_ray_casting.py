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
# # Lesson 7 — Ray casting implicit surfaces
#
# ## Overview
#
# Progressive-tracing article (*陰的に定義された曲面の漸進的レイトレーシング*, "progressive ray tracing of arbitrary implicit
# surfaces") renders any surface written as **f(p) = 0**: the user types a formula, and every pixel must find
# the first `t` where its ray `s + t·d` meets the surface. Before its own method (lesson 8), the article's
# background (背景) walks through the ways to do that, and what each one needs from `f`:
#
# the closed form (a sphere) → equal steps and a sign change (fast, but thin things **punch through**, Fig. 02)
# → sphere tracing with a distance bound (Fig. 05; safe only if the bound is true) → interval arithmetic (safe
# for any formula, but slow and pessimistic).
#
# The methods are scored against a **certified** first hit: `ssbench.reference.implicit` isolates the
# first sign change of every pixel's ray with interval arithmetic in float64, and `ssbench.metrics.implicit`
# labels each pixel correct, punch-through, early hit, false hit or true miss.
#
# > **You will learn**
# > 1. what `f(p) = 0` and `f_t(t) = f(s + t·d)` mean, and how a user's `f` is parsed safely (never `eval`);
# > 2. the article's ray–sphere quadratic, written out and checked against `analytic_sphere`;
# > 3. the fixed-step march with its sign-change test and bisection, traced by hand for one ray (Fig. 02);
# > 4. how often a thin shell punches through, as a function of the step count — and the `w/h` rule behind it;
# > 5. sphere tracing with a Lipschitz bound λ (Fig. 05), its cost map, and over-relaxation ω;
# > 6. what happens when λ is wrong: overshoot on the displaced torus, holes on a badly scaled sphere;
# > 7. the double root `(‖p‖−1)²`, which no sign-change method can see;
# > 8. interval arithmetic: enclosures on boxes, their over-estimation, and the certified reference.

# %% [markdown]
# ## Setup
#
# Small images (a quarter of the catalog's 160 × 120 per side at the small size) keep the certified references
# cheap; every number below is recomputed when you change `SSBENCH_LESSON_SIZE`.

# %%
import matplotlib.pyplot as plt
import numpy as np
import torch
from matplotlib.colors import LogNorm
from matplotlib.patches import Circle, Patch, Rectangle

from ssbench.implicit import ExpressionError, load, parse
from ssbench.metrics import implicit as M
from ssbench.passes import IMPLICIT_METHODS, implicit_method
from ssbench.passes.implicit.analytic import analytic_sphere
from ssbench.passes.implicit.common import OUT_OF_STEPS, camera_rays
from ssbench.passes.implicit.fixed import FixedStepParams, fixed_step
from ssbench.passes.implicit.sphere import SphereTraceParams, sphere_trace
from ssbench.reference import dense_march
from ssbench.reference import implicit as certified
from _setup import size

W, H = size((128, 96))
print(f"image size {W}x{H}; implicit methods:", {name: implicit_method(name)[0].__name__ for name in IMPLICIT_METHODS})

checks = {}


def check(name, ok):
    """Record a claim and fail right here if it does not hold."""
    checks[name] = bool(ok)
    assert ok, name


def scene_at(name, width=None):
    """A catalog scene, its surface (frame 0) and its camera at the lesson's size."""
    sc = load(name)
    return sc, sc.surface(0), sc.camera.with_resolution(width or W, H)


CLASS_LUT = torch.tensor([M.CLASS_COLORS[c] for c in sorted(M.CLASS_COLORS)])


def class_rgb(classes):
    """(1, 1, H, W) class codes → an RGB image (one table lookup, no loop)."""
    return CLASS_LUT[classes[0, 0].long()].numpy()


def class_legend(ax, codes, **kw):
    ax.legend(handles=[Patch(color=M.CLASS_COLORS[c], label=M.CLASS_NAMES[c].replace("_", " ")) for c in codes],
              fontsize=7, **kw)


def near_centre(mask):
    """(x, y) of the True pixel of a (H, W) mask closest to the image centre."""
    ys, xs = mask.nonzero(as_tuple=True)
    i = int(((ys.double() - mask.shape[0] / 2) ** 2 + (xs.double() - mask.shape[1] / 2) ** 2).argmin())
    return int(xs[i]), int(ys[i])


def bare(*axes):
    for a in axes:
        a.set_xticks([]), a.set_yticks([])

# %% [markdown]
# ## 1. `f(p) = 0`, and a formula typed by a user (背景: レイキャスティング, Fig. 01)
#
# The article defines the surface as the zero set of a continuous `f`, the ray as `s + t·d` with `‖d‖ = 1`,
# and ray casting as finding the **smallest root** of
#
# ```
# f_t(t) = f(s + t·d) = 0          (Fig. 01)
# ```
#
# The premise is that `f` is *arbitrary* — the user types it. ssbench parses the text with a whitelist
# recursive-descent parser (numbers, `x y z p`, named parameters and definitions, a fixed list of functions);
# nothing is ever passed to `eval`, so a formula cannot run code. Here is a user's blobby union
# (`smin`, the quadratic smooth minimum), evaluated on the plane `z = 0`, with one ray in that plane and its
# `f_t(t)`.

# %%
user_f = parse("smin(length(p - a) - 0.5, length(p - b) - 0.4, k)", params={"k": 0.25},
               defs={"a": "vec3(-0.55, 0, 0)", "b": "vec3(0.55, 0.1, 0)"})
print(user_f, f"— {user_f.n_ops} nodes after lowering")

refused = {}
for text in ["__import__('os').system('rm -rf ~')", "x.__class__", "open('secrets')", "exp(x)^999",
             "lambda: 0"]:
    try:
        parse(text)
    except ExpressionError as e:
        refused[text] = str(e).splitlines()[0]
for text, why in refused.items():
    print(f"refused {text!r:40} {why}")
check("every malicious or oversized formula is refused with an ExpressionError", len(refused) == 5)

# the same f written out in torch (the parser's documented smin), at a few points
q = torch.tensor([[0.0, 0.0, 0.0], [0.9, -0.3, 0.2], [-1.2, 0.5, 0.1]], dtype=torch.float64)
fa = (q - torch.tensor([-0.55, 0.0, 0.0], dtype=torch.float64)).norm(dim=-1) - 0.5
fb = (q - torch.tensor([0.55, 0.1, 0.0], dtype=torch.float64)).norm(dim=-1) - 0.4
hk = (0.25 - (fa - fb).abs()).clamp_min(0) / 0.25
check("the parsed formula equals smin written out by hand",
      torch.allclose(user_f(q), torch.minimum(fa, fb) - hk * hk * 0.25 / 4, atol=1e-14))
val, grad = user_f.f_and_grad(q)
step_fd = 1e-6
fd = torch.stack([(user_f(q + step_fd * e) - user_f(q - step_fd * e)) / (2 * step_fd)
                  for e in torch.eye(3, dtype=torch.float64)], -1)
check("its autograd gradient matches central differences (the normal used for shading)",
      torch.allclose(grad, fd, atol=1e-6))

xs, ys = np.linspace(-1.6, 1.6, 321), np.linspace(-1.1, 1.1, 221)
P = torch.tensor(np.stack([*np.meshgrid(xs, ys), np.zeros((221, 321))], -1))
F_slice = user_f(P).numpy()
s_ray = torch.tensor([-1.55, 0.2, 0.0], dtype=torch.float64)
d_ray = torch.tensor([1.0, 0.04, 0.0], dtype=torch.float64)
d_ray = d_ray / d_ray.norm()
ts = torch.linspace(0, 3.2, 1601, dtype=torch.float64)
ft = user_f(s_ray + ts[:, None] * d_ray).numpy()
roots = ts[:-1][(ft[:-1] >= 0) & (ft[1:] < 0)].numpy()                     # entering crossings, for the picture

fig, ax = plt.subplots(1, 2, figsize=(12, 3.8), layout="constrained", width_ratios=[1.3, 1])
im = ax[0].imshow(F_slice, extent=(xs[0], xs[-1], ys[0], ys[-1]), origin="lower", cmap="RdBu", vmin=-0.6, vmax=0.6)
ax[0].contour(xs, ys, F_slice, [0.0], colors="k", linewidths=1.5)
ax[0].plot(*(s_ray[:2] + ts[[0, -1], None] * d_ray[:2]).T.numpy(), "k--", lw=1)
ax[0].plot(*s_ray[:2].numpy(), "ko")
for r in roots:
    ax[0].plot(*(s_ray[:2] + r * d_ray[:2]).numpy(), "y*", ms=12)
ax[0].set_title("user f on the plane z = 0 (black: f = 0); a ray s + t·d", fontsize=9)
fig.colorbar(im, ax=ax[0], shrink=0.8, label="f")
ax[1].plot(ts, ft, "k-", lw=1)
ax[1].axhline(0, color="gray", lw=0.8)
for i, r in enumerate(roots):
    ax[1].axvline(r, color="y" if i == 0 else "0.7", lw=2 if i == 0 else 1)
ax[1].set_xlabel("t"), ax[1].set_ylabel("f_t(t) = f(s + t·d)")
ax[1].set_title(f"the answer is the smallest root: t = {roots[0]:.3f} (yellow)", fontsize=9)
fig.suptitle("Step 1 — the surface is f = 0; ray casting is the first root of f_t (Fig. 01)")
plt.show()
check("this ray enters the surface twice (two separate blobs), so 'first root' matters", len(roots) == 2)

# %% [markdown]
# ## 2. The closed form: ray and sphere (背景: レイキャスティング)
#
# For a sphere `f(x) = ‖x − c‖ − r` the article substitutes the ray and gets a quadratic in `t`:
#
# ```
# t² + 2((s − c)·d) t + ((s − c)² − r²) = 0
# ```
#
# Below it is written out for every pixel at once (`b = (s − c)·d`, the smaller root `−b − √(b² − c₀)`) and
# compared with `analytic_sphere`, which solves the same quadratic in a cancellation-free form. Then the
# catalog's `sphere` (`length(p) − 1`) is marched with 32 equal steps: where both hit, bisection lands within
# `10⁻⁶` of the exact root. A pixel the march misses must have a chord through the ball shorter than one step
# (a longer chord always holds a sample): at the small size there are none, at larger sizes a few on the
# silhouette.

# %%
sc_sph, sph, cam_s = scene_at("sphere")
rays = camera_rays(cam_s, dtype=torch.float64)
c, r = torch.zeros(1, 3, 1, 1, dtype=torch.float64), 1.0
check("the catalog sphere is f = ‖p‖ − 1: f(c) = −r", float(sph.f(c.view(1, 3))) == -r)

# the article's quadratic, every pixel at once
b = ((rays.origin - c) * rays.direction).sum(1, keepdim=True)            # (s − c)·d
c0 = ((rays.origin - c) ** 2).sum(1, keepdim=True) - r * r               # (s − c)² − r²
disc = b * b - c0
t_hand = -b - disc.clamp_min(0).sqrt()                                   # the smaller root
hit_hand = (disc >= 0) & (t_hand >= rays.t_near) & (t_hand <= rays.t_far)
exact = analytic_sphere(rays, (0, 0, 0), r)
check("the hand quadratic hits exactly the pixels analytic_sphere hits", torch.equal(hit_hand, exact.hit))
check("and at the same t (float64, to 1e-9)", bool(((t_hand - exact.t).abs()[exact.hit] < 1e-9).all()))

N = 32
fx = fixed_step(sph, rays, FixedStepParams(steps=N))
both = fx.hit & exact.hit
err = (fx.t - exact.t).abs()
t0_, t1_ = exact.debug["roots"][:, :1], exact.debug["roots"][:, 1:]
chord_sph = torch.where(exact.hit, t1_ - t0_, torch.zeros_like(t0_))
missed = exact.hit & ~fx.hit
step_len = rays.t_far / N
print(f"fixed step N={N}: {int(both.sum())} of {int(exact.hit.sum())} sphere pixels hit, max |t − t_exact| "
      f"{float(err[both].max()):.1e}; missed {int(missed.sum())}, their chord / step ≤ "
      f"{float((chord_sph / step_len)[missed].max()) if missed.any() else 0:.2f}")
check("bisection puts every fixed-step hit within 1e-6 of the exact root", float(err[both].max()) < 1e-6)
check("fixed step never hits where the exact answer is a miss", not bool((fx.hit & ~exact.hit).any()))
check("every pixel fixed step misses has a chord shorter than its step (a longer one must hold a sample)",
      bool((chord_sph < step_len)[missed].all()))

py0, px0 = H // 2, W // 2
tt = torch.linspace(0, 6, 600, dtype=torch.float64)
fig, ax = plt.subplots(1, 3, figsize=(14, 3.6), layout="constrained")
im = ax[0].imshow(torch.where(exact.hit, exact.t, torch.nan)[0, 0], cmap="viridis")
fig.colorbar(im, ax=ax[0], shrink=0.8, label="t")
ax[0].plot(px0, py0, "r+", ms=10), ax[0].set_title("analytic_sphere: t of the first root", fontsize=9)
quad = tt ** 2 + 2 * b[0, 0, py0, px0] * tt + c0[0, 0, py0, px0]
ax[1].plot(tt, quad, "k-"), ax[1].axhline(0, color="gray", lw=0.8)
for v in exact.debug["roots"][0, :, py0, px0]:
    ax[1].axvline(float(v), color="C1")
ax[1].set_xlabel("t"), ax[1].set_ylabel("t² + 2bt + c₀")
ax[1].set_title("the red pixel's quadratic: the first root is the hit", fontsize=9)
show = torch.where(both, err.clamp_min(1e-12).log10(), torch.nan)[0, 0]
im = ax[2].imshow(show, cmap="magma")
ax[2].imshow(np.where(missed[0, 0].numpy()[..., None], [[M.CLASS_COLORS[M.PUNCH_THROUGH]]], np.nan))
fig.colorbar(im, ax=ax[2], shrink=0.8, label="log10 |t_fixed − t_exact|")
ax[2].set_title(f"fixed step N={N} + 20 bisections vs exact\n(magenta: missed, if any)", fontsize=9)
bare(ax[0], ax[2])
fig.suptitle("Step 2 — the ray–sphere quadratic, and how close a marcher gets to it")
plt.show()

# %% [markdown]
# ## 3. Equal steps, a sign change, bisection — one ray by hand (背景 Fig. 02; 手法: 二分法による絞込み)
#
# Without a closed form, the article steps `t_{n+1} = t_n + s_n` and stops where `f_t` changes sign — in its
# method section, precisely where `f_t(t_i) ≥ 0` and `f_t(t_{i+1}) < 0` (the ray **enters** the object). The
# bracket `[t_i, t_{i+1}]` is then halved 20 times (二分法). With a constant step `s = t_far / N` this is
# `fixed_step`. Fig. 02 is the catch: a step longer than the object lets the ray pass **through** it.
#
# The catalog's `thin_shell` is `|‖p‖ − 1| − 0.01`, a sphere with a wall 0.02 thick, seen from 3.3 away with
# `far = 8`: 32 steps are 0.25 long, twelve times the wall. Below, two rays are marched by hand — one whose
# samples happen to land in the front wall, one whose samples straddle it — and compared with `fixed_step`.

# %%
sc_shell, shell, cam_shell = scene_at("thin_shell")
rays = camera_rays(cam_shell, dtype=torch.float64)
ref_shell = certified(shell, cam_shell, exits=True)                   # certified first root and its chord (Step 8)
fx32 = fixed_step(shell, rays, FixedStepParams(steps=32))
cls32, _ = M.classify(fx32, ref_shell)
front = ref_shell.hit[0, 0] & (ref_shell.t[0, 0] < 3.0)         # rays that meet the front wall first


def march_by_hand(px, py, n_steps=32, iterations=20):
    """The fixed-step march of one pixel, written out: samples 0, s, 2s, …; first f ≥ 0 → f < 0; bisection."""
    o, d = rays.origin[0, :, py, px], rays.direction[0, :, py, px]
    t_far = float(rays.t_far[0, 0, py, px])
    f_t = lambda t: float(shell.f((o + t * d)[None]))           # noqa: E731  f_t(t) = f(s + t·d)
    s = t_far / n_steps
    samples = [(0.0, f_t(0.0))]
    bracket = None
    for k in range(1, n_steps + 1):
        t_k = s + (k - 1) * s                                   # t_k = k·s
        samples.append((t_k, f_t(t_k)))
        if samples[-2][1] >= 0 > samples[-1][1]:                # the ray entered the object
            bracket = (samples[-2][0], t_k)
            break
    if bracket is None:
        return dict(hit=False, t=t_far, samples=samples)
    lo, hi = bracket
    for _ in range(iterations):                                 # 二分法: keep f(lo) ≥ 0 > f(hi)
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f_t(mid) >= 0 else (lo, mid)
    return dict(hit=True, t=0.5 * (lo + hi), samples=samples, bracket=bracket)


caught = near_centre(front & (cls32[0, 0] == M.CORRECT))
punched = near_centre(front & (cls32[0, 0] == M.PUNCH_THROUGH))
by_hand = {name: march_by_hand(*pix) for name, pix in (("caught", caught), ("punched through", punched))}
for name, pix in (("caught", caught), ("punched through", punched)):
    hand, (px, py) = by_hand[name], pix
    lib_t, lib_hit = float(fx32.t[0, 0, py, px]), bool(fx32.hit[0, 0, py, px])
    print(f"{name:16} pixel {pix}: by hand hit={hand['hit']} t={hand['t']:.9f} after {len(hand['samples'])} "
          f"samples; fixed_step hit={lib_hit} t={lib_t:.9f} after {int(fx32.steps[0, 0, py, px])}")
    check(f"the hand march of the {name} ray agrees with fixed_step (hit, t to 1e-12, samples)",
          hand["hit"] == lib_hit and abs(hand["t"] - lib_t) < 1e-12
          and len(hand["samples"]) == int(fx32.steps[0, 0, py, px]))

fig, ax = plt.subplots(1, 2, figsize=(13, 3.6), layout="constrained")
for a, name, pix in ((ax[0], "caught", caught), (ax[1], "punched through", punched)):
    px, py = pix
    hand = by_hand[name]
    o, d = rays.origin[0, :, py, px], rays.direction[0, :, py, px]
    t_true, t_exit = float(ref_shell.t[0, 0, py, px]), float(ref_shell.t_exit[0, 0, py, px])
    tt = torch.linspace(t_true - 0.6, t_true + 0.6, 4001, dtype=torch.float64)
    a.plot(tt, shell.f(o + tt[:, None] * d), "k-", lw=1)
    a.axvspan(t_true, t_exit, color=M.CLASS_COLORS[M.CORRECT], alpha=0.4,
              label=f"front wall, chord {t_exit - t_true:.3f}")
    st = np.array([smp for smp in hand["samples"] if abs(smp[0] - t_true) < 0.6])
    a.plot(st[:, 0], st[:, 1], "o", color="C0", label="samples t_k = k·s")
    if hand["hit"]:
        a.axvline(hand["t"], color="C1", lw=2, label=f"bisected t = {hand['t']:.4f}")
    a.axhline(0, color="gray", lw=0.8)
    a.set_ylim(-0.03, 0.2), a.set_xlabel("t"), a.set_ylabel("f_t(t)"), a.legend(fontsize=7, loc="upper right")
    a.set_title(f"{name}: pixel {pix}", fontsize=9)
fig.suptitle("Step 3 — a step of 0.25 against a wall of 0.02: the samples straddle it or land in it (Fig. 02)")
plt.show()

# %% [markdown]
# ## 4. Punch-through on the thin shell, against the step count (背景 Fig. 02; 結果, the right-hand image)
#
# Over the whole image, how many rays go through the wall? If the samples fall at a random phase, a slab of
# chord `w` along the ray holds a sample with probability `min(1, w/h)`, `h` the step — so a fraction
# `mean(1 − min(1, w/h))` should punch through (`metrics.implicit.predicted_punch_through`, with `w` the
# certified chord `t_exit − t`). That is the article's results picture: with the same step size and no
# progressive method, "一部のレイが薄い物体を突き抜け、透けて見えてしまっています".

# %%
t_far = rays.t_far
scored = ref_shell.hit & ~ref_shell.unfinished
chord = M.chord(ref_shell)
steps_list = [8, 16, 32, 64, 128, 256]
sweep = {}
for n in steps_list:
    res = fixed_step(shell, cam_shell, FixedStepParams(steps=n))
    cls, _ = M.classify(res, ref_shell)
    s_ = M.summary(res, ref_shell, cls)
    pred = float(M.predicted_punch_through(t_far / n, chord, frames=1, mask=scored)[0])
    sweep[n] = dict(cls=cls, pt=s_["punch_through_rate"], pred=pred, evals=s_["evaluations_mean"])
    print(f"N = {n:3}: punch-through {s_['punch_through_rate']:.3f} (predicted {pred:.3f}), "
          f"{s_['evaluations_mean']:.1f} evaluations per pixel")

fig = plt.figure(figsize=(15, 3.8), layout="constrained")
sub = fig.subfigures(1, 2, width_ratios=[1, 2.2])
a = sub[0].subplots()
a.plot(steps_list, [sweep[n]["pt"] for n in steps_list], "o", ms=8, label="measured")
a.plot(steps_list, [sweep[n]["pred"] for n in steps_list], "-", color="k", label="mean(1 − min(1, w/h))")
a.set_xscale("log", base=2), a.set_xlabel("N (h = t_far/N)"), a.set_ylabel("punch-through rate (of shell pixels)")
a.legend(fontsize=8), a.set_title("thin shell, fixed step", fontsize=9)
maps = sub[1].subplots(1, 3)
for m_, n in zip(maps, (16, 64, 256)):
    m_.imshow(class_rgb(sweep[n]["cls"]), interpolation="nearest")
    m_.set_title(f"N = {n}: {sweep[n]['pt']:.0%} punch through", fontsize=9)
bare(*maps)
class_legend(maps[0], [M.CORRECT, M.PUNCH_THROUGH, M.TRUE_MISS], loc="lower left")
fig.suptitle("Step 4 — the thin shell seen through itself: punch-through against the step count")
plt.show()
check("at N = 32 most thin-shell pixels punch through (> 70 %)", sweep[32]["pt"] > 0.7)
check("the measured rate follows mean(1 − min(1, w/h)) within 0.06 at every N",
      all(abs(sweep[n]["pt"] - sweep[n]["pred"]) < 0.06 for n in steps_list))
check("eight times the steps (32 → 256) cut the punch-through rate by more than half",
      sweep[256]["pt"] < 0.5 * sweep[32]["pt"])

# %% [markdown]
# ## 5. Sphere tracing, and over-relaxation (背景: 距離場によるレイマーチング, Fig. 05)
#
# The article's alternative picks each step from the field itself. If `λ ≥ |∇f|` everywhere (a Lipschitz
# bound; λ = 1 for a true distance), then no surface lies within `|f(p)|/λ` of `p`, and
#
# ```
# t_{i+1} = t_i + |f(s + t_i·d)| / λ          stop when |f|/λ < ε·t
# ```
#
# never steps over it (Hart 1996). Below, the costliest ray of the torus's centre column (`R = 1, r = 0.35`,
# λ = 1, the vertical plane through the camera) is traced by hand and compared with `sphere_trace`: it grazes
# the near tube, then the far one, and leaves. The circles are the unbounding spheres of Fig. 05: the steps
# shrink wherever the ray passes close to the surface, hit or not — the cost is in the grazing rays, as the
# step-count maps of the ball over the slab show (the silhouette ring, the floor seen at a low angle). Keinert et al.'s
# **over-relaxation** steps `ω·|f|/λ` and falls back to ω = 1 for the rest of the ray as soon as two
# consecutive spheres stop overlapping.

# %%
sc_tor, torus, cam_t = scene_at("torus")
cam_odd = cam_t.with_resolution(W + 1, H)                        # an odd width: the centre column is the plane x = 0
rays_odd = camera_rays(cam_odd, dtype=torch.float64)
st_odd = sphere_trace(torus, rays_odd, SphereTraceParams())
col = W // 2                                                   # the centre column of the W + 1 wide image
px_t = col
py_t = int(st_odd.steps[0, 0, :, col].argmax())                 # the costliest ray of that column

o, d = rays_odd.origin[0, :, py_t, px_t], rays_odd.direction[0, :, py_t, px_t]
t_near, t_far1 = float(rays_odd.t_near[0, 0, py_t, px_t]), float(rays_odd.t_far[0, 0, py_t, px_t])
lam, eps = 1.0, SphereTraceParams().epsilon
f_t = lambda t: float(torus.f((o + t * d)[None]))             # noqa: E731
t, f, path = 0.0, f_t(0.0), []
while True:                                                    # Hart's loop, one ray
    path.append((t, f))
    if abs(f) / lam < eps * max(t, t_near):
        hand_hit = True                                        # close enough: a hit
        break
    if t >= t_far1:
        hand_hit = False                                       # past the far plane: a miss
        break
    t = min(t + abs(f) / lam, t_far1)                          # the unbounding-sphere step
    f = f_t(t)
print(f"torus ray ({px_t}, {py_t}): by hand {'hit' if hand_hit else 'miss'} after {len(path) - 1} steps, t = "
      f"{t:.6f}; sphere_trace {'hit' if bool(st_odd.hit[0, 0, py_t, px_t]) else 'miss'} after "
      f"{int(st_odd.steps[0, 0, py_t, px_t])} steps, t = {float(st_odd.t[0, 0, py_t, px_t]):.6f}")
check("the hand sphere trace agrees with sphere_trace (hit or miss, same steps, t to 1e-12)",
      hand_hit == bool(st_odd.hit[0, 0, py_t, px_t]) and len(path) - 1 == int(st_odd.steps[0, 0, py_t, px_t])
      and abs(t - float(st_odd.t[0, 0, py_t, px_t])) < 1e-12)
check("this grazing ray costs more than twice the steps of the median ray of the image",
      len(path) - 1 > 2 * float(st_odd.steps.double().median()))

sc_anim, anim, cam_a = scene_at("animated")                     # frame 0: a ball above a wide slab
omegas = [1.0, 1.1, 1.2, 1.3, 1.5, 1.8]
relaxed = {w_: sphere_trace(anim, cam_a, SphereTraceParams(omega=w_)) for w_ in omegas}
mean_steps = {w_: float(relaxed[w_].steps.double().mean()) for w_ in omegas}
print("mean steps per pixel:", {w_: round(v, 2) for w_, v in mean_steps.items()})

fig, ax = plt.subplots(1, 4, figsize=(17, 3.7), layout="constrained", width_ratios=[1.25, 1, 1, 0.9])
pts = np.array([(o + tp * d).numpy() for tp, _ in path])
ys_ = np.linspace(min(-0.7, pts[:, 1].min() - 0.2), 2.3, 241)
zs_ = np.linspace(min(-1.8, pts[:, 2].min() - 0.2), 4.1, 471)
Z_, Y_ = np.meshgrid(zs_, ys_)
slice_ = torus.f(torch.tensor(np.stack([np.zeros_like(Z_), Y_, Z_], -1))).numpy()
ax[0].contourf(zs_, ys_, slice_ < 0, [0.5, 1.5], colors=["0.4"])
for (tp, fp), q_ in zip(path, pts):
    ax[0].add_patch(Circle((q_[2], q_[1]), abs(fp) / lam, fill=False, color="C0", lw=0.7))
ax[0].plot(pts[:, 2], pts[:, 1], ".-", color="C3", ms=4, lw=0.8)
ax[0].set_aspect("equal"), ax[0].set_xlim(zs_[0], zs_[-1]), ax[0].set_ylim(ys_[0], ys_[-1])
ax[0].set_xlabel("z"), ax[0].set_ylabel("y")
ax[0].set_title(f"torus, plane x = 0: a grazing ray, {len(path) - 1} steps\n(circles: unbounding spheres, Fig. 05)",
                fontsize=9)
vmax = float(relaxed[1.0].steps.max())
for a, w_ in ((ax[1], 1.0), (ax[2], 1.2)):
    im = a.imshow(relaxed[w_].steps[0, 0], cmap="inferno", vmin=0, vmax=vmax)
    a.set_title(f"ω = {w_}: steps per pixel, mean {mean_steps[w_]:.1f}", fontsize=9)
bare(ax[1], ax[2])
fig.colorbar(im, ax=ax[2], shrink=0.8, label="steps")
ax[3].plot(omegas, [mean_steps[w_] for w_ in omegas], "o-")
ax[3].set_xlabel("ω"), ax[3].set_ylabel("mean steps per pixel"), ax[3].set_title("ball over slab", fontsize=9)
fig.suptitle("Step 5 — sphere tracing: safe steps from |f|/λ; the cost is in grazing rays (Fig. 05)")
plt.show()
falls = {w_: float((relaxed[w_].debug["fallbacks"] > 0).double().mean()) for w_ in omegas}
print("share of rays that fell back to ω = 1:", {w_: round(v, 2) for w_, v in falls.items()})
check("ω = 1.2 saves steps on the ball over the slab (long grazing rays over the floor)",
      mean_steps[1.2] < 0.95 * mean_steps[1.0])
check("a large ω falls back on most rays and saves less than ω = 1.2", mean_steps[1.8] > mean_steps[1.2]
      and falls[1.8] > 0.5)
check("over-relaxation changes the cost, not the image: the same pixels hit for every ω",
      all(torch.equal(relaxed[w_].hit, relaxed[1.0].hit) for w_ in omegas))

# %% [markdown]
# ## 6. When λ is wrong (背景, after Fig. 05: "適切なステップサイズの上界を決定できないことあります")
#
# The guarantee is only as good as λ. The article's objection: when the user types `f`, nobody knows a bound.
# Two catalog cases:
#
# * `displaced_torus` adds bumps `0.045·sin 20x·sin 20y·sin 20z` to the torus but still *declares* λ = 1.
#   `metrics.implicit.lipschitz_check` samples `|∇f|` (autograd, points pulled onto the surface) and finds
#   about 1.9: steps of `|f|` can land **inside**. `sphere_trace` notices the sign change, flags the pixel
#   (`debug["overshoot"]`) and bisects back, so here the image survives;
# * `badly_scaled` is the unit sphere written `1000(x² + y² + z² − 1)`: `|∇f| = 2000‖p‖` has no global bound.
#   With λ = 1 the first step from the eye is 16 000 long — past the far plane — and **every** ray punches
#   through. With λ set to the largest `|∇f|` inside the object's box the steps are still too long where the
#   ray starts (‖p‖ ≈ 4): they land inside (caught and bisected) or beyond the sphere at its silhouette (holes).

# %%
sc_dt, dtorus, cam_d = scene_at("displaced_torus")
lc = M.lipschitz_check(dtorus, 20_000, torch.Generator().manual_seed(0))
ref_dt = certified(dtorus, cam_d)
st_wrong = sphere_trace(dtorus, cam_d, SphereTraceParams())               # the declared λ = 1
st_safe = sphere_trace(dtorus, cam_d, SphereTraceParams(lipschitz=2.0))   # a true bound
cls_wrong, _ = M.classify(st_wrong, ref_dt)
n_over = int(st_wrong.debug["overshoot"].sum())
print(f"displaced torus: declared λ = {lc['declared']}, observed max |∇f| = {lc['observed_max_grad']:.3f}; "
      f"overshoot on {n_over} pixels with λ = 1, {int(st_safe.debug['overshoot'].sum())} with λ = 2; mean steps "
      f"{float(st_wrong.steps.double().mean()):.1f} vs {float(st_safe.steps.double().mean()):.1f}")
check("lipschitz_check finds the declared λ = 1 violated (observed > 1.5)",
      lc["overshoot"] and lc["observed_max_grad"] > 1.5)
check("with the wrong λ some steps land inside (overshoot), with λ = 2 none do",
      n_over > 0 and not bool(st_safe.debug["overshoot"].any()))
check("the overshooting pixels are bisected back to the first root (all classified correct)",
      bool((cls_wrong[st_wrong.debug["overshoot"]] == M.CORRECT).all()))

sc_bs, bsphere, cam_b = scene_at("badly_scaled")
truth_bs = analytic_sphere(cam_b, (0, 0, 0), 1.0)               # it is the unit sphere: the exact answer
lc_bs = M.lipschitz_check(bsphere, 20_000, torch.Generator().manual_seed(0))
bs = {}
lam_box = lc_bs["observed_max_grad"]
for name, lam_ in (("λ = 1", 1.0), (f"λ = {lam_box:.0f} (max in its box)", lam_box)):
    res = sphere_trace(bsphere, cam_b, SphereTraceParams(lipschitz=lam_))
    good = res.hit & truth_bs.hit & ((res.t - truth_bs.t).abs() < 1e-3 * truth_bs.t)
    bs[name] = (res, good, 1 - float(good.sum()) / float(truth_bs.hit.sum()))
    print(f"badly scaled, {name}: {int(res.hit.sum())} hits, {bs[name][2]:.0%} of the sphere's pixels lost")

fig, ax = plt.subplots(1, 4, figsize=(17, 3.5), layout="constrained")
ax[0].imshow(class_rgb(cls_wrong), interpolation="nearest")
ov = st_wrong.debug["overshoot"][0, 0].numpy()
ax[0].contour(ov, [0.5], colors="k", linewidths=0.8)
ax[0].set_title(f"displaced torus, λ = 1: classes;\nblack outline: {n_over} overshoot pixels (bisected back)",
                fontsize=9)
class_legend(ax[0], [M.CORRECT, M.EARLY_HIT, M.FALSE_HIT], loc="lower left")
box_lo, box_hi = (torch.tensor(b_, dtype=torch.float64) for b_ in dtorus.bounds)
pts = box_lo + (box_hi - box_lo) * torch.rand(4000, 3, generator=torch.Generator().manual_seed(1), dtype=torch.float64)
ax[1].hist(dtorus.f_and_grad(pts)[1].norm(dim=-1).numpy(), bins=40, color="C0")
ax[1].axvline(1.0, color="r", label="declared λ = 1")
ax[1].axvline(lc["observed_max_grad"], color="k", ls="--", label=f"observed max {lc['observed_max_grad']:.2f}")
ax[1].set_xlabel("|∇f| at random points in the box"), ax[1].legend(fontsize=8)
ax[1].set_title("lipschitz_check: POV-Ray's 'max_gradient found'", fontsize=9)
for a, (name, (res, good, lost)) in zip(ax[2:], bs.items()):
    img = np.zeros((H, W, 3))
    img[truth_bs.hit[0, 0].numpy()] = M.CLASS_COLORS[M.PUNCH_THROUGH]
    img[good[0, 0].numpy()] = M.CLASS_COLORS[M.CORRECT]
    a.imshow(img, interpolation="nearest"), a.set_title(f"badly scaled, {name}:\n{lost:.0%} punch through",
                                                       fontsize=9)
bare(ax[0], ax[2], ax[3])
fig.suptitle("Step 6 — a wrong λ: overshoot (displaced torus) and holes (badly scaled sphere)")
plt.show()
check("badly scaled with λ = 1: every sphere pixel punches through", list(bs.values())[0][2] == 1.0)
check("with λ = max |∇f| in its box, holes remain (> 5 %) but most pixels are found",
      0.05 < list(bs.values())[1][2] < 0.5)

# %% [markdown]
# ## 7. A root with no sign change: `(‖p‖ − 1)²` (手法: レイキャスティング, the hit test)
#
# The article's hit test is a sign change, `f_t(t_i) ≥ 0 > f_t(t_{i+1})`. The catalog's `double_root` is the
# unit sphere squared: `f ≥ 0` everywhere, touching 0 on the sphere. No step count helps a sign-change
# method: it never sees the surface. Sphere tracing (with any λ; here 8, a bound near the object) creeps toward
# it ever more slowly — `|f|/λ = δ²/λ` at distance δ — and stops on its `ε` test: a hit that the certified
# reference scores as a *false hit*, because it defines a hit by a sign change too. Interval arithmetic sees
# what is there: it cannot exclude 0 near the sphere, so it reports an **ambiguous** stretch (`ambiguous_t`).

# %%
sc_dr, droot, cam_r = scene_at("double_root")
ref_dr = certified(droot, cam_r)
disc_truth = analytic_sphere(cam_r, (0, 0, 0), 1.0)            # where the double root is
fixed_dr = {n: fixed_step(droot, cam_r, FixedStepParams(steps=n)) for n in (32, 256, 2048)}
st_dr = sphere_trace(droot, cam_r, SphereTraceParams(lipschitz=8.0))
cls_dr, _ = M.classify(st_dr, ref_dr)
sum_dr = M.summary(st_dr, ref_dr, cls_dr)
amb = torch.isfinite(ref_dr.ambiguous_t)
print(f"fixed step hits: {[int(r_.hit.sum()) for r_ in fixed_dr.values()]} (N = 32, 256, 2048); sphere tracing: "
      f"{int(sum_dr['n_false_hit'])} false hits, {int((st_dr.termination == OUT_OF_STEPS).sum())} out of steps, "
      f"mean {float(st_dr.steps.double().mean()):.0f} steps; reference: {int(ref_dr.hit.sum())} hits, "
      f"{int(amb.sum())} ambiguous")
check("fixed step never hits the double root, at any N", all(int(r_.hit.sum()) == 0 for r_ in fixed_dr.values()))
check("the certified reference reports no hit, but an ambiguous stretch on exactly the sphere's pixels",
      int(ref_dr.hit.sum()) == 0 and torch.equal(amb, disc_truth.hit))
check("the ambiguous stretch starts at the sphere (within 1e-5)",
      float((ref_dr.ambiguous_t - disc_truth.t).abs()[amb].max()) < 1e-5)
check("sphere tracing 'finds' it: all its hits are false hits sitting on the ambiguous root",
      sum_dr["n_false_hit"] > 0 and sum_dr["false_hit_ambiguous"] == 1.0)

pyc, pxc = near_centre(disc_truth.hit[0, 0])[::-1]
rays_r = camera_rays(cam_r, dtype=torch.float64)
o, d = rays_r.origin[0, :, pyc, pxc], rays_r.direction[0, :, pyc, pxc]
tt = torch.linspace(2.0, 6.5, 2000, dtype=torch.float64)
fig, ax = plt.subplots(1, 4, figsize=(17, 3.4), layout="constrained", width_ratios=[1.2, 1, 1, 1])
ax[0].plot(tt, droot.f(o + tt[:, None] * d), "k-")
ax[0].axhline(0, color="gray", lw=0.8)
ax[0].set_ylim(-0.2, 2), ax[0].set_xlabel("t"), ax[0].set_ylabel("f_t(t)")
ax[0].set_title("(‖p‖−1)² along the centre ray: touches 0, never crosses", fontsize=9)
ax[1].imshow(fixed_dr[2048].hit[0, 0], cmap="gray", vmin=0, vmax=1)
ax[1].set_title("fixed step, N = 2048: hits (none)", fontsize=9)
ax[2].imshow(class_rgb(cls_dr), interpolation="nearest")
ax[2].set_title(f"sphere tracing λ = 8: {int(sum_dr['n_false_hit'])} false hits", fontsize=9)
class_legend(ax[2], [M.FALSE_HIT, M.TRUE_MISS], loc="lower left")
ax[3].imshow(torch.where(amb, ref_dr.ambiguous_t, torch.nan)[0, 0], cmap="viridis")
ax[3].set_title("certified reference: ambiguous_t (no hit)", fontsize=9)
bare(*ax[1:])
fig.suptitle("Step 7 — the double root: invisible to sign changes, 'found' by sphere tracing, flagged by intervals")
plt.show()

# %% [markdown]
# ## 8. Interval arithmetic and the certified reference (背景: interval arithmetic; Mitchell 1990, Knoll 2009)
#
# The article's last option: evaluate `f` on a whole **box** and get an interval `[lo, hi]` guaranteed to
# contain every value of `f` there. If it excludes 0, the box holds no surface and the ray can skip it —
# safe for any formula, with no λ. The article's three objections are all visible here: it is more work
# per evaluation, it needs an interval version of every operation, and it **over-estimates** (過大評価).
#
# First, `x² + y² + z² − 1` on one box by hand (a square's range is `[0, max(a², b²)]` when the box
# straddles 0, else monotone), against `Expression.interval`, which also rounds each bound outward.

# %%
ball = parse("x^2 + y^2 + z^2 - 1")
lo_box = torch.tensor([[-0.3, 0.2, 0.5], [0.9, -1.2, -0.1]], dtype=torch.float64)
hi_box = torch.tensor([[0.4, 0.6, 0.8], [1.1, -0.7, 0.1]], dtype=torch.float64)
sq_lo = torch.where((lo_box <= 0) & (hi_box >= 0), 0.0, torch.minimum(lo_box ** 2, hi_box ** 2))
sq_hi = torch.maximum(lo_box ** 2, hi_box ** 2)
hand_lo, hand_hi = sq_lo.sum(-1) - 1, sq_hi.sum(-1) - 1
lib_lo, lib_hi = ball.interval(lo_box, hi_box)
print("by hand:", hand_lo.tolist(), hand_hi.tolist(), "\nlibrary:", lib_lo.tolist(), lib_hi.tolist())
check("the library's enclosure contains the hand-derived one and is at most 1e-12 wider",
      bool(((lib_lo <= hand_lo) & (lib_hi >= hand_hi)).all())
      and float(torch.cat([hand_lo - lib_lo, lib_hi - hand_hi]).max()) < 1e-12)

# %% [markdown]
# A box the enclosure cannot decide is split. On the plane `z = 0` the torus's tubes need few undecided boxes;
# the gyroid sheet (`sin kx·cos ky + …`, k = 8) needs many more, and shrinking the box does not cure it: the
# three terms share variables, each term's range is taken as independent, so the sum's enclosure stays about a
# fifth wider than its range (sampled on a 5³ grid, corners included) however small the box — the
# **dependency problem**. For `length(p) − 1` the enclosure *is* the exact range (nearest point to nearest
# corner), ratio 1.

# %%
def quadtree(surface, extent, levels):
    """Split undecided squares of the plane z = 0 level by level (a loop over levels, not pixels)."""
    lo = torch.tensor([[-extent, -extent, 0.0]], dtype=torch.float64)
    side, decided = 2 * extent, []
    for level in range(levels):
        flo, fhi = surface.interval(lo, lo + torch.tensor([side, side, 0.0], dtype=torch.float64))
        undecided = ~((flo > 0) | (fhi < 0))                     # NaN bounds count as undecided
        decided.append((lo[~undecided], side, flo[~undecided] > 0))
        if level == levels - 1:
            return decided, lo[undecided], side
        side /= 2
        kids = torch.tensor([[0, 0, 0], [side, 0, 0], [0, side, 0], [side, side, 0]], dtype=torch.float64)
        lo = (lo[undecided][:, None, :] + kids[None]).reshape(-1, 3)


def sampled_range(expr, lo, hi, n=5):
    """f on a grid of n³ points of each box, corners included; its min/max bound the true range from inside."""
    g1 = torch.linspace(0, 1, n, dtype=torch.float64)
    grid = torch.stack(torch.meshgrid(g1, g1, g1, indexing="ij"), -1).reshape(-1, 3)
    v = expr(lo[:, None, :] + grid[None] * (hi - lo)[:, None, :])
    return v.amin(1), v.amax(1), v


def distance_range(lo, hi):
    """The exact range of ‖p‖ − 1 on boxes: the nearest point (clamp 0 into the box) and the farthest corner."""
    near = torch.zeros_like(lo).clamp(lo, hi).norm(dim=-1)
    far = torch.maximum(lo.abs(), hi.abs()).norm(dim=-1)
    return near - 1, far - 1


gyroid = parse("sin(k*x)*cos(k*y) + sin(k*y)*cos(k*z) + sin(k*z)*cos(k*x)", params={"k": 8.0})
dist = parse("length(p) - 1")
gen = torch.Generator().manual_seed(0)
deltas = [0.4, 0.1, 0.025, 0.00625]
ratio, sound = {"length(p) − 1": [], "gyroid": []}, True
for name, expr in (("length(p) − 1", dist), ("gyroid", gyroid)):
    for delta in deltas:
        centre = (torch.rand(300, 3, generator=gen, dtype=torch.float64) - 0.5) * 1.6
        lo, hi = centre - delta / 2, centre + delta / 2
        flo, fhi = expr.interval(lo, hi)
        vmin, vmax, v = sampled_range(expr, lo, hi)
        sound &= bool(((v >= flo[:, None]) & (v <= fhi[:, None])).all())
        if expr is dist:
            vmin, vmax = distance_range(lo, hi)
        ratio[name].append(float(((fhi - flo) / (vmax - vmin)).median()))
print("median enclosure width / range (exact for the distance, sampled for the gyroid):",
      {k: [round(x, 3) for x in v] for k, v in ratio.items()})
check("every sampled value lies inside its box's enclosure (soundness, 2400 boxes × 125 points)", sound)
check("length(p) − 1: the enclosure is the exact range (ratio 1 to 1e-6)",
      all(abs(x - 1) < 1e-6 for x in ratio["length(p) − 1"]))
check("gyroid: over-estimated by > 15 % even on the smallest boxes (dependency problem)",
      min(ratio["gyroid"]) > 1.15)

fig, ax = plt.subplots(1, 3, figsize=(15, 4.4), layout="constrained", width_ratios=[1, 1, 0.9])
for a, name in ((ax[0], "torus"), (ax[1], "gyroid_sheet")):
    decided, undecided, side = quadtree(load(name).surface(0), 1.5, 8)
    for lo_, s_, pos in decided:
        for (x0, y0, _), p_ in zip(lo_.tolist(), pos.tolist()):
            a.add_patch(Rectangle((x0, y0), s_, s_, fc="0.92" if p_ else "0.55", ec="0.75", lw=0.2))
    for x0, y0, _ in undecided.tolist():
        a.add_patch(Rectangle((x0, y0), side, side, fc="C3", ec="none"))
    a.set_xlim(-1.5, 1.5), a.set_ylim(-1.5, 1.5), a.set_aspect("equal"), bare(a)
    a.set_title(f"{name}, z = 0: {len(undecided)} undecided boxes at side {side:.3f}\n"
                "(light: f > 0 proved, dark: f < 0 proved, red: undecided)", fontsize=9)
    if name == "gyroid_sheet":
        n_gyroid_undecided = len(undecided)
    else:
        n_torus_undecided = len(undecided)
for name, vals in ratio.items():
    ax[2].plot(deltas, vals, "o-", label=name)
ax[2].set_xscale("log"), ax[2].set_xlabel("box side"), ax[2].set_ylabel("enclosure width / range")
ax[2].axhline(1, color="gray", lw=0.8), ax[2].legend(fontsize=8)
ax[2].set_title("over-estimation does not shrink with the box", fontsize=9)
fig.suptitle("Step 8a — interval arithmetic: proved-empty boxes, undecided boxes, and over-estimation")
plt.show()
check("the gyroid sheet leaves more undecided boxes than the torus", n_gyroid_undecided > 2 * n_torus_undecided)

# %% [markdown]
# The certified reference (`ssbench.reference.implicit`) marches every ray with such boxes — around each
# segment of the ray — doubling the segment while the enclosure excludes 0 and halving it where it cannot,
# until a segment is a *leaf* (`1e-7·t` long) whose end-point signs decide; the first entering sign change is
# then bisected to `1e-12`. A dense march with 10 000 uniform samples per ray (Dr.Jit when available) is the
# independent cross-check: same hits, same depths to within its sample spacing. The price: dozens of interval
# evaluations per pixel, each several times a point evaluation — against 33 points for 32 fixed steps. The
# reference pays it as one Dr.Jit kernel (`engine="drjit"`, the default for parsed surfaces: every ray applies
# the rules one segment at a time inside one compiled loop); `engine="torch"` runs the same rules lock-step
# over all rays, one batch of torch operations per step — the same hits and certificates, at tens of times the
# cost (the cell below times both).

# %%
dm = dense_march(shell, cam_shell, steps=10_000)
spacing = (dm.t_end - dm.t_start) / dm.steps
agree_hit = torch.equal(dm.hit, ref_shell.hit)
inside = ref_shell.hit & (ref_shell.t >= dm.t_lo - 1e-9) & (ref_shell.t <= dm.t_hi + 1e-9)
print(f"thin shell: certified {float(ref_shell.certified.double().mean()):.1%} of pixels; dense march "
      f"({dm.backend}, {dm.seconds:.1f} s) agrees on hits: {agree_hit}; mean evaluations per pixel: reference "
      f"{float(ref_shell.interval_evaluations.double().mean()):.0f} interval + "
      f"{float(ref_shell.point_evaluations.double().mean()):.0f} point, fixed N=32 "
      f"{float(fx32.evaluations.double().mean()):.0f} point")
check("the certified reference and a 10 000-step dense march agree on every pixel's hit", agree_hit)
check("and every certified root lies in the dense march's bracket", torch.equal(inside, ref_shell.hit))
check("every pixel of the thin shell is certified", bool(ref_shell.certified.all()))
by_torch = certified(shell, cam_shell, exits=True, engine="torch", use_cache=False)
print(f"engines: {ref_shell.engine} {ref_shell.seconds:.3f} s (its first call compiles the kernel), torch "
      f"{by_torch.seconds:.3f} s")
check("the torch engine finds the same hits and certificates",
      torch.equal(by_torch.hit, ref_shell.hit) and torch.equal(by_torch.certified, ref_shell.certified))
check("the reference spends more evaluations per pixel than 32 fixed steps",
      float((ref_shell.interval_evaluations + ref_shell.point_evaluations).double().mean())
      > float(fx32.evaluations.double().mean()))

fig, ax = plt.subplots(1, 3, figsize=(14, 3.5), layout="constrained")
im = ax[0].imshow(torch.where(ref_shell.hit, ref_shell.t, torch.nan)[0, 0], cmap="viridis")
fig.colorbar(im, ax=ax[0], shrink=0.8, label="t"), ax[0].set_title("certified first root t", fontsize=9)
im = ax[1].imshow(ref_shell.interval_evaluations[0, 0], cmap="inferno", norm=LogNorm())
fig.colorbar(im, ax=ax[1], shrink=0.8), ax[1].set_title("interval evaluations per pixel", fontsize=9)
im = ax[2].imshow(torch.where(ref_shell.hit, chord, torch.nan)[0, 0], cmap="cividis", norm=LogNorm())
fig.colorbar(im, ax=ax[2], shrink=0.8, label="w")
ax[2].set_title("chord w = t_exit − t of the first wall (exits=True)", fontsize=9)
bare(*ax)
fig.suptitle("Step 8b — the certified reference on the thin shell: depth, cost, and the chord w of Step 4")
plt.show()

# %% [markdown]
# Every method in this lesson needs something the article's user cannot give — a closed form, a step shorter
# than every wall, a true λ, or the patience of interval arithmetic. Lesson 8 keeps the cheap fixed step and
# spends **frames** instead: the article's progressive method.
#
# ## Checks

# %%
for name, ok in checks.items():
    print(("PASS " if ok else "FAIL ") + name)
assert checks and all(checks.values())

# %% [markdown]
# ## See also
#
# * `ssbench/implicit/parser.py` (the whitelist grammar and its limits), `implicit/interval.py` (every interval
#   rule, NaN semantics, outward rounding), `implicit/catalog.py` (the hard cases and why each is hard).
# * `ssbench/passes/implicit/analytic.py`, `fixed.py`, `sphere.py` (module docstrings:
#   overshoot handling, Keinert's fallback); `ssbench/reference/implicit.py` (root isolation, `certified`,
#   `ambiguous_t`) and `implicit_dense.py`; `ssbench/metrics/implicit.py` (classes, `lipschitz_check`, the `w/h`
#   prediction).
# * `ssbench implicit thin_shell --method fixed --steps 32 --frames 1` for one tidy row;
#   `ssbench/REFERENCES.md` for Hart (sphere tracing), Keinert et al. (enhanced sphere tracing), Mitchell and
#   Knoll et al. (interval arithmetic).
# * Next: **lesson 8**, the progressive method.
