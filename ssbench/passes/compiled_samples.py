"""How a point-sampling AO pass lays out, groups and bands its samples, eager and compiled (the switch of
:mod:`ssbench.passes.compiled`).

Eager, every torch operation loops over a whole block, so a band kernel runs all of a band's samples at once,
:math:`(B, C, K, h, W)`, on bands of rows sized to the cache for its ``K`` samples (:func:`band_samples`). Compiled,
inductor fuses a kernel into loops over the pixels, and what it stores between loops sets the cost: a reduction over
a sample axis becomes two loops with every sample's value stored in between. Crytek lays its samples last inside the
kernel (:func:`sample_axis`); hemisphere SSAO counts them unrolled, a group per call (:func:`sample_groups`,
:func:`sample_blocks`), on one band. Every layout computes each sample with the same operations: the same bits.
"""
from __future__ import annotations

import torch

from .compiled import enabled

__all__ = ["sample_axis", "SAMPLES_PER_CALL", "sample_groups", "sample_blocks", "band_samples"]


def sample_axis() -> int:
    """The axis along which Crytek's band kernel lays out its samples: 2 eager, :math:`(B, C, K, h, W)`, last inside
    ``torch.compile``, :math:`(B, C, h, W, K)`.

    Eager, each operation loops over a whole block, and with the samples outside the rows it runs along contiguous
    rows of pixels (with them innermost, hemisphere SSAO ran 1.5× slower). Compiled, inductor writes a reduction
    over a middle axis as two loops and stores every per-sample value the second one reads; over the last axis it
    may fuse the sample loop and its count into one loop (hemisphere SSAO: 0.62× the time, before it counted its
    samples unrolled, :func:`sample_blocks`). The samples' arithmetic is the same in either layout: the same bits.

    Example:
        >>> sample_axis()
        2
    """
    return -1 if torch.compiler.is_compiling() else 2


#: samples per compiled call of hemisphere SSAO's counting kernel (:func:`sample_groups`); measured at 640×360
#: against its whole sample loop in one kernel (32 samples), 4 / 8 / 16 per call: 0.94 / 0.88 / 0.86× the time,
#: sixteen compiling twice as long as eight
SAMPLES_PER_CALL = 8


def sample_groups(samples: torch.Tensor) -> tuple:
    """The samples of ``samples`` (along its first dimension) in the groups a counting kernel takes per call: all of
    them at once eager (``samples`` itself), :data:`SAMPLES_PER_CALL` at a time compiled, each group a tensor of its
    own (a view at an offset into ``samples`` would compile again for every offset).

    Example:
        >>> from ssbench.passes.compiled import compiling
        >>> with compiling(True):
        ...     [g.shape[0] for g in sample_groups(torch.zeros(20, 3))]
        [8, 8, 4]
    """
    if not enabled():
        return (samples,)
    return tuple(g.clone() for g in samples.split(SAMPLES_PER_CALL))


def sample_blocks(samples: int) -> list:
    """The blocks in which a counting kernel runs its ``samples`` (slices of them): one block of all eager, where each
    operation loops over the whole band of every sample (:math:`(B, C, K, h, W)`); one sample per block inside
    ``torch.compile``, where the unrolled blocks fuse into one loop over the pixels that counts every sample and
    stores none. (Inductor writes a reduction over a sample axis as two loops and stores every sample's value
    between them; unrolling a whole sample loop of 32–64 samples took 54–123 s to compile, hence
    :func:`sample_groups`.) The samples' arithmetic is the same in either form: the same bits.

    Example:
        >>> sample_blocks(3)
        [slice(0, 3, None)]
    """
    if torch.compiler.is_compiling():
        return [slice(k, k + 1) for k in range(samples)]
    return [slice(0, samples)]


def band_samples(samples: int) -> int:
    """The samples per pixel a pass whose compiled kernel fuses its sample loop sizes its row bands for
    (:func:`ssbench.passes.common.row_bands`): ``samples`` eager, where each operation stores a block of every sample
    of the band, and 1 compiled (Crytek, the visibility bitmask), where each call costs tens of µs of guards and
    wrappers. Bands of any size give the same bits. Measured at 640×360, compiled: Crytek 23 → 15 ms (16 → 1 band),
    the visibility bitmask 195 → 183 ms, hemisphere SSAO 41 → 28 ms (90 bands → 3; it now counts its samples
    unrolled on one band, :func:`sample_blocks`); HBAO and GTAO, whose kernels store several per-sample blocks, ran
    8–45 % slower on larger bands without the heap held and keep theirs (GTAO with the heap held as the benchmark
    holds it: 0.97–1.00× the time on bands 2× and 4× larger, so nothing to gain either; with its samples last: 1.9×
    slower, inductor vectorised over its 6 steps).

    Example:
        >>> from ssbench.passes.compiled import compiling
        >>> with compiling(False):
        ...     band_samples(32)
        32
    """
    return 1 if enabled() else samples
