"""The repository cites what users have: no paths outside it, no issue numbers, a bibliography that exists."""
import pathlib
import re
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SUFFIXES = {".py", ".md", ".j2", ".yaml", ".toml", ".txt", ".cfg", ""}
# built from pieces so this file does not match itself
FORBIDDEN = [re.compile(p) for p in (r"\.\./" + "shared/", "/work/" + "shared", "shared/" + "(notes|seeds)/",
                                      r"_anch" + r"ors\.md", r"(?i)\bissue[ #]+\d+")]


def _tracked() -> list[pathlib.Path]:
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [ROOT / f for f in out.splitlines() if (ROOT / f).suffix in SUFFIXES and (ROOT / f).is_file()]


def test_no_reference_outside_the_repository_or_to_an_issue():
    hits = []
    for path in _tracked():
        if path.suffix == "" and path.name not in ("Makefile",):
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if any(p.search(line) for p in FORBIDDEN):
                hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()[:100]}")
    assert not hits, "cite by author, title, year and URL (ssbench/REFERENCES.md) instead:\n" + "\n".join(hits)


def test_the_bibliography_holds_the_source_articles():
    text = (ROOT / "ssbench" / "REFERENCES.md").read_text(encoding="utf-8")
    for needle in ("https://zenn.dev/mebiusbox/articles/43ecf1bb12831c", "https://github.com/mebiusbox/ssr",
                   "https://zenn.dev/mebiusbox/articles/c7ea4871698ada", "https://github.com/mebiusbox/ssao",
                   "https://www.shadertoy.com/view/XsdSR7", "Sphere Tracing"):
        assert needle in text, needle


def test_the_ground_truth_does_not_import_the_passes_it_checks():
    import ast
    offenders = []
    for path in sorted((ROOT / "ssbench" / "reference").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.ImportFrom):
                names = [("." * node.level) + (node.module or "")]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            offenders += [f"{path.name}:{node.lineno}: {n}" for n in names
                          if n.startswith("..passes") or n.startswith("ssbench.passes")]
    assert not offenders, offenders


def _modules() -> dict:
    out = {}
    for path in sorted((ROOT / "ssbench").rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _source(mod: str, path: pathlib.Path, node) -> str:
    if node.level == 0:
        return node.module or ""
    base = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def test_no_module_imports_another_modules_private_names():
    """``from .x import _name`` (or ``alias._name``) reaches into another module's internals: make it public."""
    import ast
    hits = []
    for mod, path in _modules().items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        aliases = {a.asname or a.name for n in ast.walk(tree)                  # names bound to ssbench modules
                   if isinstance(n, ast.ImportFrom) and (n.level or (n.module or "").startswith("ssbench"))
                   for a in n.names}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                hits += [f"{mod}: from {node.module} import {a.name}" for a in node.names
                         if a.name.startswith("_") and not a.name.startswith("__")]
            elif (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                  and node.attr.startswith("_") and not node.attr.startswith("__")):
                hits.append(f"{mod}: {node.value.id}.{node.attr}")
    assert not hits, "\n".join(hits)


def test_no_import_cycles_at_module_level():
    """Module-level imports between ssbench modules form no cycle (imports inside functions are lazy on
    purpose: the heavy back-ends load only when used)."""
    import ast
    mods = _modules()
    graph = {m: set() for m in mods}
    for mod, path in mods.items():
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.ImportFrom):
                src = _source(mod, path, node)
                graph[mod] |= {f"{src}.{a.name}" if f"{src}.{a.name}" in mods else src for a in node.names} & set(mods)
            elif isinstance(node, ast.Import):
                graph[mod] |= {a.name for a in node.names} & set(mods)
        graph[mod].discard(mod)
    state: dict = {}

    def visit(m, trail):
        state[m] = "open"
        for n in sorted(graph[m]):
            if state.get(n) == "open":
                raise AssertionError("import cycle: " + " -> ".join(trail[trail.index(n):] + [n]))
            if n not in state:
                visit(n, trail + [n])
        state[m] = "done"
    for m in sorted(mods):
        if m not in state:
            visit(m, [m])
