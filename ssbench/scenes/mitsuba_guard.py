"""What a Mitsuba 3 scene file may ask for, checked *before* Mitsuba's own parser sees it. Data only.

:func:`guard` reads the XML with ``xml.parsers.expat`` (DOCTYPE/ENTITY declarations refused, so no external entity
is resolved and no entity expansion happens) and walks it, following ``<include>`` (at most
:data:`MAX_INCLUDE_DEPTH` deep), with the ``$name`` parameters substituted from the ``-D`` overrides and the files'
``<default>`` values, as Mitsuba does. It refuses, naming ``file:line``:

* any file name (``<include filename>``, a ``filename`` string: meshes, textures, environment maps) that is
  absolute or resolves — symbolic links followed — outside the main scene's folder, or does not exist there
  (Mitsuba resolves every relative name against the main file's folder, included files too);
* files above :data:`MAX_XML_BYTES` (XML) or :data:`MAX_RESOURCE_BYTES` (a resource), more than
  :data:`MAX_ELEMENTS` elements in all, a film side above :data:`MAX_FILM_SIDE`.

It also notes what the passes do not need and the loader ignores (integrator, sampler, reconstruction filter,
pixel format, focus distance and aperture, media, extra sensors), returns the integrator's ``max_depth`` and a
SHA-256 over every file read plus the overrides: the scene's content key.
"""
from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from typing import Optional
from xml.parsers import expat

from .model import SceneError

__all__ = ["GuardedScene", "guard", "unchanged", "parse_tree", "Node", "check_defines", "MAX_XML_BYTES", "MAX_RESOURCE_BYTES",
           "MAX_ELEMENTS", "MAX_FILM_SIDE", "MAX_INCLUDE_DEPTH"]

MAX_XML_BYTES = 16 << 20
MAX_RESOURCE_BYTES = 1 << 30
MAX_ELEMENTS = 200_000
MAX_FILM_SIDE = 16384
MAX_INCLUDE_DEPTH = 8
#: ``max_depth`` used for Mitsuba's default (unlimited, ``-1``) path depth
UNLIMITED_DEPTH = 64
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_PARAM = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")
_IGNORED = {"integrator": "the references use their own integrators",
            "sampler": "the references draw their own samples",
            "rfilter": "G-buffers are sampled at pixel centres",
            "medium": "participating media are not modelled by the passes",
            "phase": "participating media are not modelled by the passes"}
_IGNORED_PROPS = {"focus_distance": "a pinhole camera has no focus",
                  "aperture_radius": "a pinhole camera has no aperture (no depth of field)",
                  "pixel_format": "the references return their own channels",
                  "component_format": "the references return their own channels"}


class Node:
    """One XML element: ``tag``, ``attrs``, ``kids`` and the ``line`` it starts on."""
    __slots__ = ("tag", "attrs", "kids", "line")

    def __init__(self, tag: str, attrs: dict, line: int):
        self.tag, self.attrs, self.kids, self.line = tag, attrs, [], line

    def get(self, key: str, default=None):
        return self.attrs.get(key, default)


def parse_tree(text: "str | bytes", filename: str) -> Node:
    """The element tree of an XML document; DOCTYPE/ENTITY declarations are refused before anything expands.

    Example:
        >>> parse_tree('<scene version="3.0.0"><shape type="sphere"/></scene>', "a.xml").kids[0].get("type")
        'sphere'
    """
    p = expat.ParserCreate()
    p.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[Node] = []
    roots: list[Node] = []

    def start(tag: str, attrs: dict) -> None:
        if len(stack) > 32:
            raise SceneError(f"{filename}:{p.CurrentLineNumber}: malformed XML: elements nested too deeply")
        node = Node(tag, attrs, p.CurrentLineNumber)
        (stack[-1].kids if stack else roots).append(node)
        stack.append(node)

    def refuse(*_) -> None:
        raise SceneError(f"{filename}:{p.CurrentLineNumber}: DOCTYPE/ENTITY declarations are not allowed")

    p.StartElementHandler, p.EndElementHandler = start, lambda tag: stack.pop()
    p.StartDoctypeDeclHandler = p.EntityDeclHandler = p.ExternalEntityRefHandler = refuse
    try:
        p.Parse(text, True)
    except expat.ExpatError as e:
        raise SceneError(f"{filename}:{e.lineno}: malformed XML: {expat.ErrorString(e.code)}") from None
    if not roots:
        raise SceneError(f"{filename}:1: malformed XML: no root element")
    return roots[0]


