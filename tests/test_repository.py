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
