"""Scenes: the built-in catalog, YAML/TOML/Mitsuba-XML files, and the validated :class:`Scene` model."""
from __future__ import annotations

import os
from typing import Any

from . import catalog
from .files import load_file, parse_toml, parse_yaml
from .model import Light, Material, Scene, SceneError, Shape
from .schema import scene_from_dict

__all__ = ["load", "Scene", "Shape", "Material", "Light", "SceneError", "scene_from_dict", "parse_yaml",
           "parse_toml", "load_file", "catalog"]


def load(name_or_path: "str | os.PathLike | dict[str, Any] | Scene", defines=()) -> Scene:
    """Load a scene from the built-in catalog (by name), a YAML/TOML/Mitsuba XML file, or a plain dict;
    ``defines`` (``-D name=value`` pairs or a dict) override a Mitsuba file's ``$name`` parameters.

    Example:
        >>> load("sphere_on_plane").camera.width
        320
    """
    if defines and not isinstance(name_or_path, (str, os.PathLike)):
        raise ValueError("defines: only Mitsuba .xml scene files take -D overrides")
    if isinstance(name_or_path, Scene):
        return name_or_path
    if isinstance(name_or_path, dict):
        return scene_from_dict(name_or_path)
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise TypeError(f"name_or_path: expected a scene name, a file path or a dict, "
                        f"got {type(name_or_path).__name__}")
    s = os.fspath(name_or_path)
    if s in catalog.CATALOG and not defines:
        return catalog.get(s)
    if os.path.splitext(s)[1].lower() in (".yaml", ".yml", ".toml", ".xml") or os.path.exists(s):
        return load_file(s, defines)
    raise KeyError(f"name_or_path: {s!r} is neither a built-in scene ({', '.join(catalog.CATALOG)}) "
                   f"nor a scene file")
