"""What one eager torch operation costs per element: the primitives an eager pass is made of, against ``a + b``.

An eager pass runs each of its operations as its own loop over memory, so its time is the sum of what those loops
cost. They do not all cost the same: this times each on ``N`` elements (default 640·360, one float32 image) with 1
torch thread, in rounds that alternate every operation with ``a + b`` in one process (``ssbench.bench.timing``), and
prints the median ns per element and the median per-round ratio to ``a + b`` (which survives a loaded machine):

* ``torch.where`` (ATen's CPU kernel is a per-element ``cond ? a : b``): a few times an addition where the mask
  comes in long runs (a march's rays, neighbours in an image), many times where it flips at random, as a branch
  that the predictor misses would. ``masked_fill`` and a product with a bool mask (a cast per element) are no
  better. Compiled (``--compile``), a ``where`` whose mask is computed in the same kernel is a vector blend and
  costs what a compiled addition does; a lone one that reads a bool array measured no faster than eager, and just as
  dependent on the mask (inductor's generated code turns the bytes into a vector mask): one reason the
  marchers keep their flags as int32 in the compiled steps;
* comparisons write one byte per element and cost more than an addition;
* gathers at random indices into an image of ``N`` texels: ``index_select`` with int32 or int64 indices,
  ``torch.take`` and ``x[index]`` (advanced indexing);
* conversions float → int32 / int64 and integer products (int64 lanes are half as many per vector, and AVX2 has
  no 64-bit vector multiply): why the marchers and the AO passes keep texel indices in int32 where they fit;
* the transcendentals the AO passes call per sample: ``cos`` and ``sin`` of small angles (a noise texture's) and of
  the angles SAO's per-pixel hash makes, ``(3x ^ (y + xy))·10`` radians, up to ~2.6·10⁶ at 640×360. ATen's
  vectorised ``cos`` and ``sin`` (SLEEF's) reduce an argument beyond ~4·10⁴ the slow way (Payne–Hanek), for the
  whole vector of lanes when one needs it: ~12 ns against ~1.7 per value, measured. That, not its texel reads,
  is most of SAO's tap loop (``perf`` on the compiled pass: the two functions took ~2/3 of it). ``log2`` (SAO's mip
  level), ``acos`` (GTAO's horizons) and ``hypot(a, 1)`` (HBAO's ``TanToSin``, written so that a slope never
  overflows) complete the list.

A benchmark, not a test: ``.venv/bin/python benchmarks/bench_ops.py [--size 640x360 --rounds 15 --compile]``.
"""
from __future__ import annotations

import argparse

import torch

from ssbench.bench.timing import median_iqr, plan_rounds, run_rounds, warm_up


