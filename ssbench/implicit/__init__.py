"""Implicit surfaces f(p) = 0 (seed 004): a safe expression language, evaluators, surfaces and scenes.

- ``ast.py``: the scalar expression tree every evaluator walks.
- ``parser.py``: whitelist parser (never ``eval``) from text to the tree; vectors and helpers are lowered.
- ``torch_eval.py``, ``interval.py``, ``drjit_eval.py``: the three evaluators of one tree.
- ``expression.py``: :class:`Expression`, the parsed text with its parameters and the three evaluators.
- ``surface.py``, ``scene.py``, ``schema.py``, ``catalog.py``: objects with bounds / material / Lipschitz
  bound, scenes with lights, camera and animation, scene files, and the built-in hard cases.
"""
