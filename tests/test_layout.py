"""The package layout: no import circles, the profile fitter independent of the audit, a short top
level, and no module named like a public name of its package (design.md, "The shape")."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "g2r_jax"


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path, modules) -> set[str]:
    """Modules of the package that `name` imports anywhere (module level or inside functions)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base)
    return {module for module in found if module in modules and module != name}


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _cycle(graph) -> list[str] | None:
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for target in sorted(graph[node]):
            if state.get(target) == "open":
                return stack[stack.index(target):] + [target]
            if target not in state and (found := visit(target)):
                return found
        state[node] = "done"
        stack.pop()
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def _reachable(graph, start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for target in graph[todo.pop()] - seen:
            seen.add(target)
            todo.append(target)
    return seen


def test_no_import_circles():
    assert _cycle(import_graph()) is None, f"import circle: {' -> '.join(_cycle(import_graph()))}"


def test_cycle_finder_finds_a_circle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]


def test_profile_fitting_and_conversion_do_not_import_the_audit():
    graph = import_graph()
    for start in ("g2r_jax.profile.fitting", "g2r_jax.batch.conversion", "g2r_jax.pipeline"):
        assert not {m for m in _reachable(graph, start) if m.startswith("g2r_jax.audit")}, start


def test_top_level_is_short():
    """The camera's stages, the jobs around them (batch, audit, downstream), I/O and commands."""
    entries = [p.name for p in PACKAGE.iterdir() if p.name != "__pycache__"]
    assert len(entries) <= 15, sorted(entries)


def test_pipeline_and_profiles_do_not_import_the_downstream_tests():
    graph = import_graph()
    for start in ("g2r_jax.profile.fitting", "g2r_jax.batch.conversion", "g2r_jax.pipeline", "g2r_jax.audit"):
        assert not {m for m in _reachable(graph, start) if m.startswith("g2r_jax.downstream")}, start


def test_no_module_named_like_a_public_name_of_its_package():
    import g2r_jax

    clashes = []
    for name, path in _modules().items():
        if path.name != "__init__.py":
            continue
        public = set(getattr(sys.modules.get(name) or __import__(name, fromlist=["_"]), "__all__", []))
        children = {p.stem for p in path.parent.glob("*.py")} | {p.name for p in path.parent.iterdir() if p.is_dir()}
        clashes += [f"{name}.{child}" for child in public & children]
    assert not clashes
    assert g2r_jax.unprocess.__name__ == "unprocess"


@pytest.mark.slow
@pytest.mark.parametrize("module", sorted(_modules()))
def test_every_module_imports_alone(module):
    result = subprocess.run([sys.executable, "-c", f"import {module}"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-2000:]
