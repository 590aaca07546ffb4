"""Every screen-space pass against its gather floor at several sizes: ms, ns/px, floor ratio, peak memory.

One table, one row per pass × size (× compiled, with ``--compile``), each measured in a fresh subprocess so that
its peak memory is its own:

* ``ms`` — median time per call (``ssbench.bench.timing``: interleaved rounds of the pass and its floor, 1 torch
  thread unless ``--threads``), ``ns/px`` = ms / pixels, ``ns/read`` = ns/px / ``reads`` (a marcher's rays cross
  more pixels at higher resolution, so its ns/px grows with the image while its cost per read need not);
* ``floor×`` — median over rounds of pass time / the *torch gather floor* (``ssbench.bench.floors``: as many
  random depth-texel reads per pixel as the pass makes — an AO method's declared ``samples_per_pixel``, an SSR
  march's mean ``steps`` — one ``index_select`` per sample), measured side by side in the same process, so it
  survives a loaded machine; ``fused×`` the same against the *fused floor* (those reads as one Dr.Jit kernel);
  ``anchor×`` (hemisphere SSAO only) against the same method written as one Dr.Jit kernel
  (``ssbench.bench.anchors``, tested to count the same samples);
* ``peak MiB`` — the memory one steady call of the pass adds at its peak: the process's peak resident memory
  during the call minus its resident memory just before (after the first calls, compiled and eager, for the timing
  check and the comparison; the G-buffer, the interpreter and loaded compiled code excluded). The JSON rows also
  carry ``first_peak_mib``, the peak of those first calls over the memory before them, which for a compiled pass
  includes the compiler at work;
* ``compile s`` — with ``--compile``: the pass's first call with its band kernels compiled
  (``ssbench.passes.compiled``: ``torch.compile``, inductor; the on-disk cache can make it short), reported apart
  from the run time; ``Δ eager`` the largest difference of the compiled output from the eager one on valid
  pixels. The SSR marchers compile their steps (see ``ssbench.passes.compiled``).

The G-buffers come from the Mitsuba reference at each size (cached), passed to the subprocesses as files.
A benchmark, not a test: run ``.venv/bin/python benchmarks/bench_passes.py`` (``--sizes 320x240,640x360``,
``--methods ssao,hbao``, ``--effects ao``, ``--min-run-time 2``). ``make bench`` runs it.
"""
from __future__ import annotations

import argparse
import ctypes
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

SIZES = "320x240,640x360,1920x1080"
SCENES = {"ao": "sphere_on_plane", "ssr": "reflective_floor"}


def _status_mib(field: str) -> float:
    """``VmRSS`` / ``VmHWM`` (peak) of this process in MiB (Linux ``/proc``; ``ru_maxrss`` elsewhere)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _reset_peak() -> bool:
    """Reset the kernel's peak-RSS mark (``VmHWM``) to the current RSS (Linux ≥ 4.0); False if it cannot."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as f:
            f.write("5")
        return True
    except OSError:
        return False


def _trim_heap() -> None:
    """Give glibc's free heap memory back to the kernel (``malloc_trim(0)``), so that resident memory is live data
    and a later peak over it counts every page the next call touches; nothing off glibc."""
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _methods(effect: str) -> list[str]:
    from ssbench.passes import AO_METHODS, SSR_METHODS
    return list({"ao": AO_METHODS, "ssr": SSR_METHODS}[effect])


def _inputs(effect: str, method: str, g, compiled: bool):
    """``(call, output, valid, samples)`` of one pass at its defaults (AO at radius 0.5)."""
    import dataclasses

    import torch

    from ssbench.bench.effects import ao_samples
    from ssbench.passes import ao_method, ssr_method
    fn, params_cls, _ = (ao_method if effect == "ao" else ssr_method)(method)
    p = params_cls()
    if effect == "ao":
        from ssbench.evaluate import radius_param
        p = dataclasses.replace(p, **{radius_param(params_cls): 0.5})
    from ssbench.passes.compiled import compiling

    def call():
        with compiling(compiled):
            return fn(g, p, generator=torch.Generator().manual_seed(0))

    t0 = time.perf_counter()
    out = call()
    first_s = time.perf_counter() - t0
    with compiling(False):
        eager = fn(g, p, generator=torch.Generator().manual_seed(0))
    if effect == "ao":
        return call, out.ao, g.mask, ao_samples(method, p), first_s, eager.ao
    samples = max(1, round(float(out.steps.float().mean())))
    return call, out.color, g.mask, samples, first_s, eager.color


