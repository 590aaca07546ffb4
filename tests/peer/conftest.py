"""The parity tests (`pytest.mark.usefixtures("three_installed")`) need Chromium and the pinned three.js: installed
once per session, or every such test skipped with the reason (no Chromium, no npm, no writable cache folder, no
registry)."""
import pytest


@pytest.fixture(scope="session")
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
