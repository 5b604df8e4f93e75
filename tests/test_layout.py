"""The package layout: no import circles, the profile fitter independent of the audit, a short top
level, the downstream tasks on their shared base, and no module named like a public name of its
package (design.md, "The shape")."""

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
    """Module or function level: `_imports` counts the imports inside functions too."""
    assert _cycle(import_graph()) is None, f"import circle: {' -> '.join(_cycle(import_graph()))}"


def test_cycle_finder_finds_a_circle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]


def test_imports_inside_functions_count(tmp_path):
    path = tmp_path / "b.py"
    path.write_text("import g2r_jax.c\n\ndef f():\n    from g2r_jax import a\n    from .d import e\n")
    modules = {"g2r_jax.a": None, "g2r_jax.b": None, "g2r_jax.c": None, "g2r_jax.d": None}
    assert _imports("g2r_jax.b", path, modules) == {"g2r_jax.a", "g2r_jax.c", "g2r_jax.d"}


# The rooms from the bottom up (design.md, "The shape"; issue 35): a module imports only its own
# room's modules and those of rooms below it. Rooms on one line are peers.
LAYERS = (("io",), ("measure",), ("sensor",), ("colour",), ("examples", "illuminants"), ("content",),
          ("profile", "pipeline"), ("batch",), ("audit",), ("downstream",), ("cli",))
UTILITIES = ("runtime",)              # any room may import these; they import none of the rooms
TOP = "g2r_jax"                       # the public API: imports anything; imported as the audit's peer
_TOP_LAYER = next(k for k, rooms in enumerate(LAYERS) if "audit" in rooms)   # it re-exports `diagnose`


def layer_of(module: str) -> int | None:
    """The layer index of a package module (-1 for the utilities), None for a room not in LAYERS."""
    if module == TOP:
        return _TOP_LAYER
    room = module.split(".")[1]
    if room in UTILITIES:
        return -1
    return next((k for k, rooms in enumerate(LAYERS) if room in rooms), None)


def layer_violations(graph) -> list[str]:
    """'importer -> imported' for every import that runs up the layers (or from an unplaced room)."""
    found = []
    for importer, targets in sorted(graph.items()):
        if importer == TOP:
            continue
        own = layer_of(importer)
        for target in sorted(targets):
            above = layer_of(target)
            if own is None or above is None or (own == -1 and above != -1) or above > own:
                found.append(f"{importer} -> {target}")
    return found


def test_no_import_runs_up_the_layers():
    violations = layer_violations(import_graph())
    assert not violations, f"{len(violations)} import(s) against the layers {LAYERS}:\n" + "\n".join(violations)


def test_layer_check_finds_an_upward_import():
    graph = {"g2r_jax.sensor.x": {"g2r_jax.profile.schema", "g2r_jax.io.y"}, "g2r_jax.io.y": {"g2r_jax.runtime.z"},
             "g2r_jax.runtime.z": {"g2r_jax.io.y"}, "g2r_jax.nowhere": set(), TOP: {"g2r_jax.cli.a"}}
    assert layer_violations(graph) == ["g2r_jax.runtime.z -> g2r_jax.io.y", "g2r_jax.sensor.x -> g2r_jax.profile.schema"]
    assert layer_of("g2r_jax.pipeline") == layer_of("g2r_jax.profile.fitting") > layer_of("g2r_jax.content.model")


# Inside `downstream` (issue 52): one shared base at the bottom, one sub-package per task above it
# (peers: none imports another), and the check that runs every task on top (the package's own
# modules: `check`, `inputs`, `report`). Below `downstream`, the rooms of LAYERS as for any module.
DOWNSTREAM = "g2r_jax.downstream"
DOWNSTREAM_BASE = "base"
DOWNSTREAM_TASKS = {"illuminant": "experiment", "denoising": "burst_check", "isp": "task"}   # task: its run


def downstream_part(module: str) -> str | None:
    """'base', a task's name or 'check' (the package and its top-level modules) for a module of
    `downstream`; None for any other module."""
    if module != DOWNSTREAM and not module.startswith(DOWNSTREAM + "."):
        return None
    parts = module.split(".")
    if len(parts) > 2 and parts[2] in (DOWNSTREAM_BASE, *DOWNSTREAM_TASKS):
        return parts[2]
    return "check"


