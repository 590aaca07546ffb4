"""Property-based fuzzing of every screen-space pass, with hypothesis.

Each pass gets :data:`EXAMPLES` generated G-buffers: depths anywhere from before the near plane to 1e30 beyond
the far one, NaN/±inf/0/positive depths, zero, unnormalised, NaN and grazing normals, background everywhere or
nowhere, scales ×1e-3 and ×1e3, near/far ratios from 1.001 to 1e9 (near from 1e-9), float16/bfloat16/float32/
float64, batch 1 or 2, non-contiguous tensors and the meta device. The contract
(``ssbench/RELIABILITY.md``):

* a G-buffer that meets the input contract (checked here independently of the passes' own checks) gives
  finite outputs in their documented ranges;
* any other G-buffer gives a ``ValueError``/``TypeError`` whose message starts with the channel's name;
* nothing else escapes: no ``IndexError``/``RuntimeError`` from inside torch, no NaN.

``derandomize=True``: the same examples on every run (the suite is deterministic, like the rest of make test).
"""
from __future__ import annotations

import math

import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ssbench.camera import Camera
from ssbench.gbuffer import CHANNELS, GBuffer
from ssbench.passes import AO_METHODS, SSR_METHODS, ao_method, ssr_method
from ssbench.passes.gbuffer_checks import normal_tolerance
from ssbench.passes.ssr.common import HIT

EXAMPLES = 500
AO = tuple(AO_METHODS)                                            # every declared method
SSR = tuple(SSR_METHODS)
DTYPES = (torch.float16, torch.bfloat16, torch.float32, torch.float64)
Z_BAD = ("nan", "inf", "-inf", "zero", "positive")
Z_ODD = ("beyond_far", "huge", "before_near", "tiny")          # legal: finite and < 0
N_BAD = ("zero", "scaled", "nan")
N_ODD = ("grazing", "away")                                     # legal: unit length
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@st.composite
def frames(draw):
    """A (GBuffer, description) pair; the description is what the failure report prints."""
    seed = draw(st.integers(0, 2 ** 31 - 1))
    g = torch.Generator().manual_seed(seed)
    H, W = draw(st.sampled_from([(6, 8), (9, 12), (12, 16)]))
    B = draw(st.sampled_from([1, 2]))
    dtype = draw(st.sampled_from(DTYPES))
    scale = draw(st.sampled_from([1e-3, 1.0, 1e3]))
    near = draw(st.sampled_from([1e-9, 1e-6, 1e-3, 0.1, 1.0])) * scale
    far = near * draw(st.sampled_from([1.001, 10.0, 1e3, 1e6, 1e9]))
    cam = Camera.from_look_at((0.0, scale, 2 * scale), (0.0, 0.0, -scale), (0.0, 1.0, 0.0),
                              draw(st.sampled_from([20.0, 60.0, 120.0])), W, H, near, far)
    cover = draw(st.sampled_from([0.0, 0.5, 0.9, 1.0]))
    mask = torch.rand(B, 1, H, W, generator=g) < cover
    u = torch.rand(B, 1, H, W, generator=g, dtype=torch.float64)
    z = -(near + (far - near) * u ** 3)                          # more samples near the camera
    z = torch.where(mask, z, torch.full_like(z, -far))
    # normals: random unit vectors facing the camera (n_z > 0 in view space)
    n = torch.randn(B, 3, H, W, generator=g, dtype=torch.float64)
    n[:, 2] = n[:, 2].abs() + 0.05
    n = n / n.norm(dim=1, keepdim=True)
    n = torch.where(mask, n, torch.zeros_like(n))
    color = torch.rand(B, 3, H, W, generator=g, dtype=torch.float64) * mask
    where = lambda p: mask & (torch.rand(B, 1, H, W, generator=g) < p)      # noqa: E731  some geometry pixels
    z_kind = draw(st.sampled_from(("none",) * 4 + Z_ODD + Z_BAD))
    sel = where(0.3)
    z = {"nan": lambda: torch.where(sel, math.nan, z), "inf": lambda: torch.where(sel, math.inf, z),
         "-inf": lambda: torch.where(sel, -math.inf, z), "zero": lambda: torch.where(sel, 0.0, z),
         "positive": lambda: torch.where(sel, -z, z), "beyond_far": lambda: torch.where(sel, 2 * z - far, z),
         "huge": lambda: torch.where(sel, -1e30, z), "before_near": lambda: torch.where(sel, -0.5 * near, z),
         "tiny": lambda: torch.where(sel, -1e-30, z), "none": lambda: z}[z_kind]()
    n_kind = draw(st.sampled_from(("none",) * 3 + N_ODD + N_BAD))
    sel = where(0.3)
    if n_kind == "zero":
        n = torch.where(sel, 0.0, n)
    elif n_kind == "scaled":
        n = torch.where(sel, 2.0 * n, n)
    elif n_kind == "nan":
        n = torch.where(sel, math.nan, n)
    elif n_kind in ("grazing", "away"):                           # perpendicular to the view ray / facing away
        ray = cam.pixel_rays(torch.float64)[None].expand(B, -1, -1, -1)
        ray = ray / ray.norm(dim=1, keepdim=True)
        t = torch.cross(ray, torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64).view(1, 3, 1, 1).expand_as(ray), 1)
        t = t / t.norm(dim=1, keepdim=True).clamp_min(1e-12)
        alt = t if n_kind == "grazing" else -ray
        n = torch.where(sel, alt, n)
    if draw(st.integers(0, 4)) == 4:                              # (hypothesis leans to small integers)
        color = torch.where(where(0.2), math.nan, color)
    rough = torch.rand(B, 1, H, W, generator=g, dtype=torch.float64) * draw(st.sampled_from((0.0, 0.3, 1.0)))
    if draw(st.integers(0, 6)) == 6:
        rough = torch.where(where(0.2), math.nan, rough)
    chans = {"view_z": z, "normal": n, "mask": mask, "color": color, "roughness": rough * mask,
             "position": cam.uv_to_view(cam.uv_grid(torch.float64)[None], z.nan_to_num(-far, -far, -far)),
             "back_z": torch.where(mask, z - 0.1 * scale, -math.inf)}
    chans = {k: (v if k == "mask" else v.to(dtype)) for k, v in chans.items()}
    if draw(st.booleans()):                                       # non-contiguous (W-major storage)
        chans = {k: v.transpose(-1, -2).contiguous().transpose(-1, -2) for k, v in chans.items()}
    meta = draw(st.integers(0, 19)) == 19
    if meta:
        chans = {k: v.to("meta") for k, v in chans.items()}
    desc = dict(seed=seed, size=(B, H, W), dtype=str(dtype), scale=scale, near=near, far=far, cover=cover,
                z=z_kind, n=n_kind, meta=meta, contiguous=chans["view_z"].is_contiguous())
    return GBuffer(cam, **chans), desc


