"""The parity tests need Chromium and the pinned three.js: installed once per session, or every test skipped with
the reason (no Chromium, no npm, no writable cache folder, no registry)."""
import pytest


@pytest.fixture(scope="session", autouse=True)
def three_installed():
    from ssbench.peer import PeerUnavailable, available
    from ssbench.peer.runtime import ensure_three
    why = available()
    if why:
        pytest.skip(why)
    try:
        ensure_three()
    except PeerUnavailable as e:
        pytest.skip(str(e))
