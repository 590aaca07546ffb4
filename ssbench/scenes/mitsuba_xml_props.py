"""The safe XML tree and property readers behind ``mitsuba_xml.py``: data only (nothing is ever executed).

The file is parsed with ``xml.parsers.expat``; DOCTYPE/ENTITY declarations are refused, so no external entity is
resolved and no entity expansion happens. :class:`Props` reads Mitsuba property elements (numbers, colours,
transforms, lookat) and turns every problem into ``file:line: what is wrong``.
"""
from __future__ import annotations

import math
import re
from typing import Any
from xml.parsers import expat

from .model import SceneError
from .transforms import cross, default_up, identity4, matmul4, rotate_axis4, scale4, translate4, unit

_SEP = re.compile(r"[,\s]+")
_PROPS = {"float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector", "transform"}


class Node:
    __slots__ = ("tag", "attrs", "kids", "line")

    def __init__(self, tag: str, attrs: dict, line: int):
        self.tag, self.attrs, self.kids, self.line = tag, attrs, [], line

    def get(self, key: str, default: Any = None) -> Any:
        return self.attrs.get(key, default)


def parse_tree(text: str, filename: str) -> Node:
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

    def refuse(*_: Any) -> None:
        raise SceneError(f"{filename}:{p.CurrentLineNumber}: DOCTYPE/ENTITY declarations are not allowed")

    p.StartElementHandler, p.EndElementHandler = start, lambda tag: stack.pop()
    p.StartDoctypeDeclHandler = p.EntityDeclHandler = p.ExternalEntityRefHandler = refuse
    try:
        p.Parse(text, True)
    except expat.ExpatError as e:
        raise SceneError(f"{filename}:{e.lineno}: malformed XML: {expat.ErrorString(e.code)}") from None
    return roots[0]


class Props:
    def __init__(self, filename: str):
        self.f, self.lines, self.named = filename, {}, {}

    def err(self, node: Node, msg: str) -> SceneError:
        return SceneError(f"{self.f}:{node.line}: {msg}")

    def at(self, path: tuple, node: Node | None) -> None:
        if node is not None:
            self.lines[path] = node.line

    def locate(self, path: tuple) -> str:
        for n in range(len(path), -1, -1):
            if path[:n] in self.lines:
                return f"{self.f}:{self.lines[path[:n]]}"
        return f"{self.f}:1"

    # ------------------------------------------------------------ values
    def split(self, node: Node, allowed: set, objs: tuple = (), ignore: set = frozenset()) -> tuple[dict, list]:
        props: dict[str, Node] = {}
        kids: list[Node] = []
        what = f"<{node.tag} type={node.get('type')!r}>"
        for k in node.kids:
            if k.tag in _PROPS:
                name = k.get("name")
                if name in ignore:
                    continue
                if name not in allowed:
                    raise self.err(k, f"{what}: unsupported property {name!r} "
                                      f"(supported: {', '.join(sorted(allowed)) or 'none'})")
                if name in props:
                    raise self.err(k, f"{what}: duplicate property {name!r}")
                props[name] = k
            elif k.tag in objs:
                kids.append(k)
            else:
                raise self.err(k, f"{what}: element <{k.tag}> is not supported here")
        return props, kids

    def nums(self, node: Node, key: str = "value", counts: tuple = (1,)) -> list[float]:
        raw = node.get(key)
        if raw is None:
            raise self.err(node, f"<{node.tag} name={node.get('name')!r}>: missing attribute {key!r}")
        try:
            vals = [float(v) for v in _SEP.split(raw.strip()) if v]
            if not all(map(math.isfinite, vals)):
                raise ValueError
        except ValueError:
            raise self.err(node, f"<{node.tag} name={node.get('name')!r}>: {key}: expected finite numbers, "
                                 f"got {raw!r}") from None
        if len(vals) not in counts:
            raise self.err(node, f"<{node.tag}>: {key}: expected {' or '.join(map(str, counts))} numbers, "
                                 f"got {raw!r}")
        return vals

    def xyz(self, node: Node, default: float, key: str = "value") -> list[float]:
        if key in node.attrs:
            v = self.nums(node, key, (1, 3) if key == "value" else (3,))
            return v * 3 if len(v) == 1 else v
        return [self.nums(node, c)[0] if c in node.attrs else default for c in "xyz"]

    def scalar(self, props: dict, name: str, default: Any, path: tuple = (), integer: bool = False) -> Any:
        node = props.get(name)
        if node is None:
            return default
        self.at(path, node)
        if integer:
            try:
                return int(node.get("value", ""))
            except ValueError:
                raise self.err(node, f"{name}: expected an integer, got {node.get('value')!r}") from None
        return self.nums(node)[0]

    def text(self, props: dict, name: str, default: str) -> str:
        return props[name].get("value", "") if name in props else default

    def flag(self, props: dict, name: str) -> bool:
        v = self.text(props, name, "false").lower()
        if v not in ("true", "false"):
            raise self.err(props[name], f"{name}: expected true or false, got {v!r}")
        return v == "true"

    def color(self, props: dict, name: str, default: float, path: tuple) -> list[float]:
        node = props.get(name)
        if node is None:
            return [default] * 3
        self.at(path, node)
        if node.tag not in ("rgb", "float", "spectrum"):
            raise self.err(node, f"{name}: expected rgb, float or a constant spectrum, got <{node.tag}>")
        v = self.nums(node, counts=(1, 3) if node.tag == "rgb" else (1,))
        return v * 3 if len(v) == 1 else v

    def transform(self, t: Node) -> list[list[float]]:
        m = identity4()
        for op in t.kids:
            if op.tag == "translate":
                step = translate4(self.xyz(op, 0.0))
            elif op.tag == "scale":
                step = scale4(self.xyz(op, 1.0))
            elif op.tag == "rotate":
                axis = self.xyz(op, 0.0)
                if abs(math.sqrt(sum(a * a for a in axis)) - 1.0) > 1e-6:
                    raise self.err(op, f"rotate: the axis (x, y, z) must have unit length (Mitsuba does not "
                                       f"normalise it), got {axis}")
                step = rotate_axis4(axis, self.nums(op, "angle")[0])
            elif op.tag == "matrix":
                v = self.nums(op, counts=(16, 9))
                step = ([v[4 * i: 4 * i + 4] for i in range(4)] if len(v) == 16 else
                        [v[3 * i: 3 * i + 3] + [0.0] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]])
            elif op.tag == "lookat":
                eye, target, up = self.lookat(op)
                d = unit([b - a for a, b in zip(eye, target)])
                left = unit(cross(up, d))
                step = [[v[i] for v in (left, cross(d, left), d, eye)] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
            else:
                raise self.err(op, f"transform {t.get('name')!r}: unknown operation <{op.tag}>")
            m = matmul4(step, m)           # Mitsuba applies the operations in document order
        return m

    def lookat(self, op: Node) -> tuple[list[float], list[float], list[float]]:
        eye, target = self.xyz(op, 0.0, "origin"), self.xyz(op, 0.0, "target")
        if eye == target:
            raise self.err(op, "lookat: target must differ from origin")
        up = self.xyz(op, 0.0, "up") if "up" in op.attrs else [0.0, 0.0, 0.0]
        d = unit([b - a for a, b in zip(eye, target)])
        if not any(up):
            up = default_up(d)
        if math.sqrt(sum(v * v for v in cross(up, d))) < 1e-9 * math.sqrt(sum(v * v for v in up)):
            raise self.err(op, f"lookat: up {up} must not be parallel to target - origin")
        return eye, target, up
