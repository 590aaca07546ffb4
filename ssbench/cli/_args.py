"""Argument types and errors of the ``ssbench`` command line (argparse ``type=`` callables name the argument)."""
from __future__ import annotations

import argparse
import math
import sys

from ..gbuffer import CHANNELS


class UsageError(Exception):
    def __init__(self, message: str, status: int = 2):
        super().__init__(message)
        self.status = status


class Parser(argparse.ArgumentParser):
    """argparse that reports errors as ``ssbench: error: ...`` and raises instead of exiting."""

    def error(self, message: str):  # type: ignore[override]
        self.print_usage(sys.stderr)
        raise UsageError(message)


def _int_at_least(lo: int, what: str, why: str = "", name: str = "int"):
    """argparse type: an integer >= ``lo``; errors read ``expected <what>[<why>], got ...``."""
    def parse(s: str) -> int:
        try:
            v = int(s)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {s!r}") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"expected {what}{why}, got {v}")
        return v
    parse.__name__ = name
    return parse


def positive(name: str):
    return _int_at_least(1, "a positive integer", name=name)


non_negative = _int_at_least(0, "a non-negative integer", name="non_negative")
gt_rays = _int_at_least(2, "an integer >= 2", " (for a standard error)", name="rays")


def channels_arg(s: str) -> tuple[str, ...]:
    chans = tuple(dict.fromkeys(c.strip() for c in s.split(",") if c.strip()))
    unknown = [c for c in chans if c not in CHANNELS]
    if unknown or not chans:
        raise argparse.ArgumentTypeError(f"unknown or empty channel list {list(unknown or chans)}; "
                                         f"known channels: {','.join(CHANNELS)}")
    return chans


def scene_list(s: str) -> list[str]:
    from ..scenes import catalog
    names = [n.strip() for n in s.split(",") if n.strip()]
    unknown = [n for n in names if n not in catalog.CATALOG]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown or empty scene list {unknown or names}; built-in scenes: "
                                         f"{', '.join(catalog.names())}")
    return names


def positive_float(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {s!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {s!r}")
    return v


def non_negative_float(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {s!r}")
    return v


def size_arg(s: str) -> tuple[int, int]:
    w, sep, h = s.lower().partition("x")
    try:
        size = (int(w), int(h))
    except ValueError:
        size = None
    if not sep or size is None or min(size) < 1:
        raise argparse.ArgumentTypeError(f"expected WxH with two positive integers (e.g. 96x72), got {s!r}")
    return size


_BOOLS = {"true": True, "yes": True, "on": True, "false": False, "no": False, "off": False}


def parse_value(text: str):
    """A ``--param`` value as bool (true/false/yes/no/on/off), int, float or else str; never ``eval``."""
    t = text.strip()
    if t.lower() in _BOOLS:
        return _BOOLS[t.lower()]
    try:
        return int(t, 10)
    except ValueError:
        pass
    try:
        v = float(t)
    except ValueError:
        return t
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"value {text!r} is not a finite number")
    return v


def param_arg(s: str) -> tuple[str, object]:
    name, sep, value = s.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier() or not value.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE (e.g. radius=0.5), got {s!r}")
    return name, parse_value(value)


def define_arg(s: str) -> tuple[str, str]:
    """``-D NAME=VALUE``: a Mitsuba scene parameter override, kept as text (Mitsuba parses it)."""
    name, sep, value = s.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE (e.g. spp=16), got {s!r}")
    return name, value.strip()


def coerce_params(params_cls, pairs, method: str) -> dict:
    """``--param`` pairs checked against the pass's params dataclass: known names, no repeats, and values
    of the default's type (an int is accepted for a float; anything else is an error naming the parameter)."""
    import dataclasses
    defaults = params_cls()
    known = {f.name: getattr(defaults, f.name) for f in dataclasses.fields(params_cls)}
    out: dict = {}
    for name, value in pairs:
        if name not in known:
            raise UsageError(f"argument --param: unknown parameter {name!r} for {method}; "
                              f"known: {', '.join(known)}")
        if name in out:
            raise UsageError(f"argument --param: {name} given twice")
        d = known[name]
        if isinstance(d, bool):
            ok = isinstance(value, bool)
        elif isinstance(d, int):
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif isinstance(d, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            value = float(value) if ok else value
        elif isinstance(d, str):
            ok, value = True, str(value)
        else:
            ok = d is None or isinstance(value, type(d))
        if not ok:
            raise UsageError(f"argument --param: {name} expects {type(d).__name__} (default {d!r}), "
                              f"got {value!r}")
        out[name] = value
    return out


def write_row_json(out_dir: str, row: dict) -> str:
    """``out_dir/row.json`` of an evaluation row, written atomically (:func:`ssbench.io.write_atomic`)."""
    import json
    import os

    from ..io import write_atomic

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(row, f, indent=2, default=str)
            f.write("\n")
    return write_atomic(os.path.join(out_dir, "row.json"), ".json", write)


#: work above these limits is refused unless ``--force`` (documented in ``ssbench/RELIABILITY.md``): an image
#: of more pixels than 8192×8192, more ground-truth rays in all than 2^30 (Dr.Jit arrays stop at 2^32
#: entries) or more implicit frames than 10 000 is far more likely a typo than a plan
LIMITS = {"pixels": 8192 * 8192, "rays": 2 ** 30, "frames": 10_000}


def guard_work(*, force: bool, width: int, height: int, rays: int = 1, frames: int = 1,
               size_args: str = "--width/--height", rays_arg: str = "--rays") -> None:
    """Refuse work above :data:`LIMITS` with a usage error naming the argument, unless ``force``."""
    if force:
        return
    px = int(width) * int(height)
    if px > LIMITS["pixels"]:
        raise UsageError(f"argument {size_args}: {width}x{height} = {px:.3g} pixels exceeds the limit of "
                          f"{LIMITS['pixels']:.3g} (8192x8192); pass --force to try anyway")
    if px * int(rays) > LIMITS["rays"]:
        raise UsageError(f"argument {rays_arg}: {rays} rays x {px} pixels = {px * int(rays):.3g} exceeds the "
                          f"limit of {LIMITS['rays']:.3g} rays; lower it or pass --force")
    if int(frames) > LIMITS["frames"]:
        raise UsageError(f"argument --frames: {frames} exceeds the limit of {LIMITS['frames']}; "
                          f"pass --force to run them anyway")


def out_dir(path: str, arg: str = "--out") -> str:
    """Create the output folder ``path`` up front (before any work), or raise a usage error naming ``arg``."""
    import os
    if os.path.exists(path) and not os.path.isdir(path):
        raise UsageError(f"argument {arg}: {path!r} exists and is not a folder")
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as e:
        raise UsageError(f"argument {arg}: cannot create {path!r}: {e.strerror or e}") from None
    if not os.access(path, os.W_OK):
        raise UsageError(f"argument {arg}: {path!r} is not writable")
    return path
