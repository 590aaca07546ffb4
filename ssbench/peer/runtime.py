"""Run one three.js shader pass for real, in headless Chromium (WebGL2 through SwiftShader), on float textures.

:func:`ensure_three` installs the pinned ``three`` package (``js/package.json`` + ``package-lock.json``, ``npm ci``)
into ``<cache>/peer/three-<version>`` once (``$SSBENCH_CACHE_DIR`` or ``~/.cache/ssbench``, as the reference
cache; nothing is written into the source tree). :func:`run_pass` writes a page that imports the shader module
from that install (an import map over ``file://``), uploads the textures as ``DataTexture`` (``FloatType``,
``NearestFilter``, rows bottom-up as GL stores them), sets the uniforms, draws one full-screen quad into a float
render target (``FullScreenQuad``) and reads the pixels back; Chromium prints the page (``--dump-dom``) and the
result is parsed from it. No server, no network (host names do not resolve), no code but the shader runs.

Rows: an ssbench image has row 0 at the top, a GL texture at the bottom, so :func:`to_gl` flips rows on the way in
and :func:`run_pass` flips them back on the way out (``flip_rows=False``: the control that must fail).
"""
from __future__ import annotations

import base64
import json
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from ..reference.cache import cache_dir

__all__ = ["PeerUnavailable", "Uniform", "ShaderPass", "available", "ensure_three", "run_pass", "to_gl",
           "THREE_VERSION", "find_chromium", "camera_uniforms", "gbuffer_textures"]

_JS = Path(__file__).with_name("js")
THREE_VERSION = json.loads((_JS / "package.json").read_text())["dependencies"]["three"]
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")
_FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader",
          "--enable-unsafe-swiftshader", "--allow-file-access-from-files", "--host-resolver-rules=MAP * ~NOTFOUND",
          "--no-first-run", "--disable-extensions", "--virtual-time-budget=60000", "--dump-dom")


class PeerUnavailable(RuntimeError):
    """No Chromium or no npm here (the parity checks are skipped, with this message as the reason)."""


@dataclass(frozen=True)
class Uniform:
    """A uniform's ``kind`` (``float``, ``vec2``, ``mat4`` column-major, ``vec3[]``) and ``value``."""

    kind: str
    value: object


@dataclass(frozen=True)
class ShaderPass:
    """One full-screen pass: the shader ``export`` of ``module`` (a ``three/addons/...`` path), its textures
    (``name → (H, W, C ≤ 4)`` float arrays in ssbench row order; names in ``repeat`` wrap with ``REPEAT``), uniforms,
    extra ``defines`` and ``patches`` (``(from, to)`` replacements in the fragment shader, each must match)."""

    module: str
    export: str
    width: int
    height: int
    textures: dict = field(default_factory=dict)
    uniforms: dict = field(default_factory=dict)
    defines: dict = field(default_factory=dict)
    patches: tuple = ()
    repeat: tuple = ()


def camera_uniforms(cam, inverse: str = "cameraInverseProjectionMatrix") -> dict:
    """The camera uniforms every peer shader takes: ``cameraNear``, ``cameraFar``, ``resolution``,
    ``cameraProjectionMatrix`` and its closed-form inverse (under the shader's name ``inverse``), column-major."""
    def mat4(m) -> Uniform:
        return Uniform("mat4", [float(v) for v in m.to(torch.float32).T.reshape(-1)])
    return {"cameraNear": Uniform("float", cam.near), "cameraFar": Uniform("float", cam.far),
            "resolution": Uniform("vec2", [cam.width, cam.height]),
            "cameraProjectionMatrix": mat4(cam.projection_matrix()), inverse: mat4(cam.inverse_projection_matrix())}


def gbuffer_textures(g) -> dict:
    """``tDepth`` (the GL depth buffer, exactly 1.0 on background texels: the shaders' "nothing here") and
    ``tNormal`` (view normals packed ``n · 0.5 + 0.5``, undone by the shaders' ``unpackRGBToNormal``) of a
    batch-1 float32 G-buffer, as ``(H, W, C)`` arrays in ssbench row order."""
    if g.view_z.shape[0] != 1:
        raise ValueError(f"gbuffer: one image at a time, got a batch of {g.view_z.shape[0]}")
    depth = g.camera.view_z_to_depth(g.view_z)[0, 0].clone()
    depth[~g.mask[0, 0]] = 1.0
    return {"tDepth": depth.numpy(), "tNormal": (g.normal[0].permute(1, 2, 0) * 0.5 + 0.5).numpy()}


def find_chromium() -> Optional[str]:
    return next((shutil.which(n) for n in CHROMIUM_NAMES if shutil.which(n)), None)


def _install_dir() -> Path:
    return Path(cache_dir()) / "peer" / f"three-{THREE_VERSION}"


def available() -> Optional[str]:
    """``None`` when the parity checks can run here, else why not."""
    if find_chromium() is None:
        return f"no Chromium on PATH ({', '.join(CHROMIUM_NAMES)}); `make browser` installs Debian's"
    if not _installed(_install_dir()) and shutil.which("npm") is None:
        return "no npm on PATH to install the pinned three.js"
    return None


def _installed(folder: Path) -> bool:
    done = folder / "node_modules" / "three" / "package.json"
    try:
        return json.loads(done.read_text())["version"] == THREE_VERSION
    except (OSError, ValueError, KeyError):
        return False


