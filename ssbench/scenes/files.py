"""Scene files: YAML and TOML (Mitsuba XML is loaded by Mitsuba: ``ssbench.reference.mitsuba_file``). Data only,
never code.

YAML is read with PyYAML's *safe* loader (no object tags), TOML with ``tomllib``. Both keep track of the line
of every key so that validation errors read ``path/to/scene.yaml:12: shapes[1].radius: must be > 0``.
:func:`read_yaml`, :func:`read_toml` and :func:`read_data_file` return ``(data, locate)`` so that another
validator (``ssbench.implicit.schema``) reports errors the same way. A document with a top-level
``implicit:`` key is an implicit-surface scene: :func:`parse_yaml` / :func:`parse_toml` (hence
``ssbench.scenes.load``) refuse it with an error that points to ``ssbench.implicit.load``.
"""
from __future__ import annotations

import os
import re
from typing import Any, Callable

import yaml

from .model import Scene, SceneError
from .schema import scene_from_dict

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

Locator = Callable[[tuple], str]


class _LineDict(dict):
    lines: dict
    line: int


class _LineList(list):
    lines: list
    line: int


class _SafeLineLoader(yaml.SafeLoader):
    """Safe loader that records the line of every mapping key and sequence item; duplicate keys are errors."""


def _construct_map(loader: _SafeLineLoader, node: yaml.MappingNode) -> _LineDict:
    loader.flatten_mapping(node)
    out = _LineDict()
    out.lines, out.line = {}, node.start_mark.line + 1
    for k_node, v_node in node.value:
        key = loader.construct_object(k_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(None, None, "unhashable key", k_node.start_mark) from None
        if key in out:
            raise SceneError(f"{loader.name}:{k_node.start_mark.line + 1}: duplicate key {key!r}")
        out[key] = loader.construct_object(v_node, deep=True)
        out.lines[key] = k_node.start_mark.line + 1
    return out


def _construct_seq(loader: _SafeLineLoader, node: yaml.SequenceNode) -> _LineList:
    out = _LineList(loader.construct_object(n, deep=True) for n in node.value)
    out.lines, out.line = [n.start_mark.line + 1 for n in node.value], node.start_mark.line + 1
    return out


_SafeLineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_map)
_SafeLineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_seq)


def _yaml_locator(root: Any, filename: str):
    def locate(path: tuple) -> str:
        line, node = getattr(root, "line", 1), root
        for key in path:
            lines = getattr(node, "lines", None)
            if lines is None:
                break
            try:
                line, node = lines[key], node[key]
            except (KeyError, IndexError, TypeError):
                break
        return f"{filename}:{line}"
    return locate


def read_yaml(text: str, filename: str = "<yaml>") -> tuple[Any, Locator]:
    """Read YAML text (safe loader) into plain data and a locator ``path -> "file:line"``."""
    loader = _SafeLineLoader(text)
    loader.name = filename
    try:
        data = loader.get_single_data()
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line = mark.line + 1 if mark is not None else 1
        raise SceneError(f"{filename}:{line}: malformed YAML: {e.problem or e}") from None
    except yaml.YAMLError as e:
        raise SceneError(f"{filename}:1: malformed YAML: {e}") from None
    finally:
        loader.dispose()
    if data is None:
        raise SceneError(f"{filename}:1: empty scene file")
    return data, _yaml_locator(data, filename)


def _refuse_implicit(data: Any, locate: Locator) -> None:
    if isinstance(data, dict) and "implicit" in data:
        raise SceneError(f"{locate(('implicit',))}: implicit: an implicit-surface scene; "
                         f"load it with ssbench.implicit.load")


def parse_yaml(text: str, filename: str = "<yaml>", base_dir: str | None = None) -> Scene:
    """Parse YAML scene text. Errors name ``filename:line``."""
    data, locate = read_yaml(text, filename)
    _refuse_implicit(data, locate)
    return scene_from_dict(data, locate, filename, base_dir)


# ---------------------------------------------------------------------- TOML
_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r'^\s*("?[A-Za-z0-9_.\-]+"?)\s*=')


