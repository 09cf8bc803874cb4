"""The import order of docs/layout.md, checked on the source: every import counts, inside functions too.

docs/layout.md states the order as ``Imports flow one way: a -> b, c -> ... (x, y and z are leaves).``
A part of navbench (a subpackage, a top-level module, or ``__init__`` for the package itself) may
import parts after it in that order and the leaves; parts listed together (``b, c``) may not import
each other; leaves import no other part. Within a part anything goes, except that no set of modules
may import each other in a circle.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYOUT = ROOT / "docs" / "layout.md"

# Imports known to break the order, in modules being reworked elsewhere: (importing module, imported
# module). Each entry must still occur (a stale entry fails the test); the list is meant to be empty.
KNOWN_VIOLATIONS: set[tuple[str, str]] = set()
# Import circles known to exist, as sorted module tuples; the same rules as KNOWN_VIOLATIONS.
KNOWN_CIRCLES: set[tuple[str, ...]] = set()


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every module of navbench under ``root`` (a package is its ``__init__``)."""
    out = {}
    for path in sorted((root / "navbench").rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _deepest(name: str, known: dict[str, Path]) -> str | None:
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name or None


def imports(known: dict[str, Path]) -> dict[str, dict[str, int]]:
    """module -> {imported navbench module: line of the first such import}, wherever the import stands."""
    edges: dict[str, dict[str, int]] = {}
    for mod, path in known.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        found: dict[str, int] = {}
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets: list[str | None] = []
            if isinstance(node, ast.Import):
                targets = [_deepest(a.name, known) for a in node.names if a.name.split(".")[0] == "navbench"]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                if base.split(".")[0] != "navbench":
                    continue
                # ``from pkg import name``: the submodule pkg.name if there is one, else pkg itself.
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else _deepest(base, known)
                           for a in node.names]
            for t in targets:
                if t is not None and t != mod:
                    found.setdefault(t, node.lineno)
        edges[mod] = found
    return edges


def part(module: str) -> str:
    """The top-level part a module belongs to: ``navbench.scene.asset`` -> ``scene``; the package -> ``__init__``."""
    pieces = module.split(".")
    return pieces[1] if len(pieces) > 1 else "__init__"


def documented_order() -> tuple[list[list[str]], set[str]]:
    """(stages, highest first, each a list of parts; leaves) from the sentence in docs/layout.md."""
    text = " ".join(LAYOUT.read_text().split())
    m = re.search(r"Imports flow one way: (.+?) \((.+?) are leaves\)", text)
    assert m, f"{LAYOUT}: no 'Imports flow one way: ... (... are leaves)' sentence"
    stages = [[p.strip(" `") for p in stage.split(",")] for stage in m.group(1).split("->")]
    leaves = {p.strip(" `") for p in re.split(r",| and ", m.group(2)) if p.strip(" `")}
    return stages, leaves


def circles(edges: dict[str, dict[str, int]]) -> list[tuple[str, ...]]:
    """Strongly connected sets of two or more modules (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out: list[tuple[str, ...]] = []
    for root in edges:
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(edges.get(w, {})))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(tuple(sorted(comp)))
    return out


def order_violations(edges: dict[str, dict[str, int]], stages: list[list[str]], leaves: set[str]
                     ) -> dict[tuple[str, str], str]:
    """(importer, imported) -> why the import breaks the documented order."""
    rank = {p: i for i, stage in enumerate(stages) for p in stage}
    out = {}
    for mod, targets in edges.items():
        a = part(mod)
        for target, line in targets.items():
            b = part(target)
            if a == b or (b in leaves and a not in leaves):
                continue
            if a in leaves:
                why = f"{a} is a leaf"
            elif b not in rank or a not in rank:
                continue  # reported by test_every_part_is_placed
            elif rank[b] < rank[a]:
                why = f"{a} sits below {b}"
            elif rank[b] == rank[a]:
                why = f"{a} and {b} sit side by side"
            else:
                continue
            out[(mod, target)] = f"{mod} (line {line}) imports {target}: {why}"
    return out


@pytest.fixture(scope="module")
def graph():
    known = modules()
    return known, imports(known)


def test_every_part_is_placed(graph):
    known, _ = graph
    stages, leaves = documented_order()
    placed = {p for stage in stages for p in stage} | leaves
    parts = {part(m) for m in known}
    assert not parts - placed, f"parts of navbench missing from the order in {LAYOUT.name}: {sorted(parts - placed)}"
    assert not placed - parts, f"{LAYOUT.name} places parts navbench does not have: {sorted(placed - parts)}"


def test_imports_follow_the_documented_order(graph):
    _, edges = graph
    found = order_violations(edges, *documented_order())
    new = {k: v for k, v in found.items() if k not in KNOWN_VIOLATIONS}
    stale = KNOWN_VIOLATIONS - set(found)
    assert not new, "imports against docs/layout.md's order:\n" + "\n".join(sorted(new.values()))
    assert not stale, f"KNOWN_VIOLATIONS lists imports that no longer exist: {sorted(stale)}"


def test_no_import_circles(graph):
    _, edges = graph
    found = set(circles(edges))
    new, stale = found - KNOWN_CIRCLES, KNOWN_CIRCLES - found
    assert not new, "modules importing each other in a circle:\n" + "\n".join(" <-> ".join(c) for c in sorted(new))
    assert not stale, f"KNOWN_CIRCLES lists circles that no longer exist: {sorted(stale)}"


def test_the_checks_read_imports_inside_functions_and_find_circles(tmp_path):
    pkg = tmp_path / "navbench"
    (pkg / "scene").mkdir(parents=True)
    (pkg / "render").mkdir()
    for p in (pkg / "__init__.py", pkg / "scene" / "__init__.py", pkg / "render" / "__init__.py"):
        p.write_text("")
    (pkg / "render" / "r.py").write_text("def g():\n    import navbench.scene.b\n")
    (pkg / "scene" / "a.py").write_text("def f():\n    from navbench.render import r\n    from . import b\n")
    (pkg / "scene" / "b.py").write_text("if True:\n    from navbench.scene.a import f\n")
    edges = imports(modules(tmp_path))
    assert edges["navbench.scene.a"] == {"navbench.render.r": 2, "navbench.scene.b": 3}
    assert edges["navbench.render.r"] == {"navbench.scene.b": 2}
    stages = [["render"], ["scene"]]
    assert set(order_violations(edges, stages, set())) == {("navbench.scene.a", "navbench.render.r")}
    assert circles(edges) == [("navbench.render.r", "navbench.scene.a", "navbench.scene.b")]