def meets_contract(g: GBuffer, requires, finite=()) -> bool:
    """The input contract, checked independently of ``ssbench.passes.gbuffer_checks``."""
    z, m = g.view_z.double(), g.mask
    if not bool(torch.isfinite(z).all()) or bool((z[m] >= 0).any()):
        return False
    if "normal" in requires:
        nl = g.normal.double().norm(dim=1, keepdim=True)
        if bool((m & ~((nl - 1).abs() <= normal_tolerance(g.normal.dtype))).any()):
            return False
    return not any(bool(torch.isnan(getattr(g, c)).any()) for c in finite)


def _names_a_channel(e: Exception) -> bool:
    head = str(e).split(":", 1)[0]
    return head in CHANNELS or head in ("gbuffer", "params")


def _run(method, fn, P, g, desc, requires, finite, check_output):
    g = g.select(tuple(sorted(set(requires) | {"mask"})))
    finite = tuple(c for c in finite if c in requires)
    try:
        out = fn(g, P())
    except (ValueError, TypeError) as e:
        assert _names_a_channel(e), (desc, repr(e))
        assert desc["meta"] or not meets_contract(g, requires, finite), (desc, f"a valid input refused: {e}")
        return "refused"
    if desc["meta"]:
        return "meta"
    assert meets_contract(g, requires, finite), (desc, "an input outside the contract was accepted")
    check_output(out, g, desc)
    return "ran"


def _ao_output(out, g, desc):
    ao = out.ao.double()
    assert ao.shape == (g.batch_size, 1, g.height, g.width) and out.ao.dtype == g.view_z.dtype, desc
    assert bool(torch.isfinite(ao).all()), (desc, "AO not finite")
    assert bool(((ao >= 0) & (ao <= 1)).all()), (desc, "AO outside [0, 1]")
    if out.bent_normal is not None:
        assert bool(torch.isfinite(out.bent_normal.double()).all()), (desc, "bent normal not finite")


def _ssr_output(out, g, desc):
    for name in ("color", "raw_color", "hit_pixel", "hit_view", "fade"):
        t = getattr(out, name).double()
        assert bool(torch.isfinite(t).all()), (desc, f"{name} not finite")
    assert bool(((out.fade.double() >= 0) & (out.fade.double() <= 1 + 1e-6)).all()), (desc, "fade outside [0, 1]")
    hit = out.termination == HIT
    assert torch.equal(hit, out.hit) and not bool((hit & ~g.mask).any()), (desc, "a hit from background")
    px = out.hit_pixel.permute(0, 2, 3, 1)[hit[:, 0]]
    b = torch.nonzero(hit[:, 0])[:, 0]
    col = px[:, 0].floor().long().clamp(0, g.width - 1)
    row = px[:, 1].floor().long().clamp(0, g.height - 1)
    assert bool(g.mask[b, 0, row, col].all()), (desc, "a hit on the cleared background")


CASES = [(m, ao_method, (), _ao_output) for m in AO] + [(m, ssr_method, ("color", "roughness"), _ssr_output)
                                                        for m in SSR]


@pytest.mark.slow
@pytest.mark.parametrize("method,resolve,finite,check_output", CASES, ids=[c[0] for c in CASES])
def test_pass_contract(method, resolve, finite, check_output):
    fn, P, requires = resolve(method)
    seen = {"refused": 0, "meta": 0, "ran": 0}

    @FUZZ
    @given(frames())
    def prop(frame):
        g, desc = frame
        seen[_run(method, fn, P, g, desc, requires, finite, check_output)] += 1
    prop()
    print(f"fuzz {method}: {seen}")
    assert sum(seen.values()) >= EXAMPLES and seen["ran"] > 0 and seen["refused"] > 0, seen
