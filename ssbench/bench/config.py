"""Sweep files (YAML or TOML) → a validated :class:`Sweep`: the cartesian list of :class:`Config` to run.

Format (YAML shown; TOML carries the same keys, e.g. ``[methods.hbao]`` tables)::

    name: ao_small                       # optional (default: the file's stem)
    effect: ao                           # a key of ssbench.bench.effects.EFFECTS: ao | ssr
    scenes: [sphere_on_plane, crease]    # catalog names or scene files (relative to this file)
    methods:
      hbao:                              # a method of the effect; each parameter a grid
        radius: [0.25, 0.5, 1.0]         #   a list of values
        num_directions: {range: [4, 16, 4]}   #   start, stop, step, both ends included: 4, 8, 12, 16
        num_steps: {logrange: [2, 16, 4]}     #   lo, hi, n geometric points (ints for int parameters)
      gtao: {quality: [low, high]}
      ssao:                              # nothing: the defaults
      dda: [{pixel_stride: [1, 4]}, {fit_stride_to_steps: true}]   # a list of grids: their union
    seeds: [0, 1]                        # default [0]
    resolution: [320, 240]               # [W, H] or a list of them; default [320, 240]
    rays: 64                             # the effect's settings (ssbench.bench.effects), each a value or grid
    threads: 1                           # torch threads per configuration (default 1), also a grid
    timing: {min_run_time: 0.2}          # optional: time each pass and its gather floor (ssbench.bench.timing;
                                         #   also warmup, floor, rounds, interleave, processes: the fields of its
                                         #   TimingSpec)
    images: true                         # optional: also write each configuration's image and error map
                                         #   (ssbench.bench.pictures; not part of config_id)

A value that is itself a list (a GTAO noise tile) is given as ``{values: [[...]]}``. Every error is a
:class:`SweepError` reading ``file:line: field.path: what is wrong`` (the scene files' machinery,
:mod:`ssbench.scenes.files`); unknown effects, methods, parameters and settings list the valid names.
Each configuration's ``config_id`` hashes its canonical form (:meth:`Config.canonical`): the parameters as
given (coerced to the field types), not the resolved defaults, so ids stay comparable across commits.
"""
from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import os
import re
from typing import Any, Mapping, Optional

from ..scenes.files import read_text, read_toml, read_yaml
from ..scenes.model import SceneError
from .effects import EFFECTS, Effect, get_effect
from .grids import (SweepError, coerce_value, dedupe, field_kinds, grid_values, names_hint, SweepCtx, expand_logrange,
                    expand_range)
from .timing import TimingSpec

__all__ = ["SweepError", "Config", "Sweep", "load_sweep", "parse_sweep", "sweep_from_dict", "config_id",
           "expand_range", "expand_logrange"]

_TOP = {"name", "description", "effect", "scenes", "methods", "seeds", "resolution", "timing", "images"}


def config_id(canonical: Mapping) -> str:
    """16 hex digits of the SHA-256 of ``canonical`` as sorted, compact JSON.

    Example:
        >>> config_id({"b": 1, "a": [0.5]}) == config_id({"a": [0.5], "b": 1}), len(config_id({}))
        (True, 16)
    """
    text = json.dumps(canonical, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclasses.dataclass(frozen=True)
class Config:
    """One point of a sweep: the arguments of one evaluation. ``config_id`` is computed from the rest."""

    effect: str
    scene: str                      # as written: a catalog name or a scene file path
    method: str
    params: Mapping[str, Any]       # the overrides of this grid point (coerced), sorted by name
    seed: int
    width: int
    height: int
    settings: Mapping[str, Any]     # every setting of the effect (COMMON_SETTINGS included)
    scene_file: Optional[str] = None     # absolute path of a scene file (not hashed: machines differ)
    scene_sha256: Optional[str] = None   # its content hash (hashed)
    config_id: str = dataclasses.field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "config_id", config_id(self.canonical()))

    def __hash__(self) -> int:
        return hash(self.config_id)

    def canonical(self) -> dict:
        """The plain dict ``config_id`` hashes (also stored as the row's ``config``)."""
        out = {"effect": self.effect, "scene": self.scene, "method": self.method, "params": dict(self.params),
               "seed": self.seed, "width": self.width, "height": self.height, "settings": dict(self.settings)}
        if self.scene_sha256 is not None:
            out["scene_sha256"] = self.scene_sha256
        return out


@dataclasses.dataclass(frozen=True)
class Sweep:
    """A validated sweep: its configurations in expansion order (scene, method, grid, resolution, settings,
    seed), the timing block (``None``: no timing), whether each configuration's pictures are written
    (``images``) and where it came from."""

    name: str
    effect: str
    configs: tuple
    timing: Optional[TimingSpec]
    source: str
    sha256: str
    description: str = ""
    images: bool = False

    def __len__(self) -> int:
        return len(self.configs)

    def ids(self) -> list[str]:
        return [c.config_id for c in self.configs]