def check_defines(defines) -> tuple[tuple[str, str], ...]:
    """``-D name=value`` overrides as sorted ``(name, value)`` pairs; names are identifiers, values one line."""
    items = defines.items() if isinstance(defines, dict) else (defines or ())
    out = {}
    for item in items:
        if not (isinstance(item, (tuple, list)) and len(item) == 2):
            raise ValueError(f"defines: expected (name, value) pairs, got {item!r}")
        name, value = item
        if not isinstance(name, str) or not _NAME.match(name):
            raise ValueError(f"defines: {name!r} is not a parameter name (letters, digits, _)")
        value = str(value)
        if any(c in value for c in "\n\r\0<>&\"") or len(value) > 4096:
            raise ValueError(f"defines: {name}: the value must be one plain line, got {value!r}")
        out[name] = value
    return tuple(sorted(out.items()))


@dataclass(frozen=True)
class GuardedScene:
    """What :func:`guard` found: the main file's real ``path`` and ``folder``, the ``defines`` as passed, a
    ``digest`` of every file read plus the defines, the integrator's ``max_depth``, the ``notes``, and ``files``:
    ``(path, mtime_ns, size)`` of every file read, for :func:`unchanged`."""

    path: str
    folder: str
    defines: tuple[tuple[str, str], ...]
    digest: str
    max_depth: int
    notes: tuple[str, ...]
    files: tuple[tuple[str, int, int], ...] = ()


def _stat(path: str) -> tuple[str, int, int]:
    st = os.stat(path)
    return path, st.st_mtime_ns, st.st_size


def unchanged(files: tuple) -> bool:
    """Whether every file :func:`guard` read still has the modification time and size it had then (the cheap
    test before hashing them all again; an edit that keeps both is not seen)."""
    try:
        return all(_stat(f[0]) == tuple(f) for f in files)
    except OSError:
        return False


