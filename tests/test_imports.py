"""The package's import graph, read from the source (AST; imports inside
functions and ``if TYPE_CHECKING`` blocks count): no circle, and no module
imports a layer above its own (the order is docs/design.md's "Layers").
Nothing here imports the package except the rclpy-free check, which runs in
a subprocess."""
from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from shared import REPO

PACKAGE_NAME = "sensorispace_ros"
# Lowest first. A module may import its own layer and the layers below it.
LAYERS = (
    ("core", "config"),
    ("bodies",),
    ("protocol", "contracts", "messages", "progress"),
    ("state",),
    ("recording",),
    ("offline",),
    ("evaluation",),
    ("graph",),
    ("cli",),
)
# Where rclpy may be imported: the graph (the CLI reaches it through graph/ only),
# and inside the functions of contracts that make the nodes' QoS and endpoints.
RCLPY_ALLOWED = ("graph",)
RCLPY_INSIDE_FUNCTIONS = (f"{PACKAGE_NAME}.contracts",)


def module_files(root: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package under ``root``."""
    out = {}
    for path in sorted((root / PACKAGE_NAME).rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def imported_names(name: str, path: Path) -> list[tuple[str, int]]:
    """(absolute dotted name, line) of every import in the module, at any depth;
    ``from a import b`` gives ``a.b`` (a module or a name in ``a``)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            found += [(f"{base}.{alias.name}", node.lineno) for alias in node.names]
    return found


def import_graph(root: Path) -> dict[str, dict[str, int]]:
    """module -> {internal module it imports: line of the first such import}."""
    files = module_files(root)

    def resolve(dotted: str) -> str | None:
        while dotted and dotted not in files:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    graph: dict[str, dict[str, int]] = {}
    for name, path in files.items():
        edges = graph.setdefault(name, {})
        for dotted, line in imported_names(name, path):
            target = resolve(dotted)
            if target is not None and target not in (name, PACKAGE_NAME):
                edges.setdefault(target, line)
    return graph


def circles(graph: dict[str, dict]) -> list[list[str]]:
    """Every strongly connected component of more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def layer_of(module: str, layers=LAYERS) -> int | None:
    parts = module.split(".")
    if len(parts) < 2:
        return None
    return next((k for k, layer in enumerate(layers) if parts[1] in layer), None)


def layer_violations(graph: dict[str, dict[str, int]], layers=LAYERS) -> list[str]:
    """Imports of a higher layer, and modules in no layer."""
    out = []
    for module, edges in sorted(graph.items()):
        if module == PACKAGE_NAME:
            continue
        own = layer_of(module, layers)
        if own is None:
            out.append(f"{module}: in no layer of LAYERS")
            continue
        for target, line in sorted(edges.items()):
            theirs = layer_of(target, layers)
            if theirs is not None and theirs > own:
                out.append(f"{module}:{line} imports {target} (layer {layers[theirs]} "
                           f"above {layers[own]})")
    return out


def check(root: Path) -> list[str]:
    """Every problem of the package under ``root``: circles, then layer violations."""
    graph = import_graph(root)
    problems = [f"import circle: {' <-> '.join(c)}" for c in circles(graph)]
    return problems + layer_violations(graph)


def test_the_package_has_no_import_circle_and_follows_the_layer_order():
    graph = import_graph(REPO)
    assert len(graph) > 100 and sum(map(len, graph.values())) > 200, "the graph was not read"
    problems = check(REPO)
    assert problems == [], "\n".join(problems)


def test_function_level_and_relative_imports_are_read(tmp_path):
    package = tmp_path / PACKAGE_NAME
    (package / "core").mkdir(parents=True)
    for name in ("__init__.py", "core/__init__.py", "core/a.py", "core/c.py"):
        (package / name).write_text("")
    (package / "core" / "b.py").write_text(textwrap.dedent("""\
        def f():
            from . import a
            from .c import thing
            import sensorispace_ros.core.a
        """))
    assert import_graph(tmp_path)[f"{PACKAGE_NAME}.core.b"] == {
        f"{PACKAGE_NAME}.core.a": 2, f"{PACKAGE_NAME}.core.c": 3}


def test_the_checker_finds_a_circle_in_a_synthetic_graph():
    graph = {"p.a": {"p.b": 1}, "p.b": {"p.c": 1}, "p.c": {"p.a": 1}, "p.d": {"p.a": 1}}
    assert circles(graph) == [["p.a", "p.b", "p.c"]]
    assert circles({"p.a": {"p.b": 1}, "p.b": {}}) == []


def test_a_circle_planted_in_a_copy_of_the_package_fails_the_check(tmp_path):
    shutil.copytree(REPO / PACKAGE_NAME, tmp_path / PACKAGE_NAME,
                    ignore=shutil.ignore_patterns("__pycache__"))
    assert check(tmp_path) == check(REPO)
    # offline.strategies already imports core.run_world; a function-level import
    # back closes a circle, and a core module importing offline breaks the order.
    planted = tmp_path / PACKAGE_NAME / "core" / "run_world.py"
    planted.write_text(planted.read_text() + textwrap.dedent("""

        def _planted():
            from sensorispace_ros.offline.strategies import pov_params
            return pov_params
        """))
    problems = check(tmp_path)
    assert any(p.startswith("import circle:") and f"{PACKAGE_NAME}.core.run_world" in p
               and f"{PACKAGE_NAME}.offline.strategies" in p for p in problems), problems
    assert any(p.startswith(f"{PACKAGE_NAME}.core.run_world:") and "offline.strategies" in p
               for p in problems), problems


def test_only_the_graph_imports_rclpy():
    outside = []
    for name, path in module_files(REPO).items():
        if layer_of(name) is not None and LAYERS[layer_of(name)] == RCLPY_ALLOWED:
            continue
        top_level = {node.lineno for node in ast.parse(path.read_text()).body}
        outside += [f"{name}:{line}" for dotted, line in imported_names(name, path)
                    if dotted.split(".")[0] == "rclpy"
                    and (name not in RCLPY_INSIDE_FUNCTIONS or line in top_level)]
    assert outside == []


BLOCK_RCLPY = """
import importlib, importlib.abc, pkgutil, sys

class NoRclpy(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] == "rclpy":
            raise ImportError(f"{name} cannot load here")

sys.meta_path.insert(0, NoRclpy())
try:
    import rclpy
except ImportError:
    pass
else:
    raise SystemExit("the blocker let rclpy load")
import sensorispace_ros.evaluation, sensorispace_ros.recording
imported = []
for package in (sensorispace_ros.recording, sensorispace_ros.evaluation):
    for module in pkgutil.iter_modules(package.__path__):
        imported.append(importlib.import_module(f"{package.__name__}.{module.name}").__name__)
from sensorispace_ros import contracts
assert contracts.contract("/agent/points_of_view").type_name == "sensor_msgs/msg/PointCloud2"
assert "rclpy" not in sys.modules
print(len(imported), "modules")
"""


@pytest.mark.timeout(120)
def test_recording_and_evaluation_import_where_rclpy_cannot_load():
    done = subprocess.run([sys.executable, "-c", BLOCK_RCLPY], capture_output=True, text=True,
                          cwd=REPO, timeout=120)
    assert done.returncode == 0, done.stderr
    assert int(done.stdout.split()[0]) >= 15
