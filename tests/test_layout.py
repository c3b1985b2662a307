"""The package's shape: short modules and functions, a pure core, scripts that end
with their ``__main__`` guard. Read from the source (AST), nothing is imported."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "sensorispace_ros"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 60            # from the first decorator to the last line, docstring included
MAX_NODE_MODULE_LINES = 299        # a graph node module is a thin adapter: under 300 lines
NODES = PACKAGE / "graph" / "nodes"
# What core/ may import from its own package: core itself and the parameter
# table (pure Python and yaml), and the package's (empty) __init__; the rest of
# the package reaches ROS.
CORE_MAY_IMPORT = ("sensorispace_ros.core", "sensorispace_ros.config")
PACKAGE_NAME = "sensorispace_ros"
ROS_PACKAGES = {"rclpy", "rcl_interfaces", "rosidl_runtime_py", "rosidl_parser", "rosbag2_py",
                "builtin_interfaces", "launch", "launch_ros", "ament_index_python", "tf2_ros",
                "message_filters"}
ROS_SUFFIXES = ("_msgs", "_srvs", "_interfaces")


def modules(under: Path = PACKAGE) -> list[Path]:
    return sorted(p for p in under.rglob("*.py") if "__pycache__" not in p.parts)


def tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), filename=str(path))


def name(path: Path) -> str:
    return str(path.relative_to(PACKAGE.parent)) if PACKAGE.parent in path.parents else path.name


def long_modules(paths: list[Path], limit: int = MAX_MODULE_LINES) -> list[str]:
    return [f"{name(p)}: {n} lines (limit {limit})" for p in paths
            if (n := len(p.read_text().splitlines())) > limit]


def size_offenders(paths: list[Path]) -> list[str]:
    """Every module, node module and function over its limit."""
    nodes = [p for p in paths if p.parent == NODES and p.name != "__init__.py"]
    return (long_modules(paths) + long_modules(nodes, MAX_NODE_MODULE_LINES)
            + [f"{where}: {n} lines (limit {MAX_FUNCTION_LINES})"
               for n, where in function_lengths(paths) if n > MAX_FUNCTION_LINES])


def function_lengths(paths: list[Path]) -> list[tuple[int, str]]:
    """(lines, where) of every function and method, longest first."""
    out = []
    for path in paths:
        for node in ast.walk(tree(path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                start = min([node.lineno] + [d.lineno for d in node.decorator_list])
                out.append((node.end_lineno - start + 1, f"{name(path)}:{node.lineno} {node.name}"))
    return sorted(out, reverse=True)


def imported_modules(path: Path) -> set[str]:
    """Every module ``path`` imports, at any depth (inside functions too),
    relative imports resolved against the package."""
    package = name(path)[:-len(".py")].replace("/", ".").rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree(path)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                module = base + ("." + node.module if node.module else "")
            else:
                module = node.module
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return found


def is_ros(module: str) -> bool:
    top = module.split(".")[0]
    return top in ROS_PACKAGES or top.endswith(ROS_SUFFIXES)


def within(module: str, packages: tuple[str, ...]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in packages)


def core_import_violations(paths: list[Path]) -> list[str]:
    out = []
    for path in paths:
        for module in sorted(imported_modules(path)):
            outside = within(module, (PACKAGE_NAME,)) and module != PACKAGE_NAME \
                and not within(module, CORE_MAY_IMPORT)
            if is_ros(module) or outside:
                out.append(f"{name(path)} imports {module}")
    return out


def is_main_guard(node: ast.stmt) -> bool:
    test = getattr(node, "test", None)
    return (isinstance(node, ast.If) and isinstance(test, ast.Compare)
            and isinstance(test.left, ast.Name) and test.left.id == "__name__"
            and len(test.comparators) == 1 and isinstance(test.comparators[0], ast.Constant)
            and test.comparators[0].value == "__main__")


def after_main_guard(paths: list[Path]) -> list[str]:
    out = []
    for path in paths:
        body = tree(path).body
        guards = [i for i, node in enumerate(body) if is_main_guard(node)]
        if guards and guards[0] < len(body) - 1:
            late = body[guards[0] + 1]
            out.append(f"{name(path)}:{late.lineno} comes after the __main__ guard")
    return out


def test_modules_node_modules_and_functions_fit_their_size_limits():
    paths = modules()
    assert function_lengths(paths) and any(p.parent == NODES for p in paths), "nothing read"
    offenders = size_offenders(paths)
    assert offenders == [], f"{len(offenders)} over their limit:\n" + "\n".join(offenders)


def test_the_size_check_counts_decorators_and_docstrings(tmp_path):
    body = "\n".join(f"    x{k} = {k}" for k in range(MAX_FUNCTION_LINES - 3))
    source = f'@staticmethod\ndef f():\n    """Doc.\n    more"""\n{body}\n'
    (tmp_path / "m.py").write_text(source)
    assert function_lengths([tmp_path / "m.py"])[0][0] == MAX_FUNCTION_LINES + 1


def test_core_imports_neither_rclpy_nor_ros_messages_nor_the_ros_layers():
    core = modules(PACKAGE / "core")
    assert any(imported_modules(p) for p in core), "no import found in core/"
    assert core_import_violations(core) == []


def test_a_main_guard_is_the_last_statement_of_its_module():
    guarded = [p for p in modules() if any(is_main_guard(n) for n in tree(p).body)]
    assert guarded, "no module with a __main__ guard found"
    assert after_main_guard(guarded) == []
