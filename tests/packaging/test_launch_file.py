"""launch/graph.launch.py, read as source (no launch/launch_ros here): it starts
console scripts that exist, the nodes the graph runs, with parameter files that exist;
and run with stand-ins for launch and launch_ros: ``body:=false`` leaves the
simulated body out."""
from __future__ import annotations

import ast
import importlib
import importlib.util

from packaging_support import CONFIG_DIR, LAUNCH_FILE, PACKAGE, console_scripts

from sensorispace_ros.config import GRAPH_PREFIX, GRAPH_SCHEMA
from sensorispace_ros.graph.launcher import GRAPH_NODES, RECORDER, VIEWER


def tree() -> ast.Module:
    return ast.parse(LAUNCH_FILE.read_text(), filename=str(LAUNCH_FILE))


def module_constants() -> dict:
    return {target.id: node.value.value for node in tree().body if isinstance(node, ast.Assign)
            for target in node.targets if isinstance(target, ast.Name)
            and isinstance(node.value, ast.Constant)}


def node_calls() -> list[ast.Call]:
    return [call for call in ast.walk(tree()) if isinstance(call, ast.Call)
            and getattr(call.func, "id", getattr(call.func, "attr", None)) == "Node"]


def literal(expr: ast.expr, constants: dict):
    """A string the launch file writes literally or through a module constant."""
    if isinstance(expr, ast.Constant):
        return expr.value
    if isinstance(expr, ast.Name) and expr.id in constants:
        return constants[expr.id]
    raise AssertionError(f"{LAUNCH_FILE.name}:{expr.lineno}: not a literal: {ast.unparse(expr)}")


def keywords(call: ast.Call) -> dict[str, ast.expr]:
    return {k.arg: k.value for k in call.keywords}


def launched() -> dict[str, ast.Call]:
    constants = module_constants()
    nodes = {}
    for call in node_calls():
        kw = keywords(call)
        assert literal(kw["package"], constants) == PACKAGE
        nodes[literal(kw["executable"], constants)] = call
    return nodes


def test_every_executable_is_a_console_script_of_setup_py():
    scripts = console_scripts()
    unknown = sorted(set(launched()) - set(scripts))
    assert not unknown, f"{LAUNCH_FILE.name} starts {unknown}, not console scripts of setup.py"


def test_it_starts_every_node_the_graph_runs():
    assert set(launched()) == {*GRAPH_NODES, RECORDER, VIEWER}


def test_every_parameter_file_it_names_is_in_config():
    names = [n.value for n in ast.walk(tree()) if isinstance(n, ast.Constant)
             and isinstance(n.value, str) and n.value.endswith((".yaml", ".yml"))]
    assert names, "the launch file names no parameter file"
    missing = [name for name in names if not (CONFIG_DIR / name).is_file()]
    assert not missing, f"{LAUNCH_FILE.name} names {missing}, not files of {CONFIG_DIR}"


def test_every_node_gets_the_config_argument_as_its_first_parameter_file():
    for executable, call in launched().items():
        parameters = keywords(call)["parameters"]
        assert isinstance(parameters, ast.List) and parameters.elts, executable
        first = parameters.elts[0]
        assert isinstance(first, ast.Name) and first.id == "config", executable
    assigned = [n for n in ast.walk(tree()) if isinstance(n, ast.Assign)
                and any(getattr(t, "id", None) == "config" for t in n.targets)]
    assert [ast.unparse(n.value) for n in assigned] == ["arg['config']"]
    declared = [literal(call.args[0], {}) for call in ast.walk(tree())
                if isinstance(call, ast.Call) and getattr(call.func, "id", "") ==
                "DeclareLaunchArgument"]
    assert "config" in declared


def test_graph_parameters_it_sets_are_in_the_graph_schema():
    """Nodes refuse a graph.* name config.GRAPH_SCHEMA does not have."""
    names = {n.value for n in ast.walk(tree()) if isinstance(n, ast.Constant)
             and isinstance(n.value, str) and n.value.startswith(GRAPH_PREFIX)}
    assert names
    assert not sorted(names - {GRAPH_PREFIX + key for key in GRAPH_SCHEMA})


def test_what_it_imports_from_the_package_exists():
    for node in ast.walk(tree()):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(PACKAGE):
            module = importlib.import_module(node.module)
            for alias in node.names:
                assert hasattr(module, alias.name), f"{node.module}.{alias.name}"



def test_the_environment_it_sets_is_what_graph_environment_gives():
    from sensorispace_ros.graph.dds_environment import graph_environment

    keys = module_constants_tuple("GRAPH_ENVIRONMENT")
    assert set(keys) <= set(graph_environment(1, base={}))


def module_constants_tuple(name: str) -> tuple:
    [value] = [ast.literal_eval(node.value) for node in tree().body
               if isinstance(node, ast.Assign)
               and any(getattr(t, "id", None) == name for t in node.targets)]
    return value


class _Recorded:
    """Stands for a launch action: keeps what it was given."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


def _launch_module(monkeypatch):
    """The launch file imported with stand-ins for launch, launch_ros and
    ament_index_python (not installable from pip wheels)."""
    import sys
    import types

    stand_ins = {
        "ament_index_python": {}, "launch_ros": {},
        "ament_index_python.packages": {"get_package_share_directory": lambda name: "/share"},
        "launch": {"LaunchDescription": _Recorded},
        "launch.actions": {name: type(name, (_Recorded,), {}) for name in (
            "DeclareLaunchArgument", "LogInfo", "OpaqueCoroutine", "OpaqueFunction",
            "RegisterEventHandler", "SetEnvironmentVariable", "Shutdown")},
        "launch.event_handlers": {"OnProcessExit": _Recorded},
        "launch.events": {"Shutdown": _Recorded},
        "launch_ros.actions": {"Node": type("Node", (_Recorded,), {})}}
    for name, attributes in stand_ins.items():
        module = types.ModuleType(name)
        vars(module).update(attributes)
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location("graph_launch", LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _started_nodes(monkeypatch, tmp_path, **arguments):
    module = _launch_module(monkeypatch)
    declared = {action.args[0]: action.kwargs["default_value"]
                for action in module.generate_launch_description().args[0]
                if type(action).__name__ == "DeclareLaunchArgument"}
    values = {**declared, "results_dir": str(tmp_path / "results"),
              "bags_dir": str(tmp_path / "bags"), "run": "r", "domain_id": "7", **arguments}
    context = type("Context", (), {"launch_configurations": values})()
    return {action.kwargs["executable"]: action.kwargs["parameters"]
            for action in module.graph(context) if type(action).__name__ == "Node"}


def test_body_false_leaves_the_simulated_body_out_and_waits_for_the_users(monkeypatch, tmp_path):
    simulated = _started_nodes(monkeypatch, tmp_path, record="false")
    assert set(simulated) == {"environment", "body", "agent", "representation"}
    own = _started_nodes(monkeypatch, tmp_path, record="false", body="false",
                         body_node="my_arm")
    assert set(own) == {"environment", "agent", "representation"}
    waited = own["environment"][1]["graph.wait_for_nodes"]
    assert waited == ["my_arm", "agent", "representation"]
    # Only the representation's exit ends the launch; the others wait to be stopped.
    assert [own[name][1]["graph.exit_when_done"] for name in ("agent", "representation")] \
        == [False, True]
