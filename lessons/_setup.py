"""Lesson settings, and nothing else: the image size, read from one environment variable.

``SSBENCH_LESSON_SIZE`` picks the resolution every lesson renders at:

* ``full`` (the default, for people): the scene's own size, 320 × 240;
* ``small`` (what ``tests/lessons`` sets, for CI): half of it, 160 × 120;
* ``WxH``, e.g. ``640x480``: any size you like.

No ssbench call hides here: the lessons call the library themselves, in plain sight.
"""
from __future__ import annotations

import os

import matplotlib.pyplot as plt

SETTING = os.environ.get("SSBENCH_LESSON_SIZE", "full").strip().lower()
SMALL = SETTING == "small"

plt.rcParams["figure.max_open_warning"] = 0      # headless runs keep every figure open; that is fine


def size(full: tuple[int, int] = (320, 240)) -> tuple[int, int]:
    """``(width, height)`` to render at: ``full``, half of it when small, or the ``WxH`` asked for."""
    if SETTING in ("", "full"):
        return full
    if SETTING == "small":
        return full[0] // 2, full[1] // 2
    try:
        w, h = (int(v) for v in SETTING.split("x"))
    except ValueError:
        raise ValueError(f"SSBENCH_LESSON_SIZE: expected 'full', 'small' or 'WxH', got {SETTING!r}") from None
    return w, h


def pick(full, small):
    """``small`` in small (CI) runs, ``full`` otherwise: for sample counts that only cost time."""
    return small if SMALL else full
