"""Implicit surfaces f(p) = 0 (progressive-tracing article): a safe expression language, evaluators, surfaces and scenes.

- ``ast.py``: the scalar expression tree every evaluator walks.
- ``parser.py``: whitelist parser (never ``eval``) from text to the tree;
  ``lowering.py``: what its functions mean (vectors and helpers lowered to scalar trees, constants folded).
- ``torch_eval.py``, ``interval.py``, ``drjit_eval.py``: the three evaluators of one tree.
- ``expression.py``: :class:`Expression`, the parsed text with its parameters and the three evaluators.
- ``surface.py``, ``union.py``, ``scene.py``, ``schema.py``, ``catalog.py``: objects with bounds / material /
  Lipschitz bound, their union (the surface the casters read), scenes with lights, camera and animation,
  scene files, and the built-in hard cases.
"""
from __future__ import annotations

from . import catalog
from .expression import Expression, parse
from .parser import ExpressionError
from .scene import Animation, ImplicitScene, Segment, load
from .schema import scene_from_dict, scene_from_file, scene_from_toml, scene_from_yaml
from .surface import ImplicitObject, expression_key
from .union import ImplicitSurface

__all__ = ["Expression", "parse", "ExpressionError", "ImplicitObject", "ImplicitSurface", "expression_key",
           "ImplicitScene", "Animation", "Segment", "load", "scene_from_dict", "scene_from_yaml",
           "scene_from_toml", "scene_from_file", "catalog"]
