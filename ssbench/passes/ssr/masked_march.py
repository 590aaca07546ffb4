"""The masked march that the DDA (:mod:`.dda_march`) and its supercover walk (:mod:`.dda_supercover_walk`) share:
fixed-shape steps over a working set of rays in which a stopped ray rides along masked (so a compiled step compiles
once for every size), compacted once 1/8 of the set has stopped; the working set's columns as the march keeps them,
and the set-up's columns read back only for the rays that hit."""
from __future__ import annotations

import dataclasses
from typing import NamedTuple, Optional

import torch

from ...indices import flat_nonzero
from ..common import index_dtype
from ..compiled import step_blocks
from .common import OUT_OF_STEPS
from .dda_state import DDARays

__all__ = ["HIT_ONLY", "add_visits", "hit_rows", "marching_fields", "masked_march", "next_state"]


def add_visits(visits: torch.Tensor, t: torch.Tensor, active: torch.Tensor) -> None:
    """Count one fetch of texel ``t`` in the visit map for each ``active`` ray (bool, or int32 0/1)."""
    on = active if active.dtype == torch.bool else active != 0
    visits.index_add_(0, t[on], torch.ones_like(t[on], dtype=visits.dtype))


def next_state(state: NamedTuple, marching: torch.Tensor, moved: tuple, done: torch.Tensor, live: torch.Tensor,
               term: torch.Tensor) -> NamedTuple:
    """The state after one step of a masked march (:func:`~.dda_march.dda_step`, the supercover walk's
    ``walk_step``): the state's leading fields become ``moved`` (in field order) where the ray was ``marching`` and
    stay elsewhere; then ``alive32`` is cleared where the ray stopped (``done``), ``steps`` counts the ``live``
    fetches and ``term`` (int32) takes the step's termination code where the ray stopped. In the eager float form
    (:mod:`.dda_float_step`: flags, counts and codes in the samples' dtype; ``marching`` still bool) the same numbers
    by arithmetic: ``done`` and ``live`` are 0/1 and a ray stops only while marching."""
    kept = [torch.where(marching, a, a0) for a, a0 in zip(moved, state)]
    if state.alive32.is_floating_point():
        return type(state)(*kept, state.alive32 - done, state.steps + live,
                           torch.addcmul(state.term, done, term - state.term))      # small integers: exact
    return type(state)(*kept, torch.where(done, 0, state.alive32), state.steps + live.to(torch.int32),
                       torch.where(done, term.to(state.term.dtype), state.term))


#: the set-up's fields (:class:`DDARays`) that the DDA reads only where a ray hits: left out of the marching working
#: set, whose compactions then copy 26 of its ~120 bytes per ray less, and read back from the set-up by row ``i``
#: (:func:`hit_rows`)
HIT_ONLY = ("b", "permute", "clipped", "Q0x", "Q0y", "dQx", "dQy")


def hit_rows(s, rows: torch.Tensor, set_up: DDARays, hit_only: tuple = HIT_ONLY):
    """The working set ``s``'s ``rows`` (a copy, :meth:`~.dda_state.DDARays.select`) with the fields ``hit_only``,
    which the march left out (:func:`marching_fields`), read back from the rays before the march ``set_up``."""
    h = s.select(rows)
    return dataclasses.replace(h, **{f: getattr(set_up, f).index_select(0, h.i) for f in hit_only})


def marching_fields(s: DDARays, texels: int, hit_only: tuple = HIT_ONLY) -> dict:
    """The fields of the set-up's rays ``s`` as a masked march keeps them (:class:`~.dda_march.MarchingRays`, the
    supercover's ``CellWalk``): each column contiguous (the set-up's are strided views; a compiled step compiles again
    for views), ``None`` for the fields ``hit_only`` (read back for the hits, :func:`hit_rows`), the batch index in
    the index dtype of ``texels`` texels, ``permute``, ``clipped`` and ``alive`` as int32, no fetches yet (``steps``)
    and the termination ``OUT_OF_STEPS`` (int32, :func:`~.common.end_code`)."""
    N, dev = s.count, s.k.device

    def kept(name: str, v):
        return None if name in hit_only else v.contiguous() if isinstance(v, torch.Tensor) else v
    return dict({f.name: kept(f.name, getattr(s, f.name)) for f in dataclasses.fields(s)},
                b_index=s.b.to(index_dtype(texels)), permute32=s.permute.to(torch.int32),
                clipped32=s.clipped.to(torch.int32), alive32=torch.ones(N, dtype=torch.int32, device=dev),
                steps=torch.zeros(N, dtype=torch.int32, device=dev),
                term=torch.full((N,), OUT_OF_STEPS, dtype=torch.int32, device=dev))


def masked_march(s, state: type, ray: type, run, flush, max_steps: int, visits: Optional[torch.Tensor]) -> None:
    """A marcher's loop over fixed-shape masked steps (the DDA's, the supercover walk's): ``run(state, ray, count,
    left)`` (a step kernel over :func:`~ssbench.passes.compiled.step_blocks`) advances the fields of the per-ray
    dataclass ``s`` that the named tuple ``state`` names (``alive32`` among them), given those that ``ray`` names,
    and returns ``(state, stopped)`` (plus the fetched texels and which rays fetched them, counted into ``visits`` if
    given). Once 1/8 of the working set has stopped, ``flush(s, rows)`` writes the stopped rows back and the set is
    compacted; at the end every row is flushed."""
    dead = 0
    for count, left in step_blocks(max_steps, visits is not None, s.k.device):
        if s.count == dead:
            break
        r = run(state(*(getattr(s, f) for f in state._fields)), ray(*(getattr(s, f) for f in ray._fields)), count,
                left)
        for f, v in zip(state._fields, r[0]):
            setattr(s, f, v)
        if visits is not None:
            add_visits(visits, *r[2:])
        dead += int(r[1])
        if 8 * dead >= s.count and dead:                                            # compact
            flush(s, flat_nonzero(s.alive32 == 0))
            s, dead = s.select(flat_nonzero(s.alive32)), 0
    flush(s, torch.arange(s.count, device=s.k.device))