def ensure_three() -> Path:
    """The folder holding ``node_modules/three`` at the pinned version, installed with ``npm ci`` when missing.

    The install runs in a fresh sibling folder that is renamed into place once complete, so two processes (the test
    suite's workers, two reports) never share a half-written install: the first to finish keeps its copy, and a
    folder left incomplete by an interrupted install is replaced."""
    folder = _install_dir()
    if _installed(folder):
        return folder
    npm = shutil.which("npm")
    if npm is None:
        raise PeerUnavailable("no npm on PATH to install the pinned three.js")
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        part = Path(tempfile.mkdtemp(prefix=folder.name + ".part-", dir=folder.parent))
    except OSError as e:
        raise PeerUnavailable(f"cannot install three@{THREE_VERSION} into {folder}: {e}") from None
    try:
        for name in ("package.json", "package-lock.json"):
            shutil.copyfile(_JS / name, part / name)
        r = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--ignore-scripts"], cwd=part,
                           capture_output=True, text=True, timeout=600)
        if r.returncode != 0 or not _installed(part):
            raise PeerUnavailable(f"npm ci of three@{THREE_VERSION} failed: {' '.join(r.stderr.split())[-300:]}")
        if folder.exists() and not _installed(folder):
            shutil.rmtree(folder, ignore_errors=True)             # an incomplete install of an older run
        try:
            os.rename(part, folder)
        except OSError:
            if not _installed(folder):                            # not another process's finished install
                raise
    except (OSError, subprocess.SubprocessError) as e:
        raise PeerUnavailable(f"cannot install three@{THREE_VERSION} into {folder}: {e}") from None
    finally:
        shutil.rmtree(part, ignore_errors=True)                   # gone already when it was renamed
    return folder


def to_gl(image: np.ndarray, flip_rows: bool = True) -> str:
    """``(H, W, C)`` floats → base64 of a float32 RGBA texture, rows bottom-up (``flip_rows``), C padded to 4."""
    a = np.asarray(image, dtype=np.float32)
    if a.ndim == 2:
        a = a[..., None]
    rgba = np.zeros(a.shape[:2] + (4,), np.float32)
    rgba[..., :a.shape[2]] = a
    if flip_rows:
        rgba = rgba[::-1]
    return base64.b64encode(np.ascontiguousarray(rgba).tobytes()).decode("ascii")


def _page(spec: dict, three: Path) -> str:
    imports = {"three": (three / "node_modules/three/build/three.module.js").as_uri(),
               "three/addons/": (three / "node_modules/three/examples/jsm").as_uri() + "/"}
    data = json.dumps(spec).replace("</", "<\\/")
    runner = (_JS / "pass_runner.js").as_uri()
    main = (f"import * as shaders from {json.dumps(spec['module'])}; import {{ run }} from {json.dumps(runner)}; "
            f"run(shaders[{json.dumps(spec['export'])}]);")
    return (f'<!doctype html><html><head><meta charset="utf-8"><script type="importmap">'
            f'{json.dumps({"imports": imports})}</script></head><body><pre id="out">pending</pre>'
            f'<script type="application/json" id="spec">{data}</script>'
            f'<script type="module">{main}</script></body></html>')


def run_pass(p: ShaderPass, *, flip_rows: bool = True, timeout: float = 180.0) -> np.ndarray:
    """Run ``p`` in headless Chromium; returns its ``(H, W, 4)`` float32 output in ssbench row order (row 0 at the
    top, when ``flip_rows``). Raises :class:`PeerUnavailable` (no Chromium / npm) or ``RuntimeError`` (the page
    failed: the shader did not compile, a patch target is missing, …) with the page's message."""
    chromium = find_chromium()
    if chromium is None:
        raise PeerUnavailable(available() or "no Chromium")
    three = ensure_three()
    spec = {"module": p.module, "export": p.export, "width": int(p.width), "height": int(p.height),
            "textures": {name: {"data": to_gl(img, flip_rows), "width": int(np.shape(img)[1]),
                                "height": int(np.shape(img)[0]), "repeat": name in p.repeat}
                         for name, img in p.textures.items()},
            "uniforms": {name: {"kind": u.kind, "value": u.value} for name, u in p.uniforms.items()},
            "defines": dict(p.defines), "patches": [list(x) for x in p.patches]}
    with tempfile.TemporaryDirectory(prefix="ssbench-peer-") as tmp:
        page = Path(tmp) / "pass.html"
        page.write_text(_page(spec, three), encoding="utf-8")
        for attempt in range(3):                  # a loaded machine can dump before the modules ran: once more
            r = subprocess.run([chromium, *_FLAGS, f"--user-data-dir={tmp}/profile{attempt}", page.as_uri()],
                               capture_output=True, text=True, timeout=timeout)
            m = re.search(r'<pre id="out">(.*?)</pre>', r.stdout, re.S)
            if m is None or m.group(1).strip() != "pending":
                break
    if m is None:
        raise RuntimeError(f"peer: Chromium printed no result (exit {r.returncode}): {r.stderr.strip()[-400:]}")
    text = m.group(1).strip()
    if not text.startswith("OK "):
        raise RuntimeError(f"peer: {p.export}: {' '.join(text.split())[:600]}")
    _, revision, gl_error, payload = text.split(" ", 3)
    if gl_error != "0":
        raise RuntimeError(f"peer: {p.export}: WebGL error {gl_error}")
    out = np.frombuffer(base64.b64decode(payload), np.float32).reshape(p.height, p.width, 4)
    return np.array(out[::-1] if flip_rows else out, order="C")     # a writable copy (frombuffer is read-only)
