"""steady_heap: glibc's thresholds held while timing and settled after (errors too); nothing off glibc."""
import pytest

from ssbench.bench import heap


class _FakeLibc:
    def __init__(self, ok=1):
        self.ok, self.log = ok, []

    def mallopt(self, param, value):
        self.log.append(("mallopt", param, value))
        return self.ok

    def malloc_trim(self, pad):
        self.log.append(("malloc_trim", pad))
        return 1


def test_steady_heap_keeps_freed_memory_while_timing_and_settles_after(monkeypatch):
    libc = _FakeLibc()
    monkeypatch.setattr(heap, "_glibc", lambda: libc)
    with pytest.raises(RuntimeError):
        with heap.steady_heap() as ok:
            assert ok and libc.log == [("mallopt", -3, 32 << 20), ("mallopt", -1, heap.TIMING_TRIM)]
            raise RuntimeError("a failing pass")
    assert libc.log[2:] == [("mallopt", -1, heap.SETTLED_TRIM), ("malloc_trim", 0)]      # restored on errors too


@pytest.mark.parametrize("libc", [None, _FakeLibc(ok=0)])
def test_steady_heap_without_glibc_changes_nothing(monkeypatch, libc):
    monkeypatch.setattr(heap, "_glibc", lambda: libc)
    with heap.steady_heap() as ok:
        assert ok is False
    assert libc is None or all(entry[0] == "mallopt" for entry in libc.log)       # no settling, no trim
    with heap.steady_heap():                                              # the real one (glibc or not) runs
        pass