def one(effect: str, method: str, path: str, compiled: bool, min_run_time: float, threads: int,
        rounds: int = 9) -> dict:
    """Measure one pass on the G-buffer stored at ``path`` (run in its own process)."""
    import torch

    from ssbench.bench.effects import BenchInputs
    from ssbench.bench.timing import TimingSpec, time_pass
    torch.set_num_threads(threads)
    from ssbench.bench.floors import drjit_llvm
    if drjit_llvm() is not None:             # this process writes no EXR: its Dr.Jit pool may be sized once, here,
        import drjit as dr                   # before any kernel, so both floors and the anchor use `threads` too
        dr.set_thread_count(threads)
    g = torch.load(path, weights_only=False)
    _reset_peak()
    before = _status_mib("VmRSS")
    call, out, valid, samples, first_s, eager = _inputs(effect, method, g, compiled)
    first_peak = _status_mib("VmHWM") - before                 # compiled: includes the compiler's own working memory
    _trim_heap()                                               # freed heap back to the kernel: RSS = live data
    _reset_peak()
    steady = _status_mib("VmRSS")
    call()                                                     # a steady call: what the pass itself holds at its peak
    peak = _status_mib("VmHWM") - steady
    row = time_pass(BenchInputs(call, out.detach(), valid, samples, g.view_z),
                    TimingSpec(min_run_time=min_run_time, warmup=1, rounds=rounds), threads)
    v = valid.expand_as(out)
    diff = float((out.double() - eager.double()).abs()[v].max()) if v.any() else 0.0
    anchor = _anchor_ratio(effect, method, g, call, threads, rounds)
    px = g.width * g.height
    return {"method": method, "size": f"{g.width}x{g.height}", "mode": "compiled" if compiled else "eager",
            "ms": row["time_median_ms"], "ns_px": row["time_median_ms"] * 1e6 / px,
            "ns_read": row["time_median_ms"] * 1e6 / (px * max(samples, 1)), "floor_ms": row["floor_median_ms"],
            "floor_ratio": row["floor_ratio"], "floor_ratio_iqr": row["floor_ratio_iqr"], "samples": samples,
            "fused_floor_ratio": row["fused_floor_ratio"], "fused_floor_ms": row["fused_floor_median_ms"],
            "peak_mib": peak, "first_peak_mib": first_peak, "first_call_s": first_s, "max_diff_eager": diff, "threads": threads,
            "anchor_ratio": anchor, "error": row["timing_error"]}


