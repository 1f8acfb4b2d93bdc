"""The TUI's modules import each other without a cycle (counting imports inside functions too)."""

import ast
from pathlib import Path

import accelrig.tui

ROOT = Path(accelrig.tui.__file__).parent


def tui_imports() -> dict[str, set[str]]:
    graph = {}
    for path in ROOT.rglob("*.py"):
        parts = path.relative_to(ROOT.parent.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                found.add(node.module)
            elif isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names)
        graph[name] = {m for m in found if m.startswith("accelrig.tui")}
    return graph


def test_no_import_cycle_in_the_tui():
    graph = tui_imports()
    assert "accelrig.tui.screens.wizard" in graph and "accelrig.tui.app" in graph
    state: dict[str, str] = {}

    def visit(name: str, path: list[str]) -> None:
        state[name] = "open"
        for target in sorted(graph.get(name, ())):
            if state.get(target) == "open":
                raise AssertionError("import cycle: " + " -> ".join(path[path.index(target):] + [target]))
            if target not in state:
                visit(target, path + [target])
        state[name] = "done"

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])


def test_screens_never_import_the_app():
    assert not [name for name, targets in tui_imports().items() if "accelrig.tui.app" in targets
                and name.startswith("accelrig.tui.screens")]