def _method_grids(c: SweepCtx, effect: Effect, name: str, v: Any) -> list[dict]:
    """The method's parameter combinations (dicts of coerced overrides), each checked by its params class."""
    path = ("methods", name)
    fn, params_cls, _ = effect.method(name)
    kinds = field_kinds(params_cls)
    grids = v if isinstance(v, list) else [v]
    if not grids:
        raise c.fail(path, "empty list of grids")
    combos: list[dict] = []
    for gi, grid in enumerate(grids):
        gpath = path + (gi,) if isinstance(v, list) else path
        grid = {} if grid is None else c.mapping(grid, gpath)
        axes, where = [], {}                    # where[name][value as JSON] = path of that value in the file
        for pname, pv in grid.items():
            if pname not in kinds:
                raise c.fail(gpath + (pname,), f"unknown parameter {pname!r} for {effect.name} method {name!r}"
                             f"{names_hint(pname, kinds)}; valid: {', '.join(kinds)}")
            where[pname] = {}

            def check(x, p, kind=kinds[pname], seen=where[pname]):
                v = coerce_value(c, x, kind, p)
                seen.setdefault(json.dumps(v, sort_keys=True), p)
                return v
            check.integer = kinds[pname][0] is int
            axes.append([(pname, x) for x in grid_values(c, pv, gpath + (pname,), check)])
        for combo in itertools.product(*axes):
            overrides = dict(sorted(combo))
            try:
                params_cls(**overrides)
            except (ValueError, TypeError) as e:
                field = str(e).split(":", 1)[0]
                bad = where[field].get(json.dumps(overrides[field], sort_keys=True), gpath + (field,)) \
                    if field in overrides else gpath
                raise c.fail(bad, f"{params_cls.__name__} rejects {overrides}: {e}") from None
            combos.append(overrides)
    return combos


def _scenes(c: SweepCtx, effect: Effect, v: Any,
            base_dir: Optional[str]) -> list[tuple[str, Optional[str], Optional[str]]]:
    """``(as written, absolute file or None, file sha256 or None)`` per scene; each file is loaded once to
    check it (with the effect's loader)."""
    from ..scenes.schema import file_sha256
    builtin = effect.builtin_scenes()
    names = grid_values(c, v, ("scenes",), lambda x, p: c.text(x, p))
    out = []
    for s in names:
        path = ("scenes", v.index(s)) if isinstance(v, list) else ("scenes",)
        if s in builtin:
            out.append((s, None, None))
            continue
        full = s if os.path.isabs(s) else os.path.join(base_dir or os.getcwd(), s)
        if not os.path.isfile(full):
            raise c.fail(path, f"unknown scene {s!r}{names_hint(s, builtin)}; built-in: {', '.join(builtin)}; "
                         f"or a scene file")
        try:
            effect.check_scene_file(full)
        except (ValueError, KeyError) as e:               # SceneError is a ValueError
            raise c.fail(path, f"invalid scene file: {e}") from None
        out.append((s, os.path.abspath(full), file_sha256(full)))
    return out


def _resolutions(c: SweepCtx, v: Any) -> list[tuple[int, int]]:
    path = ("resolution",)
    pairs = v if isinstance(v, list) and v and all(isinstance(x, list) for x in v) else [v]
    out = []
    for i, r in enumerate(pairs):
        p = path + (i,) if pairs is v else path
        if not isinstance(r, list) or len(r) != 2:
            raise c.fail(p, f"expected [width, height] or a list of them, got {r!r}")
        out.append((c.integer(r[0], p + (0,), 1), c.integer(r[1], p + (1,), 1)))
    return dedupe(out)


def _timing(c: SweepCtx, v: Any) -> Optional[TimingSpec]:
    if v is None or v is False:
        return None
    if v is True:
        return TimingSpec()
    d = c.mapping(v, ("timing",))
    fields = [f.name for f in dataclasses.fields(TimingSpec)]
    c.keys(d, set(fields), ("timing",))
    try:
        return TimingSpec(**d)
    except ValueError as e:
        field = str(e).split(":", 1)[0]
        raise c.fail(("timing", field) if field in d else ("timing",), str(e).split(":", 1)[-1].strip()) from None


