"""``ssbench info``, ``scenes``, ``render`` and ``report``."""
from __future__ import annotations

import json
import os
import time

from ._args import UsageError, guard_work, out_dir


def cmd_info(args) -> int:
    from ..runinfo import environment
    env = environment()
    if args.json:
        print(json.dumps(env, indent=2))
        return 0
    llvm = f"{env['libllvm']} (major {env['libllvm_major']})" if env["libllvm"] else "none"
    lines = [("ssbench", env["ssbench"]), ("python", f"{env['python']} ({env['python_executable']})"),
             ("torch", f"{env['torch']} ({env['torch_threads']} threads)"), ("kornia", env["kornia"]),
             ("numpy", env["numpy"]), ("mitsuba variant", f"{env['variant']} ({env['backend_reason']})"),
             ("libLLVM", llvm), ("mitsuba", env["mitsuba"]),
             ("drjit", f"{env['drjit']} ({env['drjit_threads']} threads)"),
             ("machine", f"{env['node']}, {env['processor']}, {env['cpu_count']} CPUs")]
    for k, v in lines:
        print(f"{k:<16} {v}")
    print("probe attempts:")
    for cand, outcome in env["probe"]:
        print(f"  {cand}: {outcome}")
    return 0


def cmd_scenes(args) -> int:
    from ..scenes import catalog
    desc = catalog.describe()
    if args.json:
        print(json.dumps([{"name": n, "description": d} for n, d in desc.items()], indent=2))
        return 0
    width = max(len(n) for n in desc)
    print(f"{'name':<{width}}  description")
    print(f"{'-' * width}  {'-' * 11}")
    for n, d in desc.items():
        print(f"{n:<{width}}  {d}")
    return 0


def load_scene(arg: str, defines=()):
    """The scene a command names (``-D`` overrides for a Mitsuba file); a usage error naming SCENE otherwise."""
    from ..scenes import SceneError, catalog, load
    try:
        return load(arg, defines)
    except SceneError as e:
        raise UsageError(f"argument SCENE: {e}") from None
    except (KeyError, ValueError, FileNotFoundError, OSError) as e:
        why = e.args[0] if e.args else str(e)
        if arg not in catalog.CATALOG and not os.path.exists(arg):
            why = f"{arg!r} is neither a built-in scene nor an existing scene file"
        raise UsageError(f"argument SCENE: {why}; built-in scenes: {', '.join(catalog.names())}") from None


def cmd_render(args) -> int:
    from .. import io
    from ..reference import backend
    from ..report.build import render_scene
    sc = load_scene(args.scene, args.defines)
    guard_work(force=args.force, width=args.width or sc.camera.width, height=args.height or sc.camera.height)
    out_dir(args.out)
    t_start = time.perf_counter()
    info = backend.info()                                    # probe + import Mitsuba outside the timings
    backend_init_s = time.perf_counter() - t_start
    g, timings = render_scene(sc, args.width, args.height, args.channels, spp=args.spp, seed=args.seed,
                              use_cache=not args.no_cache)
    t0 = time.perf_counter()
    os.makedirs(args.out, exist_ok=True)
    files = []
    for ch in args.channels:
        t = getattr(g, ch)
        io.write_exr(os.path.join(args.out, f"{ch}.exr"), t[0])
        io.preview_png(os.path.join(args.out, f"{ch}.png"), ch, t, mask=g.mask, camera=g.camera)
        files += [f"{ch}.exr", f"{ch}.png"]
    timings["write_s"] = time.perf_counter() - t0
    timings["backend_init_s"] = backend_init_s
    timings["total_s"] = time.perf_counter() - t_start
    from dataclasses import asdict
    meta = {"scene": sc.name, "scene_arg": args.scene, "description": sc.description,
            "camera": asdict(g.camera), "channels": list(args.channels), "spp": args.spp, "seed": args.seed,
            "use_cache": not args.no_cache, "timings": timings, "backend": info, "files": files}
    tmp = os.path.join(args.out, ".meta.json.tmp")
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(meta, f, indent=2, default=str)
        f.write("\n")
    os.replace(tmp, os.path.join(args.out, "meta.json"))
    print(f"{sc.name} {g.width}x{g.height}: G-buffer {timings['gbuffer_s']:.3f} s"
          + (f", colour {timings['color_s']:.3f} s" if timings["color_s"] is not None else "")
          + f"; wrote {len(files) + 1} files to {args.out}")
    return 0




def cmd_report(args) -> int:
    if args.compare:
        from ..report.compare import cmd_compare
        return cmd_compare(args, args.report_parser)
    if args.from_run:
        from ..report.render import render_run
        from ..report.compare import resolve_run
        building = [d for d, v in vars(args).items() if d not in ("command", "out", "from_run", "report_parser",
                                                                   "screenshots", "compile")   # compile: global
                    and v != args.report_parser.get_default(d)]
        if building:
            args.report_parser.error("--from cannot be combined with report-building options "
                                     f"({', '.join('--' + d.replace('_', '-') for d in building)})")
        index = render_run(resolve_run(args.from_run, os.path.abspath(args.out), 'RUN'))
        print(f"report: {index}")
        return _screenshots(index) if args.screenshots else 0
    from ..report.build import build_report
    out_dir(args.out)
    off = lambda flag: False if flag else None                # noqa: E731  (None: the section's default)
    extra = []                                               # loaded here (once), so a bad file is a usage error
    for f in args.extra_scenes:                              # before any work
        if not os.path.isfile(f):
            raise UsageError(f"argument --scene: {f!r} is not a scene file")
        extra.append(load_scene(f))
    index = build_report(args.out, scenes=args.scenes, extra_scenes=extra, width=args.width, height=args.height, spp=args.spp,
                         seed=args.seed, use_cache=not args.fresh_previews, gt_cache=not args.no_gt_cache, ao=not args.no_ao,
                         ao_radius=args.ao_radius, ao_rays=args.ao_rays, ssr=not args.no_ssr, ssr_spp=args.ssr_spp,
                         implicit=off(args.no_implicit), speed=off(args.no_speed), tuning=off(args.no_tuning),
                         calibration=off(args.no_calibration), time_axis=off(args.no_time),
                         glossy=off(args.no_glossy))
    print(f"report: {index}")
    print(f"latest: {os.path.join(os.path.abspath(args.out), 'latest', 'index.html')}")
    return _screenshots(index) if args.screenshots else 0


def _screenshots(index: str) -> int:
    """``--screenshots``: one PNG per section of the run's page (a missing Chromium is a one-line error)."""
    from ..report.screenshots import section_screenshots
    shots = section_screenshots(index)
    if not shots:
        raise RuntimeError("screenshots: Chromium wrote no screenshot")
    print(f"screenshots: {len(shots)} sections in {os.path.dirname(next(iter(shots.values())))}")
    return 0
