"""Reference G-buffers: one Mitsuba ray per pixel centre (no jitter), as one vectorised Dr.Jit kernel.

Rays come from the scene's own Mitsuba sensor (``sensor.sample_ray`` at film position ``((i + ½)/W,
(j + ½)/H)``), so they start on the near plane and end at the far plane exactly like a GL rasteriser's
frustum. A hit's position is the point on *that* ray, ``ray.o + si.t · ray.d`` in float64 (``si.t`` is
measured from the near-plane origin, never used as an eye distance; ``si.p`` is rebuilt from shape-local
coordinates and can stray ~1e-6 relative off the ray), mapped to GL view space by :meth:`Camera.view_matrix`.

Only the requested channels are evaluated; Dr.Jit is lazy, so unrequested expressions cost nothing, and the
back-face search (``back_z``, up to :data:`EXIT_SEARCH` extra traces) and the second depth layer (``second_z``:
one more trace from the exit, or from the hit of an open surface) run only when asked for.
"""
from __future__ import annotations

import time
from typing import Iterable, Optional

import numpy as np
import torch

from ..camera import Camera
from ..gbuffer import CHANNELS, GBuffer
from ..scenes import Scene, load as load_scene
from . import backend, cache, convert

#: channels rendered when none are named (``back_z`` and ``color`` cost extra: ask for them)
DEFAULT_CHANNELS = ("view_z", "normal", "position", "albedo", "roughness", "metallic", "shape_id", "mask")
#: maximum number of surfaces crossed while looking for the exit through the first object
EXIT_SEARCH = 8
_KERNEL_VERSION = 6        # bump when the kernel's output changes, to invalidate caches


def _channels(channels: Optional[Iterable[str]]) -> tuple[str, ...]:
    if channels is None:
        return DEFAULT_CHANNELS
    if isinstance(channels, str):
        channels = (channels,)
    chans = tuple(dict.fromkeys(channels))
    unknown = [c for c in chans if c not in CHANNELS]
    if unknown or not chans:
        raise ValueError(f"channels: unknown or empty {list(chans)}; known: {list(CHANNELS)}")
    return chans