def operations(n: int, gen: torch.Generator) -> dict:
    """``{name: call}`` over ``n``-element inputs drawn from ``gen``."""
    a, b = torch.rand(n, generator=gen), torch.rand(n, generator=gen)
    runs = (torch.arange(n) // 4096) % 2 == 0                                 # a mask in runs of 4096
    random = a > 0.5                                                          # a mask that flips at random
    sparse = a > 0.9
    idx64 = torch.randint(0, n, (n,), generator=gen)
    idx32 = idx64.int()
    i32, i64 = idx32 // 3 + 1, idx64 // 3 + 1
    small = (a - 0.5) * 6.28                                                  # angles in [-pi, pi)
    hashed = ((3 * idx64) ^ (idx64 // 7)).to(torch.float32) * 10.0             # SAO's hash angles: ~10^6
    one = torch.ones_like(a)
    return {
        "a + b": lambda: a + b,
        "a * b": lambda: a * b,
        "a > b": lambda: a > b,
        "minimum(a, b)": lambda: torch.minimum(a, b),
        "where(m, a, b), m all true": lambda: torch.where(torch.ones_like(runs), a, b),
        "where(m, a, b), m in runs": lambda: torch.where(runs, a, b),
        "where(m, a, b), m 10 % true": lambda: torch.where(sparse, a, b),
        "where(m, a, b), m random": lambda: torch.where(random, a, b),
        "where(m, a, 0.0), m in runs": lambda: torch.where(runs, a, 0.0),
        "a.masked_fill(m, 0), m in runs": lambda: a.masked_fill(runs, 0.0),
        "a * m (bool), m in runs": lambda: a * runs,
        "index_select, int32 indices": lambda: a.index_select(0, idx32),
        "index_select, int64 indices": lambda: a.index_select(0, idx64),
        "take, int64 indices": lambda: torch.take(a, idx64),
        "a[index], int64 indices": lambda: a[idx64],
        "float -> int32": lambda: b.to(torch.int32),
        "float -> int64": lambda: b.to(torch.int64),
        "int32 * int32": lambda: i32 * i32,
        "int64 * int64": lambda: i64 * i64,
        "cos(a), a in [-pi, pi)": lambda: torch.cos(small),
        "cos(a), a ~ 1e6 (SAO's hash angle)": lambda: torch.cos(hashed),
        "sin(a), a ~ 1e6 (SAO's hash angle)": lambda: torch.sin(hashed),
        "log2(a)": lambda: torch.log2(a),
        "acos(a)": lambda: torch.acos(a),
        "hypot(a, 1)": lambda: torch.hypot(a, one),
    }


def compiled_operations(n: int, gen: torch.Generator) -> dict:
    """``where`` as compiled kernels (inductor): reading a bool mask, and with the mask computed in the kernel (the
    eager twin of that is two operations, the comparison and the select)."""
    a, b = torch.rand(n, generator=gen), torch.rand(n, generator=gen)
    runs, random = (torch.arange(n) // 4096) % 2 == 0, a > 0.5
    where = torch.compile(lambda m, x, y: torch.where(m, x, y), dynamic=False)
    fused = torch.compile(lambda x, y: torch.where(x > 0.5, x, y), dynamic=False)
    add = torch.compile(lambda x, y: x + y, dynamic=False)
    return {"compiled a + b": lambda: add(a, b), "compiled where(m, a, b), m in runs": lambda: where(runs, a, b),
            "compiled where(m, a, b), m random": lambda: where(random, a, b),
            "eager where(a > 0.5, a, b)": lambda: torch.where(a > 0.5, a, b),
            "compiled where(a > 0.5, a, b)": lambda: fused(a, b)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", default="640x360", help="WxH: the elements per operation")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--block-ms", type=float, default=20.0, help="about how long one timed block of calls lasts")
    ap.add_argument("--compile", action="store_true", help="also time compiled where and add")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    try:
        w, h = (int(v) for v in a.size.lower().split("x"))
    except ValueError:
        ap.error(f"--size: expected WxH such as 640x360, got {a.size!r}")
    if w < 1 or h < 1:
        ap.error(f"--size: each side must be >= 1, got {a.size!r}")
    if a.rounds < 3:
        ap.error(f"--rounds: must be at least 3, got {a.rounds}")
    if not a.block_ms > 0:
        ap.error(f"--block-ms: must be > 0, got {a.block_ms}")
    torch.set_num_threads(1)
    n, gen = w * h, torch.Generator().manual_seed(a.seed)
    ops = operations(n, gen)
    if a.compile:
        ops.update(compiled_operations(n, gen))
    reference = ops["a + b"]
    print(f"torch {torch.__version__}, 1 thread, {n} elements ({w}x{h}), float32 unless named; "
          f"median of {a.rounds} rounds, each operation alternated with a + b")
    print(f"{'operation':38s} {'ns/element':>10s} {'x a + b':>14s}")
    for name, call in ops.items():
        rounds, numbers = plan_rounds(warm_up([call, reference], at_least=3), a.block_ms / 1e3 * a.rounds, a.rounds)
        op_s, ref_s = run_rounds([call, reference], numbers, rounds)
        ns, _ = median_iqr(op_s)
        ratio, iqr = median_iqr([x / y for x, y in zip(op_s, ref_s)])
        print(f"{name:38s} {ns * 1e9 / n:10.2f} {ratio:8.1f} ±{iqr:4.1f}")


if __name__ == "__main__":
    main()
