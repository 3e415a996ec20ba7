"""The web UI's ES modules (src/curvefm/service/static, no build step) import each other without a cycle.

A cycle between modules works in a browser only while no module uses an import at load time; it hides which
module owns what. The test reads every ``import ... from "./x.js"`` (static imports, relative paths) and looks for
a cycle in that graph.
"""

from __future__ import annotations

import re
from pathlib import Path

from support.paths import REPO

STATIC = REPO / "src" / "curvefm" / "service" / "static"
IMPORT = re.compile(
    r"""(?:^|\n)\s*(?:import|export)\s[^;]*?\sfrom\s*["'](\.{1,2}/[^"']+)["']|import\s*["'](\.{1,2}/[^"']+)["']"""
)


def import_graph(root: Path = STATIC) -> dict[str, set[str]]:
    """Each module (path relative to ``root``) and the modules it imports statically by a relative path."""
    graph: dict[str, set[str]] = {}
    for path in sorted(root.rglob("*.js")):
        if "vendor" in path.relative_to(root).parts:
            continue
        name = path.relative_to(root).as_posix()
        targets = set()
        for match in IMPORT.finditer(path.read_text()):
            target = (path.parent / (match.group(1) or match.group(2))).resolve()
            if target.is_relative_to(root):
                targets.add(target.relative_to(root).as_posix())
        graph[name] = targets
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle as a list of modules (first repeated at the end), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt) :] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_the_graph_is_read():
    graph = import_graph()
    assert "app.js" in graph and graph["controllers/curves.js"], "no imports found: has the static folder moved?"


def test_the_finder_finds_a_cycle():
    assert find_cycle({"a.js": {"b.js"}, "b.js": {"c.js"}, "c.js": {"a.js"}}) == ["a.js", "b.js", "c.js", "a.js"]
    assert find_cycle({"a.js": {"b.js"}, "b.js": set(), "c.js": {"a.js", "b.js"}}) is None


def test_no_import_cycle_in_the_ui():
    cycle = find_cycle(import_graph())
    assert cycle is None, "the UI's modules import each other in a cycle: " + " -> ".join(cycle)