def sweep_from_dict(data: Any, locate=None, source: str = "<dict>", base_dir: Optional[str] = None,
                    sha256: Optional[str] = None) -> Sweep:
    """Validate plain data into a :class:`Sweep`; errors name ``file:line`` (via ``locate``) and the field."""
    c = SweepCtx(locate or (lambda path: source), base_dir)
    d = c.mapping(data, ())
    if "effect" not in d:
        raise c.fail(("effect",), f"missing required field (one of: {', '.join(EFFECTS)})")
    if d["effect"] not in EFFECTS:
        raise c.fail(("effect",), f"unknown effect {d['effect']!r}; valid: {', '.join(EFFECTS)}")
    effect = get_effect(d["effect"])
    settings_spec = effect.all_settings()
    c.keys(d, _TOP | set(settings_spec), ())
    for key in ("scenes", "methods"):
        if key not in d:
            raise c.fail((key,), "missing required field")
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", os.path.splitext(os.path.basename(source))[0]).lstrip(".") or "sweep"
    name = c.text(d.get("name", stem), ("name",))
    if not re.fullmatch(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*", name):
        raise c.fail(("name",), f"use letters, digits, '_', '-', '.' (it names the output folder), got {name!r}")
    description = d.get("description", "")
    if not isinstance(description, str):
        raise c.fail(("description",), "expected a string")
    scenes = _scenes(c, effect, d["scenes"], base_dir)
    methods = d["methods"]
    if isinstance(methods, list):                       # a plain list of names: their defaults
        methods = {c.text(m, ("methods", i)): None for i, m in enumerate(methods)}
    methods = c.mapping(methods, ("methods",))
    if not methods:
        raise c.fail(("methods",), f"empty (valid: {', '.join(effect.method_names())})")
    valid = effect.method_names()
    grids = {}
    for m, mv in methods.items():
        if m not in valid:
            raise c.fail(("methods", m), f"unknown {effect.name} method {m!r}{names_hint(m, valid)}; "
                         f"valid: {', '.join(valid)}")
        grids[m] = _method_grids(c, effect, m, mv)
    seeds = grid_values(c, d.get("seeds", [0]), ("seeds",), lambda x, p: c.integer(x, p, 0))
    resolutions = _resolutions(c, d.get("resolution", [320, 240]))
    axes = []
    for key, spec in settings_spec.items():
        def check(x, p, spec=spec):
            try:
                return spec.check(x)
            except ValueError as e:
                raise c.fail(p, str(e)) from None
        check.integer = spec.types == (int,)
        axes.append([(key, x) for x in grid_values(c, d.get(key, spec.default), (key,), check)])
    timing = _timing(c, d.get("timing"))
    images = c.boolean(d.get("images", False), ("images",))
    configs, seen = [], set()
    for (scene, sfile, ssha), (method, combos) in itertools.product(scenes, grids.items()):
        for params, (w, h), settings, seed in itertools.product(combos, resolutions, itertools.product(*axes),
                                                                seeds):
            cfg = Config(effect.name, scene, method, params, seed, w, h, dict(settings), sfile, ssha)
            if cfg.config_id not in seen:
                seen.add(cfg.config_id)
                configs.append(cfg)
    if sha256 is None:
        sha256 = hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()
    return Sweep(name, effect.name, tuple(configs), timing, source, sha256, description, images)


def _read(text: str, filename: str, fmt: str):
    """``(data, locate)`` of YAML/TOML text via the scene files' readers (errors become :class:`SweepError`)."""
    try:
        if fmt == "toml":
            return read_toml(text, filename)
        return read_yaml(text, filename)
    except SceneError as e:                              # already "file:line: ..."
        raise SweepError(str(e).replace("empty scene file", "empty sweep file")) from None


def parse_sweep(text: str, filename: str = "<sweep>", fmt: Optional[str] = None,
                base_dir: Optional[str] = None) -> Sweep:
    """Parse sweep text (``fmt`` ``"yaml"`` or ``"toml"``; default from ``filename``'s extension, else YAML)."""
    fmt = fmt or ("toml" if filename.lower().endswith(".toml") else "yaml")
    if fmt not in ("yaml", "toml"):
        raise ValueError(f"fmt: expected 'yaml' or 'toml', got {fmt!r}")
    data, locate = _read(text, filename, fmt)
    if data is None or data == {}:
        raise SweepError(f"{filename}:1: empty sweep file")
    return sweep_from_dict(data, locate, filename, base_dir, hashlib.sha256(text.encode()).hexdigest())


def load_sweep(path: "str | os.PathLike") -> Sweep:
    """Load a ``.yaml``/``.yml`` or ``.toml`` sweep file (scene files in it are relative to its folder)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise SweepError(f"config: sweep file not found: {path}")
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".yaml", ".yml", ".toml"):
        raise SweepError(f"{path}:1: unknown sweep file type {ext!r} (use .yaml, .yml or .toml)")
    try:
        text = read_text(path)
    except SceneError as e:
        raise SweepError(str(e)) from None
    return parse_sweep(text, path, "toml" if ext == ".toml" else "yaml", os.path.dirname(os.path.abspath(path)))
