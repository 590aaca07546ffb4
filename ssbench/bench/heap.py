"""Keep a timed pass's memory behaviour the same from run to run: glibc's heap thresholds held while timing.

:func:`steady_heap` is the first step of the timing protocol (:mod:`ssbench.bench.timing`): without it glibc's
malloc page-faults a pass's temporaries on every call or not, depending on what the process ran before.
"""
from __future__ import annotations

import contextlib
import ctypes
from typing import Any, Iterator

__all__ = ["steady_heap", "SETTLED_MMAP", "SETTLED_TRIM", "TIMING_TRIM"]


#: glibc ``mallopt`` parameters
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: where glibc's dynamic thresholds settle on 64-bit once a block of 32 MiB was freed (mmap 32 MiB, trim 2x)
SETTLED_MMAP, SETTLED_TRIM = 32 << 20, 64 << 20
#: the trim threshold while timing: the largest ``mallopt`` takes, so freed heap stays with the process
TIMING_TRIM = (1 << 31) - 1


def _glibc() -> Any:
    """glibc's ``mallopt``/``malloc_trim`` (an object with both), or ``None`` off glibc."""
    try:
        libc = ctypes.CDLL(None)
        libc.mallopt, libc.malloc_trim                                        # noqa: B018 - probe
        return libc
    except (OSError, AttributeError, TypeError):
        return None


@contextlib.contextmanager
def steady_heap() -> Iterator[bool]:
    """Keep freed heap memory in the process for the ``with`` block; yields whether it could (glibc only).

    glibc's malloc serves blocks above its *mmap threshold* from fresh pages and gives freed heap above its
    *trim threshold* back to the kernel; both thresholds grow with the largest block the process has freed so far.
    So one pass either reuses memory or page-faults all of its temporaries on every call (2-4x slower for a large
    gather), depending on what the process did before, and two runs of one configuration disagree far beyond
    their IQR. Inside the block, blocks up to 32 MiB come from the heap and freed heap is kept (up to 2 GiB;
    larger blocks page-fault on every call, the same in every run); on leaving, the thresholds
    are where glibc's own adjustment settles (:data:`SETTLED_MMAP`, :data:`SETTLED_TRIM`; ``mallopt`` cannot
    switch the adjustment back on) and ``malloc_trim(0)`` returns the free memory to the kernel.
    """
    libc = _glibc()
    ok = libc is not None and libc.mallopt(_M_MMAP_THRESHOLD, SETTLED_MMAP) == 1 \
        and libc.mallopt(_M_TRIM_THRESHOLD, TIMING_TRIM) == 1
    try:
        yield ok
    finally:
        if ok:
            libc.mallopt(_M_TRIM_THRESHOLD, SETTLED_TRIM)
            libc.malloc_trim(0)
