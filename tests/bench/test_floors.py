"""The gather floors: the torch floor reads texels of the texture, sample by sample, from a bounded index pool; the
fused floor sums exactly the texels its hash names (checked against a NumPy transcription of the hash)."""
import numpy as np
import pytest
import torch

from ssbench.bench import floors as F


def test_torch_floor_reads_texels_from_a_bounded_pool_and_is_deterministic():
    z = torch.arange(1.0, 49.0).view(1, 1, 6, 8)
    call = F.torch_floor(z, 20, seed=3)
    out = call()
    assert out.shape == (48,) and set(out.tolist()) <= set(z.flatten().tolist())
    assert torch.equal(out, F.torch_floor(z, 20, seed=3)()) and not torch.equal(out, F.torch_floor(z, 20, 4)())
    pool = call.index_pool                                    # POOL rows of int32 ids, not K rows
    assert tuple(pool.shape) == (F.POOL, 48) and pool.dtype == torch.int32
    assert tuple(F.torch_floor(z, 3).index_pool.shape) == (3, 48)


@pytest.mark.parametrize("bad, match", [((torch.zeros(6, 8), 4), "texture"), ((torch.zeros(1, 1, 6, 8), 0), "samples"),
                                        ((torch.zeros(1, 1, 6, 8), True), "samples")])
def test_floors_name_bad_arguments(bad, match):
    for f in (F.torch_floor, F.fused_floor):
        with pytest.raises(ValueError, match=f"^{match}:"):
            f(*bad)


def _pcg(v: np.ndarray) -> np.ndarray:                      # PCG-RXS-M-XS 32, written again from O'Neill (2014)
    v = v.astype(np.uint64)
    m = np.uint64(0xFFFFFFFF)
    state = (v * np.uint64(747796405) + np.uint64(2891336453)) & m
    word = (((state >> ((state >> np.uint64(28)) + np.uint64(4))) ^ state) * np.uint64(277803737)) & m
    return ((word >> np.uint64(22)) ^ word) & m


def test_fused_floor_sums_the_texels_its_hash_names():
    z = torch.rand(1, 1, 6, 8, generator=torch.Generator().manual_seed(0))
    call = F.fused_floor(z, 5, seed=2)
    if call is None:
        pytest.skip("no Dr.Jit LLVM backend on this machine")
    got = np.array(call())
    n, flat = 48, z.flatten().numpy()
    pixel = np.arange(n, dtype=np.uint64)
    salt = np.uint64(2 * 2654435761 % 2 ** 32)
    want = sum(flat[(_pcg((pixel * np.uint64(5) + np.uint64(k) + salt) & np.uint64(0xFFFFFFFF)) % np.uint64(n))
                    .astype(np.int64)] for k in range(5))
    assert np.allclose(got, want, rtol=1e-6, atol=0)
    assert F.fused_floor(z.to("meta"), 5) is None                       # not on the CPU: no fused floor


def test_timing_with_the_fused_floor_never_changes_drjit_threads():
    """Resizing Dr.Jit's pool in a process that also writes EXR files through Mitsuba hung it: never done."""
    from ssbench.bench import effects as E
    from ssbench.bench import timing as T
    if F.drjit_llvm() is None:
        pytest.skip("no Dr.Jit LLVM backend on this machine")
    import drjit as dr
    z = -torch.rand(1, 1, 6, 8) - 1
    inputs = E.BenchInputs(lambda: z * 2, z, torch.ones(1, 1, 6, 8, dtype=torch.bool), 3, z)
    before = dr.thread_count()
    row = T.time_pass(inputs, T.TimingSpec(min_run_time=0.01, warmup=0), threads=1)
    assert row["fused_floor_ratio"] > 0 and dr.thread_count() == before