def downstream_violations(graph) -> list[str]:
    """'importer -> imported' for every import inside `downstream` against its order: the base
    importing a task or the check, a task importing another task or the check."""
    found = []
    for importer, targets in sorted(graph.items()):
        own = downstream_part(importer)
        if own is None or own == "check":
            continue
        for target in sorted(targets):
            theirs = downstream_part(target)
            if theirs not in (None, own, DOWNSTREAM_BASE):
                found.append(f"{importer} -> {target}")
    return found


def test_downstream_holds_one_sub_package_per_task_on_the_shared_base():
    root = PACKAGE / "downstream"
    on_disk = {p.parent.name for p in root.glob("*/__init__.py")}
    assert on_disk == {DOWNSTREAM_BASE, *DOWNSTREAM_TASKS}, sorted(on_disk)
    assert not list(root.glob("*/*/__init__.py")), "one level of sub-packages"


def test_downstream_tasks_import_only_the_shared_base():
    """A task's modules import their own task's, the base's and lower rooms' (LAYERS), never
    another task's nor the check's; the base imports no task; both module level and in functions."""
    graph = import_graph()
    violations = downstream_violations(graph)
    assert not violations, f"{len(violations)} import(s) across the downstream tasks:\n" + "\n".join(violations)
    for task, run in DOWNSTREAM_TASKS.items():    # the rule is not empty: every task stands on the base
        reached = {downstream_part(m) for m in _reachable(graph, f"{DOWNSTREAM}.{task}.{run}")}
        assert reached - {None} == {task, DOWNSTREAM_BASE}, (task, reached)


def test_downstream_check_finds_an_import_across_tasks():
    graph = {"g2r_jax.downstream.isp.task": {"g2r_jax.downstream.illuminant.experiment",
                                             "g2r_jax.downstream.base.training", "g2r_jax.measure"},
             "g2r_jax.downstream.base.cache": {"g2r_jax.downstream.report"},
             "g2r_jax.downstream.denoising.noise": {"g2r_jax.downstream.denoising.bursts"},
             "g2r_jax.downstream.check": {"g2r_jax.downstream.isp.task", "g2r_jax.downstream.denoising"},
             "g2r_jax.downstream.illuminant": {"g2r_jax.downstream.denoising.bursts"}}
    assert downstream_violations(graph) == ["g2r_jax.downstream.base.cache -> g2r_jax.downstream.report",
                                            "g2r_jax.downstream.illuminant -> g2r_jax.downstream.denoising.bursts",
                                            "g2r_jax.downstream.isp.task -> g2r_jax.downstream.illuminant.experiment"]
    assert downstream_part("g2r_jax.downstream") == downstream_part("g2r_jax.downstream.report") == "check"
    assert downstream_part("g2r_jax.downstream.base") == "base" and downstream_part("g2r_jax.measure") is None


MAX_FUNCTION_LINES = 100


def long_functions(paths, root: Path = PACKAGE.parent) -> list[str]:
    """'path:line name (n lines)' for every function or method, nested ones included, over
    MAX_FUNCTION_LINES lines from its def to its last line (end_lineno - lineno + 1)."""
    found = []
    for path in paths:
        for node in ast.walk(ast.parse(Path(path).read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    found.append(f"{Path(path).relative_to(root)}:{node.lineno} {node.name} ({length} lines)")
    return found


def test_no_function_over_100_lines():
    found = long_functions(sorted(PACKAGE.rglob("*.py")))
    assert not found, f"{len(found)} function(s) over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(found)


def test_long_function_finder_counts_lines(tmp_path):
    lines = [f"x{k} = {k}" for k in range(MAX_FUNCTION_LINES - 1)]
    body = lambda indent: "\n".join(indent + line for line in lines)
    path = tmp_path / "m.py"
    path.write_text(f"def fits():\n{body('    ')}\n\n\nclass C:\n    def too_long(self):\n{body(' ' * 8)}\n"
                    "        return 1\n")
    too_long_at = 1 + len(lines) + 3 + 1   # fits, its body, two blank lines and the class line
    assert long_functions([path], tmp_path) == [f"m.py:{too_long_at} too_long ({MAX_FUNCTION_LINES + 1} lines)"]


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
