"""One switch for compiled passes: ``torch.compile`` of each pass's per-band kernel.

A pass marks the pure tensor function it runs per band of rows (or once per image, for its per-pixel set-up) with
:func:`kernel`. With the switch off (the
default) the kernel runs as written (eager). With it on, the kernel runs through ``torch.compile`` (inductor;
``dynamic=False``, so an image size compiles at most twice: its full bands and its last band); everything
around it — parameter checks, noise and kernel draws, the band loop, early exits — stays eager, so a compiled
pass is the same pass. Compiled: Crytek and hemisphere SSAO (their per-pixel set-up and their sample loop, bit for bit
equal to eager, tested) and GTAO (the one exception to
"equal": its AO differs from eager by up to 4.5e-6 in float32, measured at 1920×1080, because inductor's
vectorised cos/acos differ from ATen's by an ulp and ``acos`` near ±1 magnifies that; float64 agrees to 1e-14) and
the visibility-bitmask AO (the same ulp now and then moves a sample across a sector edge: one bit of one slice,
1/(sectors·slices) = 1/128 at the defaults, in 0.03 % of the pixels of stairs at 640×360, 4.3× faster than eager
there, 9.2× with cosine weighting; two such bits, 2/128, in a pixel of ``sphere_on_plane`` at 1920×1080) and SAO's
tap loop and the norm of its face normals (bit-equal at the defaults on stairs at 640×360; with G-buffer normals and
radius 2, 2 of 230 400 pixels differ by ≤ 4.5e-5: inductor contracts
``ssR·cos`` to an FMA, and a tap within an ulp of a pixel edge truncates to the neighbour; the normals' cross
product stays eager, because ATen computes each component with one FMA and inductor's C++ does not) and GTAO's
denoise (its edges, tap weights and one pass, each a kernel on pre-padded planes: exact operations and divisions
only, so the same bits, tested) and HBAO's band (compiled, its march skips
the early exit, which would break the graph — ``torch.compiler.is_compiling()`` — and the steps it skipped are masked
anyway: the same AO bit for bit, only the debug ``horizons`` differ by an ulp of ``atan``) and three.js GTAO (its
band's frame and one kernel per slice direction, called for each: ≤ 2.4e-7 from eager in float32, measured at
1920×1080, where inductor's vectorised ``acos`` and ``sqrt`` differ from ATen's by an ulp) and five SSR marchers:
the linear march's step and bisection probe, the DDA's step, the supercover DDA's cell step (``dda_supercover_walk``)
and Hi-Z's whole iteration (its pyramid read, ``AdvanceRay``, the hit test and the ray's state; compiled, it judges
every ray and keeps the candidates' verdicts, where eager judges only the candidates) are size-dynamic kernels
(``@kernel(dynamic=True)``: one compilation for every working-set size; rays that stop ride along masked until the
set is compacted; compiled, the DDA, its supercover walk, Hi-Z and the linear march (its steps and its bisection's
probes) run :data:`STEPS_PER_CALL` steps per call in one fused loop, ``fuse_whole``, :func:`step_blocks`), bit for bit
equal to eager, tested; and
the three.js march's steps (``three_ssr_step.march_steps``, :data:`STEPS_PER_CALL` per call, the hit's verdict
judged for every ray as Hi-Z does: equal to eager on every output tested, but its ``pointToLineDistance`` is an
ulp apart from ATen's in a quarter of the rays, whose cross product ATen may compute with FMA, so a ray exactly on
the thickness bound could end differently). Glossy SSR's ray reuse (``glossy_reuse.reuse_ray``:
one ray's weighted sums over the whole window in one loop, its inputs padded outside the kernel) is compiled too:
its resolved colours are within 4.8e-7 of eager in float32 (measured on three scenes, four settings), as inductor's
divisions and roots round differently; without reuse it gives the same bits. The linear march's per-pixel ray set-up
is compiled around its reflection (``linear_rays.ray_origin`` before it, ``ray_steps`` after it: exact operations,
the same bits, size-dynamic); the reflection itself stays eager, because compiled its normalised directions differed
from ATen's in the last bit (1.8e-7), which moved refined hit points by up to 0.8 px. Hi-Z's per-ray constants
(``hiz_march.ray_constants``, after the shared eager ``ray_segments``) compile the same way. Not compiled: the DDA's
hit refinement.

Kernels compile without inductor's bounds check on gathered indices (``assert_indirect_indexing``): every kernel
clamps its texel indices itself and is tested equal to its eager form, where ATen checks them; the check cost the
SAO tap loop a fifth of its time. Three inductor habits shaped the kernels (measured): ``F.pad`` inside a kernel
compiles to masked loads slower than eager (pad outside, slice inside); a kernel that reads a neighbour's
value of a fused intermediate recomputes it per neighbour (split the kernel where an intermediate is read shifted);
and a bool tensor that inductor stores between two loops of a kernel is written and read back one lane at a time
(hold such a mask as 0/1 floats, :func:`kept_mask`), as is the mask of every ``where`` that selects int8 values
(the SSR marchers keep their termination codes and alive flags in int32).
One torch 2.13 bug shapes the size-dynamic kernels' arguments: ``torch.compile(dynamic=True)`` keeps the first
call's value of a float argument that fills a tensor (``full_like``, a ``where`` operand) while the same float in
arithmetic follows each call (``x * m + full_like(x, m)`` compiled at ``m = 20`` gives ``x * 7 + 20`` at ``m = 7``):
such a number goes in as a 0-d tensor (``ssr.common.clip_ray_length``'s limit). A float made from an int argument
or an image size fills correctly (``torch.where(x > 0, float(n), 0.0)`` follows ``n``; ``ssr.dda_rays``' viewport
edges). ``tests/passes/test_compiled.py`` runs every SSR marcher compiled through each changed setting, as a sweep
does; ``tests/passes/ssr/test_dda_rays.py`` the DDA's set-up through changed settings and a second image size.

The switch, in order of precedence: :func:`compiling` (a context manager), else the environment variable
``SSBENCH_COMPILE`` (``1``/``true``: on; ``ssbench --compile …`` sets it, so sweep processes inherit it).

Each kernel keeps up to :data:`KERNEL_VARIANTS` compilations (one per input signature), and past that raises
instead of running eager unannounced. Compilation is paid on a kernel's first call per input signature;
:func:`compile_seconds` adds up those first calls (compile plus one run), so rows can report it apart from the
run time. Inductor keeps compiled graphs in its on-disk cache (``TORCHINDUCTOR_CACHE_DIR``, by default under the
system temporary folder), which later runs reuse.
"""
from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import threading
import time
from typing import Any, Callable, Iterator, Optional