class _Walk:
    def __init__(self, path: str, defines: tuple):
        self.folder = os.path.dirname(path)
        self.defines, self.defaults = dict(defines), {}
        self.hash = hashlib.sha256(repr(defines).encode())
        self.elements, self.notes = 0, {}
        self.max_depth: Optional[int] = None
        self.files: list = []

    def sub(self, value: str) -> str:
        return _PARAM.sub(lambda m: self.defines.get(m.group(1), self.defaults.get(m.group(1), m.group(0))), value)

    def resolve(self, name: str, where: str, limit: int) -> str:
        name = self.sub(name)
        if os.path.isabs(name) or re.match(r"^[A-Za-z]:", name):
            raise SceneError(f"{where}: file name {name!r} is absolute; scene files may only name files inside "
                             f"the scene's folder")
        real = os.path.realpath(os.path.join(self.folder, name))
        if os.path.commonpath([real, self.folder]) != self.folder:
            raise SceneError(f"{where}: file name {name!r} resolves outside the scene's folder {self.folder}")
        if not os.path.isfile(real):
            raise SceneError(f"{where}: file {name!r} not found in the scene's folder {self.folder}")
        size = os.path.getsize(real)
        if size > limit:
            raise SceneError(f"{where}: file {name!r} is {size} bytes, above the limit of {limit}")
        return real

    def note(self, key: str, text: str) -> None:
        self.notes.setdefault(key, text)

    def file(self, path: str, where: str, depth: int) -> None:
        if depth > MAX_INCLUDE_DEPTH:
            raise SceneError(f"{where}: <include> nested more than {MAX_INCLUDE_DEPTH} deep")
        self.files.append(_stat(path))
        with open(path, "rb") as f:
            data = f.read(MAX_XML_BYTES + 1)
        if len(data) > MAX_XML_BYTES:
            raise SceneError(f"{path}:1: scene file above {MAX_XML_BYTES} bytes")
        self.hash.update(path.encode() + b"\0" + data)
        root = parse_tree(data, path)
        if root.tag != "scene":
            raise SceneError(f"{path}:{root.line}: the root element must be <scene>, got <{root.tag}>")
        self.node(root, path, depth)

    def node(self, node: Node, path: str, depth: int) -> None:
        self.elements += 1
        where = f"{path}:{node.line}"
        if self.elements > MAX_ELEMENTS:
            raise SceneError(f"{where}: more than {MAX_ELEMENTS} elements")
        tag, name = node.tag, node.get("name")
        if tag == "default" and name is not None:
            self.defaults.setdefault(name, node.get("value", ""))
        elif tag == "include":
            if node.get("filename") is None:
                raise SceneError(f"{where}: <include> needs a filename")
            self.file(self.resolve(node.get("filename"), where, MAX_XML_BYTES), where, depth + 1)
        elif tag == "string" and name == "filename" and node.get("value") is not None:
            resource = self.resolve(node.get("value"), where, MAX_RESOURCE_BYTES)
            self.files.append(_stat(resource))
            with open(resource, "rb") as f:
                for chunk in iter(lambda: f.read(1 << 22), b""):
                    self.hash.update(chunk)
        elif tag == "integer" and name in ("width", "height"):
            try:
                side = int(self.sub(node.get("value", "0")))
            except ValueError:
                side = 0
            if side > MAX_FILM_SIDE:
                raise SceneError(f"{where}: film {name} {side} above the limit of {MAX_FILM_SIDE}")
        elif name in _IGNORED_PROPS:
            self.note(name, f"{where}: {name} ignored: {_IGNORED_PROPS[name]}")
        if tag in _IGNORED:
            self.note(tag, f"{where}: <{tag} type={node.get('type')!r}> ignored: {_IGNORED[tag]}")
        if tag == "integrator":
            self.max_depth = self.depth_of(node)
        for kid in node.kids:
            self.node(kid, path, depth)

    def depth_of(self, node: Node) -> int:
        for kid in node.kids:
            if kid.tag == "integer" and kid.get("name") == "max_depth":
                try:
                    d = int(self.sub(kid.get("value", "")))
                except ValueError:
                    return UNLIMITED_DEPTH
                return UNLIMITED_DEPTH if d < 0 else max(1, min(d, UNLIMITED_DEPTH))
        return UNLIMITED_DEPTH


def guard(path: "str | os.PathLike", defines=()) -> GuardedScene:
    """Check a Mitsuba scene file and everything it names (see the module docstring); :class:`SceneError`
    naming ``file:line`` on the first problem.

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp()); f = d / "s.xml"
        >>> _ = f.write_text('<scene version="3.0.0"><include filename="../x.xml"/></scene>')
        >>> guard(f)
        Traceback (most recent call last):
        ...
        ssbench.scenes.model.SceneError: ...s.xml:1: file name '../x.xml' resolves outside the scene's folder ...
    """
    real = os.path.realpath(os.fspath(path))
    if not os.path.isfile(real):
        raise SceneError(f"{os.fspath(path)}:1: no such scene file")
    defs = check_defines(defines)
    walk = _Walk(real, defs)
    walk.file(real, f"{real}:1", 0)
    if walk.max_depth is None:
        walk.note("integrator", f"{real}:1: no <integrator>: the colour reference paths up to "
                                f"{UNLIMITED_DEPTH} bounces (Mitsuba's default is unlimited)")
    return GuardedScene(real, walk.folder, defs, walk.hash.hexdigest(), walk.max_depth or UNLIMITED_DEPTH,
                        tuple(walk.notes.values()), tuple(walk.files))
