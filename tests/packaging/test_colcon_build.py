"""`colcon build` of the package in a workspace of its own, and `ros2 run`'s view of it.

No ros2cli here, so the test does what ``ros2 run sensorispace_ros <exe>`` does:
source ``<install>/local_setup.sh``, ask the ament index for the package's
prefix and take the executable from ``<prefix>/lib/sensorispace_ros/``.
(A ``pip install -e .`` puts the console scripts in <venv>/bin instead.)
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from packaging_support import CONFIG_DIR, PACKAGE, REPO, console_scripts

from shared import free_domain_id

COLCON = Path(sys.prefix) / "bin" / "colcon"
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    assert COLCON.is_file(), f"{COLCON} missing: scripts/bootstrap.sh installs it from the lock"
    ws = tmp_path_factory.mktemp("colcon_ws")
    (ws / "src").mkdir()
    (ws / "src" / PACKAGE).symlink_to(REPO, target_is_directory=True)
    # a plain build: --symlink-install runs `setup.py develop --editable`, which
    # setuptools >= 80 rejects ("option --editable not recognized")
    done = subprocess.run(
        [str(COLCON), "--log-base", str(ws / "log"), "build", "--base-paths", str(ws / "src"),
         "--build-base", str(ws / "build"), "--install-base", str(ws / "install")],
        cwd=ws, capture_output=True, text=True, timeout=120,
        env={**os.environ, "COLCON_HOME": str(ws / "colcon_home")})  # no user defaults.yaml
    assert done.returncode == 0, done.stdout + done.stderr
    return ws


@pytest.fixture(scope="module")
def sourced(workspace) -> dict:
    """The environment after ``. <install>/local_setup.sh``, discovery kept on this host."""
    base = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "ROS_DOMAIN_ID": str(free_domain_id())}
    base.pop("PYTHONPATH", None)
    done = subprocess.run(["bash", "-c", '. "$0/local_setup.sh" && env -0',
                           str(workspace / "install")],
                          env=base, capture_output=True, timeout=60)
    assert done.returncode == 0, done.stderr.decode()
    return dict(entry.split("=", 1) for entry in done.stdout.decode().split("\0") if "=" in entry)


def run_python(code: str, env: dict, cwd: Path) -> list[str]:
    """``python -c`` in ``cwd`` (it is first on sys.path: not the source tree)."""
    done = subprocess.run([sys.executable, "-c", code], env=env, cwd=cwd, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout.splitlines()


def test_colcon_builds_it_as_ament_python(workspace):
    log = next((workspace / "log").glob("build_*/logger_all.log")).read_text()
    assert f"with type 'ros.ament_python' and name '{PACKAGE}'" in log
    assert "colcon_ros.task.ament_python.build:Building ROS package" in log


def test_ros2_run_finds_every_console_script(workspace, sourced):
    [prefix] = run_python("from ament_index_python.packages import get_package_prefix; "
                          f"print(get_package_prefix({PACKAGE!r}))", sourced, workspace)
    assert Path(prefix) == workspace / "install" / PACKAGE
    executables = {p.name for p in (Path(prefix) / "lib" / PACKAGE).iterdir()
                   if p.is_file() and os.access(p, os.X_OK)}
    assert executables == set(console_scripts())


def test_the_sourced_workspace_imports_the_installed_package(workspace, sourced):
    """Every console script's target resolves, from the install, not the source tree."""
    targets = sorted(console_scripts().values())
    lines = run_python(
        "import importlib, sys\n"
        f"for target in {targets!r}:\n"
        "    module, function = target.split(':')\n"
        "    module = importlib.import_module(module)\n"
        "    assert callable(getattr(module, function)), target\n"
        "    print(module.__file__)\n", sourced, workspace)
    site = workspace / "install" / PACKAGE / "lib"
    assert len(lines) == len(targets)
    assert all(Path(line).is_relative_to(site) for line in lines), lines


def test_the_share_holds_package_xml_configs_and_launch_file(workspace):
    share = workspace / "install" / PACKAGE / "share" / PACKAGE
    assert (share / "package.xml").read_bytes() == (REPO / "package.xml").read_bytes()
    assert {p.name for p in (share / "config").iterdir()} == \
        {p.name for p in CONFIG_DIR.glob("*.yaml")}
    assert (share / "launch" / "graph.launch.py").is_file()
    assert (share / "msg_schemas" / "topics.yaml").is_file()


def test_an_installed_node_rejects_a_bad_parameter_by_name(workspace, sourced):
    prefix = workspace / "install" / PACKAGE
    done = subprocess.run(
        [str(prefix / "lib" / PACKAGE / "body"), "--ros-args",
         "--params-file", str(prefix / "share" / PACKAGE / "config" / "smoke.yaml"),
         "-p", "world.grid_count:=1"],
        env=sourced, cwd=workspace, capture_output=True, text=True, timeout=60)
    output = done.stdout + done.stderr
    assert done.returncode != 0, output
    assert "world.grid_count" in output and "Traceback" not in output, output