def _toml_index(text: str) -> dict[tuple, int]:
    """Map key paths to line numbers by a light scan (tables, arrays of tables, multi-line inline arrays)."""
    index: dict[tuple, int] = {}
    counters: dict[tuple, int] = {}
    table: tuple = ()
    array_key: tuple | None = None
    depth, item = 0, -1
    for lineno, raw in enumerate(text.splitlines(), 1):
        if array_key is not None:                      # inside a multi-line `key = [ ... ]`
            s = raw.strip()
            if s.startswith("{"):
                item += 1
                index[array_key + (item,)] = lineno
            depth += raw.count("[") - raw.count("]")
            if depth <= 0:
                array_key = None
            continue
        m = _HEADER.match(raw)
        if m:
            keys = tuple(k.strip().strip('"') for k in m.group(2).split("."))
            real: tuple = ()
            for j, k in enumerate(keys):
                real += (k,)
                if keys[: j + 1] in counters and (m.group(1) == "[" or j < len(keys) - 1):
                    real += (counters[keys[: j + 1]],)
            if m.group(1) == "[[":
                counters[keys] = counters.get(keys, -1) + 1
                real += (counters[keys],)
            table = real
            index.setdefault(table, lineno)
            continue
        k = _KEY.match(raw)
        if k:
            path = table + tuple(p.strip('"') for p in k.group(1).split("."))
            index[path] = lineno
            rest = raw.split("=", 1)[1]
            if rest.count("[") > rest.count("]"):
                array_key, depth, item = path, rest.count("[") - rest.count("]"), -1
    return index


def read_toml(text: str, filename: str = "<toml>") -> tuple[Any, Locator]:
    """Read TOML text into plain data and a locator ``path -> "file:line"``."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"line (\d+)", str(e))
        raise SceneError(f"{filename}:{m.group(1) if m else 1}: malformed TOML: {e}") from None
    index = _toml_index(text)

    def locate(path: tuple) -> str:
        for n in range(len(path), 0, -1):
            if path[:n] in index:
                return f"{filename}:{index[path[:n]]}"
        return f"{filename}:1"

    return data, locate


def parse_toml(text: str, filename: str = "<toml>", base_dir: str | None = None) -> Scene:
    """Parse TOML scene text. Errors name ``filename:line``."""
    data, locate = read_toml(text, filename)
    _refuse_implicit(data, locate)
    return scene_from_dict(data, locate, filename, base_dir)


def read_text(path: str) -> str:
    """The UTF-8 text of a scene file; a file that is not UTF-8 is a :class:`SceneError` naming file:line:column."""
    with open(path, "rb") as f:
        raw = f.read()
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        col = e.start - (raw.rfind(b"\n", 0, e.start) + 1) + 1
        raise SceneError(f"{path}:{line}: byte 0x{raw[e.start]:02x} at column {col} is not UTF-8; scene files are "
                         f"UTF-8 text (re-save it as UTF-8)") from None


def read_data_file(path: str | os.PathLike) -> tuple[Any, Locator]:
    """Read a ``.yaml``/``.yml`` or ``.toml`` file into plain data and its locator (shared by the validators)."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if not os.path.isfile(path):
        raise FileNotFoundError(f"name_or_path: scene file not found: {path}")
    if ext not in (".yaml", ".yml", ".toml"):
        raise SceneError(f"{path}:1: unknown scene file type {ext!r} (use .yaml, .yml or .toml)")
    text = read_text(path)
    return read_yaml(text, path) if ext in (".yaml", ".yml") else read_toml(text, path)


def load_file(path: str | os.PathLike, defines=()) -> Scene:
    """Load a ``.yaml``/``.yml``, ``.toml`` or Mitsuba 3 ``.xml`` scene file. An ``.xml`` file is loaded by
    Mitsuba itself (:func:`ssbench.reference.mitsuba_file.load_xml`), with ``defines`` (``-D name=value``)
    overriding its ``$name`` parameters; YAML and TOML take no ``defines``."""
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if not os.path.isfile(path):
        raise FileNotFoundError(f"name_or_path: scene file not found: {path}")
    if ext == ".xml":
        from ..reference.mitsuba_file import load_xml      # Mitsuba is imported only for Mitsuba files
        return load_xml(path, defines)
    if defines:
        raise ValueError(f"defines: only Mitsuba .xml scenes take -D overrides, not {os.path.basename(path)}")
    text = read_text(path)
    base = os.path.dirname(os.path.abspath(path))
    if ext in (".yaml", ".yml"):
        return parse_yaml(text, path, base)
    if ext == ".toml":
        return parse_toml(text, path, base)
    raise SceneError(f"{path}:1: unknown scene file type {ext!r} (use .yaml, .yml, .toml or .xml)")
