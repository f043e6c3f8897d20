"""The package layout the architecture promises: dependencies one way, no import circles, small
modules. Imports are read from the source (every `import` statement, also those inside
functions), so a lazy import cannot hide a circle."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("fmus", "plant_models", "planner", "orchestrator")
MAX_MODULE_LINES = 400
# package -> packages it may import (the architecture's one-way dependencies).
ALLOWED = {
    "fmus": {"fmus"},
    "plant_models": {"plant_models"},
    "planner": {"planner", "plant_models"},
    "orchestrator": {"orchestrator", "planner", "plant_models", "fmus"},
}


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def project_modules() -> dict[str, Path]:
    return {module_name(path): path for package in PACKAGES
            for path in sorted((ROOT / package).rglob("*.py"))}


def imported_modules(path: Path, known: set[str]) -> set[str]:
    """Project modules that the file imports (`from a.b import c` counts a.b.c when c is a module,
    else a.b)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [f"{node.module}.{alias.name}" for alias in node.names]
            names = [name if name in known else node.module for name in names]
        else:
            continue
        for name in names:
            while name and name not in known:
                name = name.rpartition(".")[0]
            if name:
                found.add(name)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = project_modules()
    known = set(modules)
    return {name: imported_modules(path, known) - {name} for name, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the directed graph as a list of nodes (first repeated last), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for target in sorted(graph.get(node, ())):
            if state.get(target) == 1:
                return stack[stack.index(target):] + [target]
            if target not in state and (cycle := visit(target)):
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def package_of(module: str) -> str:
    """The top-level package, or for the orchestrator its subpackage (orchestrator.runlog)."""
    parts = module.split(".")
    return ".".join(parts[:2] if parts[0] == "orchestrator" else parts[:1])


def test_the_cycle_finder_finds_a_planted_circle():
    graph = import_graph()
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    planted = {name: set(targets) for name, targets in graph.items()}
    planted["plant_models.geometry"].add("plant_models.presets")  # the circle that was
    assert find_cycle(planted) is not None


def test_no_module_imports_a_module_that_imports_it_back():
    assert find_cycle(import_graph()) is None


def test_no_circle_between_the_orchestrator_subpackages():
    # orchestrator.scenario -> orchestrator.plants -> ... -> orchestrator.scenario would be one.
    graph: dict[str, set[str]] = {}
    for module, targets in import_graph().items():
        source = package_of(module)
        graph.setdefault(source, set()).update(
            package_of(t) for t in targets if package_of(t) != source)
    assert find_cycle(graph) is None


@pytest.mark.parametrize("package", PACKAGES)
def test_dependencies_point_one_way(package):
    wrong = sorted(f"{module} imports {target}"
                   for module, targets in import_graph().items() if module.split(".")[0] == package
                   for target in targets if target.split(".")[0] not in ALLOWED[package])
    assert wrong == []


def test_the_orchestrator_is_grouped_into_subpackages():
    loose = sorted(p.name for p in (ROOT / "orchestrator").glob("*.py") if p.name != "__init__.py")
    assert loose == []


def test_every_module_is_under_the_size_limit():
    long = sorted(f"{path.relative_to(ROOT)}: {n} lines" for path in project_modules().values()
                  if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES)
    assert long == []
