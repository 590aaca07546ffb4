"""What GTAO-style passes return beyond AO, scored against its own truth: the bent normal and multi-bounce AO.

:func:`ao_beyond` runs one AO method on one scene and returns one tidy row:

* **bent normal** (methods whose pass takes ``bent_normals=True``: GTAO, Jimenez et al. 2016, Algorithm 2 as
  XeGTAO writes it; visibility-bitmask AO's clear-sector centre): the angle to the ray-traced mean unoccluded
  direction (:func:`ssbench.reference.bent_normal.bent_normals`), ``bent_{mean,median,p95}_deg``, beside the
  do-nothing baseline (the shading normal, ``shading_normal_mean_deg``) and the truth's own error bar
  (``bent_truth_stderr_deg``, its mean angular standard error); NaN for methods without bent normals;
* **multi-bounce** (every method): the method's AO through Jimenez et al.'s fit with the G-buffer albedo
  (:func:`ssbench.metrics.ao_multibounce.jimenez_multibounce`) against the path-traced multi-bounce AO under a
  uniform white environment (:func:`ssbench.reference.multibounce.multibounce_ao`): ``multibounce_rmse`` and
  ``multibounce_bias``; the baselines ``single_bounce_rmse`` (the exact one-bounce AO: what ignoring
  interreflection costs) and ``fit_exact_rmse`` (the fit on the exact AO: what the fit itself costs), and the
  truth's RMS standard error ``multibounce_truth_stderr``.
"""
from __future__ import annotations

import dataclasses
import importlib

import torch

from ._common import params_as_dict, resolve_params

__all__ = ["ao_beyond", "has_bent_normals"]


def has_bent_normals(fn) -> bool:
    """Whether an AO pass returns bent normals (its signature takes ``bent_normals``)."""
    from ._ssr import accepted_kwargs
    return "bent_normals" in accepted_kwargs(fn, bent_normals=True)


def ao_beyond(scene, method: str, params=None, *, width: int = 160, height: int = 120, radius: float = 0.5,
              rays: int = 256, seed: int = 0, use_cache: bool = True) -> dict:
    """Score ``method``'s bent normal and multi-bounce AO on ``scene`` (module docstring); one row.

    Args:
        scene: catalog name, scene file, dict or :class:`~ssbench.scenes.Scene`.
        method: a name of :data:`ssbench.passes.AO_METHODS`; ``params`` overrides its defaults.
        width, height: image size. radius: the pass's radius and the truths'.
        rays: rays (bent normal) and paths (multi-bounce) per pixel of the truths. seed: theirs and the pass's.
    """
    from .. import reference
    from ..metrics.ao_bent import bent_normal_error
    from ..metrics.ao_multibounce import jimenez_multibounce, multibounce_error
    from ..passes import ao_method
    from ..reference.bent_normal import bent_normals
    from ..reference.multibounce import multibounce_ao
    from ..scenes import load as load_scene
    from ._ao import radius_param
    for name, v, lo in (("rays", rays, 2), ("seed", seed, 0)):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ValueError(f"{name}: must be an integer >= {lo}, got {v!r}")
    if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not 0 < radius < float("inf"):
        raise ValueError(f"radius: must be a finite number > 0, got {radius!r}")
    fn, params_cls, _ = ao_method(method)
    p = resolve_params(params_cls, params, method)
    rname = radius_param(params_cls, importlib.import_module(fn.__module__))
    if rname:
        p = dataclasses.replace(p, **{rname: float(radius)})
    sc = load_scene(scene)
    g = reference.gbuffer(sc, width, height, use_cache=use_cache)
    bent = has_bent_normals(fn)
    gen = torch.Generator().manual_seed(seed)
    out = fn(g, p, generator=gen, **({"bent_normals": True} if bent else {}))
    row = {"scene": sc.name, "method": method, "params": params_as_dict(p), "width": width, "height": height,
           "radius": float(radius), "rays": rays, "seed": seed, "has_bent_normals": bent}
    ref = bent_normals(sc, g, float(radius), rays=rays, seed=seed, use_cache=use_cache)
    base = bent_normal_error(g.normal, ref.normal, g.mask, ref.stderr_deg)
    row["shading_normal_mean_deg"], row["bent_truth_stderr_deg"] = base["mean_deg"], base["truth_stderr_deg"]
    err = bent_normal_error(out.bent_normal, ref.normal, g.mask, ref.stderr_deg) if bent else {}
    for k in ("mean_deg", "median_deg", "p95_deg"):
        row[f"bent_{k}"] = err.get(k, float("nan"))
    mb = multibounce_ao(sc, g, float(radius), rays=rays, seed=seed, use_cache=use_cache)
    score = lambda pred: multibounce_error(pred, mb.ao, g.mask, mb.stderr)                   # noqa: E731
    mine = score(jimenez_multibounce(out.ao.double(), g.albedo.double()))
    row.update({"multibounce_rmse": mine["rmse"], "multibounce_bias": mine["bias"],
                "multibounce_truth_stderr": mine["truth_stderr"],
                "single_bounce_rmse": score(mb.single.expand(-1, 3, -1, -1))["rmse"],
                "fit_exact_rmse": score(jimenez_multibounce(mb.single, mb.albedo))["rmse"]})
    return row
