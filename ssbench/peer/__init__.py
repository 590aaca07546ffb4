"""Peer parity: the shaders ssbench's passes transliterate, run for real in headless Chromium on ssbench's
G-buffers and compared with the torch passes (:mod:`.runtime`: the harness; :mod:`.ssao`: three.js
``SSAOShader``; :mod:`.ssr`: ``SSRShader``; :mod:`.gtao`: ``GTAOShader``). ``ssbench/PARITY.md`` says what is proven equal to which shader version; :func:`proofs` lists it
for the report."""
from .runtime import THREE_VERSION, PeerUnavailable, ShaderPass, Uniform, available, run_pass

__all__ = ["THREE_VERSION", "PeerUnavailable", "ShaderPass", "Uniform", "available", "run_pass", "proofs"]


def proofs() -> list[str]:
    """One line per pass proven equal to a peer shader by ``tests/peer`` (each peer module's ``PROOF``)."""
    import importlib
    import pkgutil
    out = []
    for m in pkgutil.iter_modules(__path__):
        mod = importlib.import_module(f"{__name__}.{m.name}")
        if isinstance(getattr(mod, "PROOF", None), str):
            out.append(f"{mod.PROOF} (three.js r{THREE_VERSION.split('.')[1]})")
    return out