import torch

from ..camera import Camera

__all__ = ["enabled", "compiling", "kernel", "compile_seconds", "step_blocks", "ENV", "KERNEL_VARIANTS",
           "WHOLE_FUSION_SIZE", "STEPS_PER_CALL", "kept_mask", "is_set"]

#: environment variable of the switch
ENV = "SSBENCH_COMPILE"
_ON, _OFF = ("1", "true", "yes", "on"), ("", "0", "false", "no", "off")
_local = threading.local()
_first_calls: dict = {}                       # (kernel, signature) -> seconds of its first compiled call


def enabled() -> bool:
    """Whether passes run their compiled kernels now (see the module docstring for the precedence)."""
    forced: Optional[bool] = getattr(_local, "forced", None)
    if forced is not None:
        return forced
    value = os.environ.get(ENV, "").strip().lower()
    if value in _ON:
        return True
    if value in _OFF:
        return False
    raise ValueError(f"{ENV}: expected 1/true/yes/on or 0/false/no/off (or unset), got {os.environ[ENV]!r}")


@contextlib.contextmanager
def compiling(on: bool = True) -> Iterator[None]:
    """Run the passes compiled (``on=True``) or eager inside the block, whatever ``SSBENCH_COMPILE`` says.

    Example:
        >>> with compiling(False):
        ...     enabled()
        False
    """
    if not isinstance(on, bool):
        raise TypeError(f"on: expected True or False, got {on!r}")
    prev = getattr(_local, "forced", None)
    _local.forced = on
    try:
        yield
    finally:
        _local.forced = prev


