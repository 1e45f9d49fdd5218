"""Architecture checks: the ``wovenskin`` modules import one another without circles.

Every module under ``wovenskin/`` is parsed with :mod:`ast` (nothing is imported), and
each import of a ``wovenskin`` module becomes an edge of the module graph, whether it
sits at module level or inside a function (relative imports are resolved). Imports
under ``if TYPE_CHECKING:`` are left out, since they never run. ``from package import
name`` points at ``package.name`` when that is a module, else at the package. The
packages a dotted import passes through on its way are not edges of their own.
"""

from __future__ import annotations

import ast

from module_graph import PACKAGE_ROOT, _modules, _runtime_imports, import_graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` as ``[a, b, ..., a]``, or None when there is none."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(graph.get(node, ())):
            if state.get(target) == 1:
                return [*path[path.index(target) :], target]
            if target not in state:
                cycle = visit(target)
                if cycle:
                    return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state:
            cycle = visit(start)
            if cycle:
                return cycle
    return None


def test_the_graph_sees_the_package():
    graph = import_graph()
    assert "wovenskin.cli" in graph
    assert "wovenskin.sim.motion" in graph["wovenskin.sim.performances"]


def test_find_cycle_reports_the_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert find_cycle(graph) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_circles():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import circle: " + " -> ".join(cycle or [])


# The pipeline's layers, bottom first.  A module may import modules of its own package and
# of packages in lower layers, never of a package in its own or a higher layer.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("wovenskin",),  # the top-level modules: errors, io, settings, specs, outputs, gestures
    ("ros2",),  # ROS 2 without a ROS install: message types, DDS entities, topic names
    ("skin",),
    ("recording", "signal"),
    ("tracking",),  # fingertips followed as tracks, the touch so far
    ("sim", "independent", "recognition"),  # independent: people and skins apart from sim
    ("robots",),
    ("tasks",),  # study task scenes on the simulated arm
    ("control", "training"),
    ("teleop",),  # keyboard and teach pendant: inputs beside the skin
    ("runtime",),
    ("operators",),  # simulated operators: people with human timing at an interface
    ("study",),  # user studies: plans, trials, reports
    ("ui",),
    ("bench",),  # benchmarks measure every stage, the dashboard too
    ("reproduce",),  # the paper's evaluation regenerated: recognition, study, report
    ("cli",),
)
LAYER_OF = {package: level for level, packages in enumerate(LAYERS) for package in packages}


def _package(module: str) -> str:
    """The package directly under ``wovenskin`` that holds ``module``; ``wovenskin`` for the
    top-level modules."""
    parts = module.split(".")
    is_package = len(parts) > 1 and (PACKAGE_ROOT / parts[1]).is_dir()
    return parts[1] if is_package else "wovenskin"


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Each import of a module in a same or higher layer's other package, as ``a -> b``."""
    found = []
    for module, targets in sorted(graph.items()):
        mine = _package(module)
        for target in sorted(targets):
            theirs = _package(target)
            if theirs != mine and LAYER_OF[theirs] >= LAYER_OF[mine]:
                found.append(f"{module} -> {target}")
    return found


def test_every_package_has_a_layer():
    missing = {_package(m) for m in import_graph()} - set(LAYER_OF)
    assert not missing, f"packages without a layer in LAYERS: {missing}"


def test_upward_imports_are_found():
    graph = {"wovenskin.skin.a": {"wovenskin.sim.b"}, "wovenskin.sim.b": {"wovenskin.skin.a"}}
    assert upward_imports(graph) == ["wovenskin.skin.a -> wovenskin.sim.b"]
    graph = {"wovenskin.sim.b": {"wovenskin.recognition.c"}}  # the same layer: not allowed
    assert upward_imports(graph) == ["wovenskin.sim.b -> wovenskin.recognition.c"]


def test_every_stage_imports_only_stages_below_it():
    upward = upward_imports(import_graph())
    assert not upward, "upward imports:\n" + "\n".join(upward)


MAX_MODULE_LINES = 500  # a module past this is doing two jobs


def test_no_module_is_too_long():
    long = {
        str(path.relative_to(PACKAGE_ROOT)): n
        for path in PACKAGE_ROOT.rglob("*.py")
        if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


# Where an import of a wovenskin module may sit inside a function: the command line (each
# command imports its library code when it runs, so `wovenskin --help` stays fast) and a
# package's module-level __getattr__ (a submodule that is also run with `python -m`), and the
# ros2 robot spec, which loads its backend (and the optional cyclonedds) only when built.
LAZY_IMPORTS_ALLOWED = ("wovenskin.cli", "wovenskin.robots.techman", "wovenskin.robots.ros2.config")


def function_level_imports() -> list[str]:
    """``module:line`` of each import of a wovenskin module inside a function or class."""
    found = []
    for name, path in _modules().items():
        if name.startswith(LAZY_IMPORTS_ALLOWED):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for top in tree.body:
            if not isinstance(top, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                continue
            for node in _runtime_imports(top):
                modules = (
                    [alias.name for alias in node.names]
                    if isinstance(node, ast.Import)
                    else [node.module or ""]
                )
                relative = isinstance(node, ast.ImportFrom) and node.level > 0
                if relative or any(m.split(".")[0] == "wovenskin" for m in modules):
                    found.append(f"{name}:{node.lineno}")
    return found


def test_wovenskin_modules_are_imported_at_module_top():
    lazy = function_level_imports()
    assert not lazy, "imports inside functions: " + ", ".join(lazy)