def _anchor_ratio(effect: str, method: str, g, call, threads: int, rounds: int) -> float:
    """Pass time / the Dr.Jit anchor's (``ssbench.bench.anchors``: hemisphere SSAO and the linear SSR march at
    their bench parameters), median of per-round ratios of alternating blocks; ``nan`` for other passes or
    without an LLVM backend."""
    import statistics

    from ssbench.bench.anchors import linear_ssr_anchor, ssao_anchor
    from ssbench.bench.timing import timeit_calls
    if (effect, method) == ("ao", "ssao"):
        from ssbench.passes.ao.ssao import HemisphereSSAOParams
        anchor = ssao_anchor(g, HemisphereSSAOParams(kernel_radius=0.5))
    elif (effect, method) == ("ssr", "linear"):
        from ssbench.passes.ssr.linear import LinearSSRParams
        anchor = linear_ssr_anchor(g, LinearSSRParams())
    else:
        return float("nan")
    if anchor is None:
        return float("nan")
    ratios = [timeit_calls(call, 3) / timeit_calls(anchor, 3) for _ in range(max(3, rounds))]
    return statistics.median(ratios)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default=SIZES)
    ap.add_argument("--effects", default="ao,ssr")
    ap.add_argument("--methods", default="", help="comma-separated subset (default: every declared method)")
    ap.add_argument("--compile", action="store_true", help="also time torch.compile(pass)")
    ap.add_argument("--min-run-time", type=float, default=1.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=9, help="timing rounds (>= 3; a slow pass gets at least 9 "
                    "unless fewer are asked for)")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    ap.add_argument("--one", nargs=3, metavar=("EFFECT", "METHOD", "GBUFFER"), help=argparse.SUPPRESS)
    ap.add_argument("--compiled", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    from ssbench.bench.timing import TimingSpec, TimingSpecError
    try:                                            # the timing arguments, checked before any G-buffer is rendered
        TimingSpec(min_run_time=a.min_run_time, warmup=1, rounds=a.rounds)
    except TimingSpecError as e:
        ap.error(f"--{e.field.replace('_', '-')}: {e.reason}")
    if a.one:
        print(json.dumps(one(*a.one, a.compiled, a.min_run_time, a.threads, a.rounds)))
        return 0
    import torch

    from ssbench.reference import gbuffer
    sizes = [tuple(int(v) for v in s.split("x")) for s in a.sizes.split(",")]
    wanted = set(filter(None, a.methods.split(",")))
    rows = []
    print(f"torch {torch.__version__}, {a.threads} thread(s), min_run_time {a.min_run_time} s; "
          f"floor× / fused× = pass / torch gather / Dr.Jit fused gather of as many texels per pixel (median of {a.rounds} rounds ± IQR)")
    name = 1 + max([16] + [len(m) for e in a.effects.split(",") for m in _methods(e)])   # the pass column's width
    head = (f"{'pass':<{name}}{'size':>10}{'mode':>9}{'ms':>10}{'ns/px':>8}{'ns/read':>8}{'floor×':>13}{'fused×':>8}{'anchor×':>8}"
            f"{'reads':>6}{'peak MiB':>9}")
    head += f"{'compile s':>10}{'Δ eager':>9}" if a.compile else ""
    print(head)
    with tempfile.TemporaryDirectory() as tmp:
        for effect in a.effects.split(","):
            for w, h in sizes:
                path = os.path.join(tmp, f"{effect}_{w}x{h}.pt")
                chans = ("view_z", "normal", "position", "mask") + (("color", "roughness") if effect == "ssr" else ())
                torch.save(gbuffer(SCENES[effect], w, h, chans, spp=4, use_cache=True), path)
                for method in _methods(effect):
                    if wanted and method not in wanted:
                        continue
                    for compiled in (False, True) if a.compile else (False,):
                        cmd = [sys.executable, __file__, "--one", effect, method, path, "--threads", str(a.threads),
                               "--min-run-time", str(a.min_run_time), "--rounds", str(a.rounds)] + (["--compiled"] if compiled else [])
                        r = subprocess.run(cmd, capture_output=True, text=True)
                        if r.returncode:
                            print(f"{method:<{name}}{w}x{h:>5}  failed: {r.stderr.strip().splitlines()[-1:]}")
                            continue
                        row = json.loads(r.stdout.strip().splitlines()[-1])
                        rows.append(row)
                        line = (f"{method:<{name}}{row['size']:>10}{row['mode']:>9}{row['ms']:>10.1f}{row['ns_px']:>8.0f}"
                                f"{row['ns_read']:>8.1f}"
                                f"{row['floor_ratio']:>7.1f} ±{row['floor_ratio_iqr']:<4.1f}"
                                f"{row['fused_floor_ratio']:>8.1f}{row['anchor_ratio']:>8.1f}{row['samples']:>6}"
                                f"{row['peak_mib']:>9.0f}")
                        if a.compile:
                            line += (f"{row['first_call_s']:>10.1f}{row['max_diff_eager']:>9.1e}" if compiled else "")
                        print(line, flush=True)
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