def resolve_camera(scene, width, height) -> tuple[Scene, Camera]:
    sc = load_scene(scene)
    w = sc.camera.width if width is None else width
    h = sc.camera.height if height is None else height
    for name, v in (("width", w), ("height", h)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v <= 0:
            raise ValueError(f"{name}: image size must be a positive integer, got {v!r}")
    return sc, sc.camera.with_resolution(int(w), int(h))


def _albedo_at_hit(sc: Scene) -> list[bool]:
    """Per shape, whether its albedo is a texture to look up at each hit (a Mitsuba file's diffuse textures)."""
    return [bool(dict(s.params).get("albedo_at_hit", False)) for s in sc.shapes]


def _trace(mi, dr, mscene, cam: Camera, want_back: bool, want_albedo: bool = False, want_second: bool = False) -> dict:
    """The kernel: arrays of length H·W (row-major, row 0 at the top)."""
    W, H = cam.width, cam.height
    sensor = mscene.sensors()[0]
    idx = dr.arange(mi.UInt32, W * H)
    ix, iy = idx % W, idx // W
    film_pos = mi.Point2f((mi.Float(ix) + 0.5) / W, (mi.Float(iy) + 0.5) / H)      # pixel centres
    ray, _ = sensor.sample_ray(time=0.0, sample1=0.0, sample2=film_pos, sample3=mi.Point2f(0.5, 0.5))
    si = mscene.ray_intersect(ray)
    hit = si.is_valid()
    V = mi.Transform4f([[float(v) for v in row] for row in cam.view_matrix().tolist()])
    dr.make_opaque(V)                            # one kernel for every camera (a literal would recompile it)
    p_view = V @ si.p
    n_view = dr.normalize(V @ mi.Vector3f(si.sh_frame.n))
    n_view = dr.select(dr.dot(n_view, mi.Vector3f(p_view)) > 0, -n_view, n_view)   # face the camera

    # ------------------------------------------------ shape ids: registry id -> scene index
    shapes = mscene.shapes()
    rids = dr.reinterpret_array(mi.UInt32, mscene.shapes_dr()).numpy()
    table = np.full(int(rids.max()) + 1, -1, dtype=np.int32)
    for rid, sh in zip(rids, shapes):
        table[int(rid)] = convert.scene_index(sh.id())
    rid_px = dr.reinterpret_array(mi.UInt32, si.shape)
    sid = dr.select(hit, dr.gather(mi.Int32, mi.Int32(table), rid_px, hit), -1)
    out = {"hit": hit, "ray_o": ray.o, "ray_d": ray.d, "t": si.t, "p_view": p_view, "n_view": n_view,
           "sid": sid}
    if want_albedo:                             # textured albedo, looked up at the hit (Mitsuba-file scenes)
        out["albedo"] = si.bsdf().eval_diffuse_reflectance(si, hit)

    if want_back or want_second:                # ------------ exit through the first object entered
        # Step along the *same* line (o + t·d): spawn_ray() would push the origin off it along the normal by
        # ~1e-4·|p|, which moves the exit of short chords by up to 1e-3 relative.
        back = dr.full(mi.Float, -dr.inf, W * H)
        active = mi.Bool(hit)
        t_acc = mi.Float(si.t)
        t_exit = dr.full(mi.Float, dr.inf, W * H)
        for _ in range(EXIT_SEARCH):
            step = 1e-4 * (t_acc + cam.near)                                  # scale-invariant nudge
            nxt = mscene.ray_intersect(mi.Ray3f(ray.o + (t_acc + step) * ray.d, ray.d), active)
            t_new = t_acc + step + nxt.t
            rid_n = dr.reinterpret_array(mi.UInt32, nxt.shape)
            sid_n = dr.gather(mi.Int32, mi.Int32(table), rid_n, active & nxt.is_valid())
            exits = active & nxt.is_valid() & (dr.dot(nxt.n, ray.d) > 0) & (sid_n == sid)
            back = dr.select(exits, (V @ mi.Point3f(ray.o + t_new * ray.d)).z, back)
            active &= nxt.is_valid() & ~exits
            t_acc = dr.select(active, t_new, t_acc)
            t_exit = dr.select(exits, t_new, t_exit)
        out["back_z"] = back
        if want_second:                         # ------------ the next surface behind it: the second layer
            start = dr.select(dr.isfinite(t_exit), t_exit, si.t)
            step = 1e-4 * (start + cam.near)
            nxt = mscene.ray_intersect(mi.Ray3f(ray.o + (start + step) * ray.d, ray.d), hit)
            out["second_z"] = dr.select(hit & nxt.is_valid(),
                                        (V @ mi.Point3f(ray.o + (start + step + nxt.t) * ray.d)).z, -dr.inf)
    return out


def _render_jit(sc: Scene, cam: Camera, chans: tuple[str, ...]) -> dict[str, np.ndarray]:
    mi = backend.mitsuba()
    import drjit as dr
    mscene = convert.load(sc, cam)
    r = _trace(mi, dr, mscene, cam, "back_z" in chans, "albedo" in chans and any(_albedo_at_hit(sc)),
               "second_z" in chans)
    H, W = cam.height, cam.width
    dr.eval(r)                                   # every channel in one kernel (one conversion each re-traced)
    # Dr.Jit -> torch by DLPack (.torch(): zero-copy for flat arrays); numpy views of those for the cache
    img = lambda a: a.torch().reshape(1, 1, H, W).numpy()                        # noqa: E731
    vec = lambda v: np.concatenate([img(v.x), img(v.y), img(v.z)], 1)            # noqa: E731
    out = {"mask": r["hit"].torch().reshape(1, 1, H, W).numpy()}
    if {"position", "view_z"} & set(chans):
        # The hit point on Mitsuba's own ray, o + t·d, and world -> view, both in float64. (Mitsuba's si.p is
        # rebuilt from shape-local coordinates and strays up to ~1e-6 relative off the ray for big shapes.)
        f64 = lambda v: torch.stack([v.x.torch(), v.y.torch(), v.z.torch()]).double()  # noqa: E731
        t = r["t"].torch().double()
        pw = f64(r["ray_o"]) + t * f64(r["ray_d"])
        pw = torch.where(torch.isfinite(pw), pw, torch.zeros_like(pw))                   # misses: t = inf
        pv = cam.world_to_view(pw, dim=0).float().numpy().reshape(1, 3, H, W)
        if "position" in chans:
            out["position"] = pv
        if "view_z" in chans:
            out["view_z"] = pv[:, 2:3].copy()
    if "normal" in chans:
        out["normal"] = vec(r["n_view"])
    if {"shape_id", "albedo", "roughness", "metallic"} & set(chans):
        out["shape_id"] = r["sid"].torch().reshape(1, 1, H, W).numpy()
    for name in ("back_z", "second_z"):
        if name in chans:
            out[name] = img(r[name])
    if "albedo" in r:
        out["albedo_hit"] = vec(r["albedo"])
    return out


def _render_scalar(sc: Scene, cam: Camera, chans: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Slow fallback: the same computation one pixel at a time (``scalar_rgb`` has no wide arrays)."""
    mi = backend.mitsuba()
    import drjit as dr
    from tqdm import tqdm
    mscene = convert.load(sc, cam)
    sensor = mscene.sensors()[0]
    H, W = cam.height, cam.width
    V = mi.Transform4f([[float(v) for v in row] for row in cam.view_matrix().tolist()])
    hit = np.zeros((H, W), bool)
    pos, nrm = np.zeros((3, H, W), np.float32), np.zeros((3, H, W), np.float32)
    sid, back = np.full((H, W), -1, np.int32), np.full((H, W), -np.inf, np.float32)
    second = np.full((H, W), -np.inf, np.float32)
    for j in tqdm(range(H), desc="gbuffer (scalar)", disable=H * W < 20000, leave=False):
        for i in range(W):
            ray, _ = sensor.sample_ray(0.0, 0.0, mi.Point2f((i + 0.5) / W, (j + 0.5) / H), mi.Point2f(0.5, 0.5))
            si = mscene.ray_intersect(ray)
            if not si.is_valid():
                continue
            hit[j, i] = True
            p = V @ si.p
            n = dr.normalize(V @ mi.Vector3f(si.sh_frame.n))
            n = -n if dr.dot(n, mi.Vector3f(p)) > 0 else n
            pos[:, j, i], nrm[:, j, i] = [p.x, p.y, p.z], [n.x, n.y, n.z]
            sid[j, i] = convert.scene_index(si.shape.id())
            if "back_z" in chans or "second_z" in chans:
                t_acc, start = si.t, si.t
                for _ in range(EXIT_SEARCH):
                    step = 1e-4 * (t_acc + cam.near)
                    nxt = mscene.ray_intersect(mi.Ray3f(ray.o + (t_acc + step) * ray.d, ray.d))
                    if not nxt.is_valid():
                        break
                    t_acc = t_acc + step + nxt.t
                    if dr.dot(nxt.n, ray.d) > 0 and convert.scene_index(nxt.shape.id()) == sid[j, i]:
                        back[j, i] = (V @ mi.Point3f(ray.o + t_acc * ray.d)).z
                        start = t_acc
                        break
                step = 1e-4 * (start + cam.near)
                nxt = mscene.ray_intersect(mi.Ray3f(ray.o + (start + step) * ray.d, ray.d))
                if nxt.is_valid():
                    second[j, i] = (V @ mi.Point3f(ray.o + (start + step + nxt.t) * ray.d)).z
    return {"mask": hit[None, None], "position": pos[None], "view_z": pos[None, 2:3], "normal": nrm[None],
            "shape_id": sid[None, None], "back_z": back[None, None], "second_z": second[None, None]}


def _fill(sc: Scene, cam: Camera, raw: dict[str, np.ndarray], chans: tuple[str, ...]) -> GBuffer:
    """numpy arrays → torch, material look-ups by shape id, background fill values (gbuffer.FILL)."""
    mask = torch.from_numpy(np.ascontiguousarray(raw["mask"]))
    out: dict[str, torch.Tensor] = {}
    if "mask" in chans:
        out["mask"] = mask
    if "view_z" in chans:
        out["view_z"] = torch.where(mask, torch.from_numpy(raw["view_z"].copy()), torch.tensor(-cam.far))
    if "position" in chans:
        uv = cam.uv_grid(torch.float32).unsqueeze(0)
        far_pt = cam.uv_to_view(uv, torch.full((1, 1, cam.height, cam.width), -cam.far))
        out["position"] = torch.where(mask, torch.from_numpy(raw["position"].copy()), far_pt)
    if "normal" in chans:
        out["normal"] = torch.where(mask, torch.from_numpy(raw["normal"].copy()), torch.tensor(0.0))
    for name in ("back_z", "second_z"):
        if name in chans:
            out[name] = torch.where(mask, torch.from_numpy(raw[name].copy()), torch.tensor(-float("inf")))
    if "shape_id" in raw:
        sid = torch.from_numpy(raw["shape_id"].copy()).to(torch.int32)
        idx = sid.clamp_min(0).long()
        mats = [s.material for s in sc.shapes]
        tables = {"albedo": torch.tensor([m.albedo for m in mats], dtype=torch.float32),      # (N, 3)
                  "roughness": torch.tensor([[m.roughness] for m in mats], dtype=torch.float32),
                  "metallic": torch.tensor([[m.metallic] for m in mats], dtype=torch.float32)}
        bg = {"albedo": 0.0, "roughness": 1.0, "metallic": 0.0}
        for name, tab in tables.items():
            if name in chans:
                vals = tab[idx[:, 0]].permute(0, 3, 1, 2)                                  # (1, C, H, W)
                if name == "albedo" and "albedo_hit" in raw:                      # textures, at each hit
                    at_hit = torch.tensor(_albedo_at_hit(sc))
                    vals = torch.where(at_hit[idx[:, 0]].unsqueeze(1),
                                       torch.from_numpy(raw["albedo_hit"].copy()).clamp(0.0, 1.0), vals)
                out[name] = torch.where(mask, vals, torch.tensor(bg[name]))
        if "shape_id" in chans:
            out["shape_id"] = torch.where(mask, sid, torch.tensor(-1, dtype=torch.int32))
    return GBuffer(cam, **out)


def gbuffer(scene, width: Optional[int] = None, height: Optional[int] = None,
            channels: Optional[Iterable[str]] = None, *, spp: int = 64, seed: int = 0,
            use_cache: bool = True, info: Optional[dict] = None) -> GBuffer:
    """Render a reference :class:`~ssbench.gbuffer.GBuffer` with one ray per pixel centre.

    Args:
        scene: a :class:`~ssbench.scenes.Scene`, a catalog name, a scene file path or a dict.
        width, height: image size (default: the scene camera's); the vertical fov is kept.
        channels: names from :data:`ssbench.gbuffer.CHANNELS` (default :data:`DEFAULT_CHANNELS`). ``color``
            is path traced by :func:`ssbench.reference.color` with ``spp`` and ``seed``.
        use_cache: read and write the on-disk cache (``ssbench.reference.cache``).
        info: a dict to receive ``{"cached": bool, "seconds": float or None}`` of the geometric channels: whether
            they came from the cache and how long their rendering took (then, when they were rendered).

    Returns:
        A batch-1 G-buffer whose camera is the scene camera at ``width × height``.
    """
    sc, cam = resolve_camera(scene, width, height)
    chans = _channels(channels)
    geo = tuple(c for c in chans if c != "color")
    gb = None
    if geo:
        key = cache.make_key("gbuffer", _KERNEL_VERSION, sc.content_hash(), cam, sorted(geo))
        stored: dict = {}
        raw = cache.load(key, stored) if use_cache else None
        cached = raw is not None
        if not cached:
            t0 = time.perf_counter()
            raw = (_render_jit if backend.is_jit() else _render_scalar)(sc, cam, geo)
            raw = {k: v for k, v in raw.items() if k in geo or k in ("mask", "shape_id", "albedo_hit")}
            stored = {"seconds": time.perf_counter() - t0}
            if use_cache:
                cache.store(key, raw, stored)
        if info is not None:
            info.update(cached=cached, seconds=stored.get("seconds"))
        gb = _fill(sc, cam, raw, geo)
    if "color" in chans:
        from .color import color as render_color
        col = render_color(sc, cam.width, cam.height, spp=spp, seed=seed, use_cache=use_cache)
        gb = GBuffer(cam, color=col, **(gb.as_dict() if gb is not None else {}))
    return gb