def _signature(args: tuple, kwargs: dict, dynamic: bool = False) -> tuple:
    """What makes a compiled kernel compile again: tensor shapes, dtypes and devices (inside tuples too, never
    their values) and the other arguments' values (parameter dataclasses, cameras, flags). A ``dynamic`` kernel
    compiles once for all sizes and numbers: only tensors' ranks, dtypes and devices and the other values count, and
    of a camera all but its width and height (dynamo makes those symbolic too; it keeps the field of view, the
    planes and the pose as constants)."""
    def one(v: Any) -> Any:
        if isinstance(v, torch.Tensor):
            return ("T", v.dim() if dynamic else tuple(v.shape), v.dtype, v.device.type)
        if isinstance(v, (tuple, list)):
            return ("S", tuple(one(x) for x in v))
        if dynamic and isinstance(v, (int, float)) and not isinstance(v, bool):
            return ("N", type(v).__name__)
        if dynamic and isinstance(v, Camera):
            return ("C", tuple((f.name, getattr(v, f.name)) for f in dataclasses.fields(v)
                               if f.name not in ("width", "height")))
        return ("V", repr(v))
    return tuple(one(v) for v in args) + tuple((k, one(v)) for k, v in sorted(kwargs.items()))


#: compilations one kernel may keep (input signatures): dynamo's default of 8 per function would, past it, run the
#: kernel eager without a word: a sweep's ninth configuration would time eager code as "compiled"
KERNEL_VARIANTS = 256


#: the settings every compiled kernel call runs under, ``(config module, name, value)`` (:func:`_room_for_variants`)
_ROOM = ((torch._dynamo.config, "recompile_limit", KERNEL_VARIANTS),
         (torch._dynamo.config, "accumulated_recompile_limit", 16 * KERNEL_VARIANTS),
         (torch._dynamo.config, "fail_on_recompile_limit_hit", True),
         (torch.fx.experimental._config, "use_duck_shape", False))


@contextlib.contextmanager
def _room_for_variants() -> Iterator[None]:
    """Room for :data:`KERNEL_VARIANTS` compilations of each kernel (a static kernel compiles once per band shape
    and parameter set; a size-dynamic one once per rank, dtype, flag or debug variant), and an error instead of a
    silent eager run past it. Without *duck sizing*: with it, dynamo gives sizes that are equal on the first call one
    symbol, and a marcher whose first working set is as long as its image (every pixel casts a ray) compiled a graph
    for that call and another for every later one.

    The settings (:data:`_ROOM`) are set and restored by assignment, as torch's ``config.patch`` does (both write the
    same context-local overrides): the two ``patch`` context managers cost ~45 µs per kernel call, the assignments
    ~20 µs."""
    prior = [(config, name, getattr(config, name)) for config, name, _ in _ROOM]
    try:
        for config, name, value in _ROOM:
            setattr(config, name, value)
        yield
    finally:
        for config, name, value in prior:
            setattr(config, name, value)


#: inductor options of every kernel: no bounds check on gathered indices (a kernel clamps its texel indices
#: itself, and is tested equal to its eager form, where ATen checks them); the check cost SAO's tap loop a fifth
_OPTIONS = {"assert_indirect_indexing": False}


#: inductor's limit on the nodes of one fused loop, for a kernel that asks to fuse whole (``fuse_whole=True``): past
#: the default (64) inductor splits a long kernel into loops that store their intermediates
WHOLE_FUSION_SIZE = 4096


def kernel(fn: Optional[Callable] = None, *, dynamic: bool = False, fuse_whole: bool = False) -> Callable:
    """Mark ``fn`` (a pure tensor function, the body a pass runs per band) as the pass's compilable kernel:
    eager while the switch is off, ``torch.compile(fn)`` while it is on; ``wrapper.eager`` is ``fn`` itself.

    ``@kernel(dynamic=True)`` compiles with symbolic sizes and numbers (``torch.compile(dynamic=True)``): for a
    marcher's step, whose working set shrinks as rays stop, one compilation serves every size. ``fuse_whole=True``
    lifts inductor's limit on the size of one fused loop (:data:`WHOLE_FUSION_SIZE`), for a kernel that unrolls
    several steps: it then compiles to one loop that keeps the rays' state in registers between its steps (kernels
    without it measured the same or slower with the limit lifted)."""
    if fn is None:
        return functools.partial(kernel, dynamic=dynamic, fuse_whole=fuse_whole)
    options = dict(_OPTIONS, **({"max_fusion_size": WHOLE_FUSION_SIZE} if fuse_whole else {}))
    compiled: list = []

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        if not enabled():
            return fn(*args, **kwargs)
        if not compiled:
            compiled.append(torch.compile(fn, dynamic=dynamic, options=options))
        key = (fn.__qualname__, fn.__module__, _signature(args, kwargs, dynamic))
        with _room_for_variants():
            if key in _first_calls:
                return compiled[0](*args, **kwargs)
            t0 = time.perf_counter()
            out = compiled[0](*args, **kwargs)
        _first_calls[key] = time.perf_counter() - t0
        return out

    wrapper.eager = fn                                       # type: ignore[attr-defined]
    return wrapper


def kept_mask(mask: torch.Tensor) -> torch.Tensor:
    """``mask`` (bool) as a kernel should hold a mask that several of its operations read: the mask itself eager,
    0/1 in float32 inside ``torch.compile``. Read it back with :func:`is_set`: the same selections, the same bits.

    Inductor stores such a mask as a bool buffer when it splits the kernel into loops, and its C++ writes and reads
    a bool vector one lane at a time, with a branch per lane (``VecMask<bool>``). HBAO's march, whose hit mask is
    read by three selections per step, spent ~40 % of its compiled time there (perf); held as floats, the compiled
    pass took 0.70× the time at 640×360. Eager it stays bool: the two conversions would cost 14 %.

    Example:
        >>> is_set(kept_mask(torch.tensor([True, False]))).tolist()
        [True, False]
    """
    return mask.to(torch.float32) if torch.compiler.is_compiling() else mask


def is_set(mask: torch.Tensor) -> torch.Tensor:
    """The bool mask a :func:`kept_mask` holds (``mask`` itself when it is bool)."""
    return mask if mask.dtype == torch.bool else mask > 0


#: steps a marcher's ``fuse_whole`` kernel runs per compiled call (the DDA and its supercover walk, Hi-Z, the linear
#: and three.js marches), their rays' state in registers between them; measured on the DDA at 640×360, 1 / 4 / 8 / 16
#: per call: 470 / 370 / 334 / 334 ms, sixteen compiling twice as long
STEPS_PER_CALL = 8


def step_blocks(total: int, one_by_one: bool = False, device=None) -> Iterator[tuple[int, Optional[torch.Tensor]]]:
    """The calls of a marcher's step kernel over ``total`` steps, ``(count, left)`` each: ``count`` steps per call
    (:data:`STEPS_PER_CALL` compiled; 1 eager, or ``one_by_one`` where debug buffers read every step) and ``left``
    the steps the march has left, a 0-d tensor (the kernel masks its ``j``-th step unless ``j < left``: one graph
    for any budget), ``None`` with one step per call.

    Example:
        >>> with compiling(False):
        ...     list(step_blocks(3))
        [(1, None), (1, None), (1, None)]
    """
    count = STEPS_PER_CALL if enabled() and not one_by_one else 1
    for first in range(0, total, count):
        yield count, (torch.tensor(total - first, device=device) if count > 1 else None)


def compile_seconds() -> float:
    """Seconds spent so far, in this process, in compiled kernels' first calls (compilation plus one run).

    Example:
        >>> compile_seconds() >= 0.0
        True
    """
    return float(sum(_first_calls.values()))
