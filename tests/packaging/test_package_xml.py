"""package.xml: every runtime requirement by its rosdep key, a real maintainer.

The keys below were looked up in rosdistro (rosdep/python.yaml for Python
libraries, jazzy/distribution.yaml for ROS packages); a requirement without
a key there is named in a package.xml comment instead of an invented key.
"""
from __future__ import annotations

import ast
import re

from packaging_support import (LAUNCH_FILE, PACKAGE, PACKAGE_XML, REPO, dependencies, package_xml,
                               package_xml_comments, requirement_names, setup_keyword)

# requirements.in name -> rosdep key of the same library
RUNTIME_KEYS = {
    "ros-jazzy-rclpy": "rclpy",
    "ros-jazzy-rmw-fastrtps-cpp": "rmw_fastrtps_cpp",
    "ros-jazzy-std-msgs": "std_msgs",
    "ros-jazzy-sensor-msgs": "sensor_msgs",
    "ros-jazzy-visualization-msgs": "visualization_msgs",
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "scikit-learn": "python3-sklearn",
    "matplotlib": "python3-matplotlib",
    "pyyaml": "python3-yaml",
    "numba": "python3-numba",
    "rosbags": "python3-rosbags-pip",
    "mcap-ros2-support": "mcap-ros2-support",
    "mcap": "mcap-ros2-support",          # a dependency of mcap-ros2-support
}
# runtime requirements rosdistro has no key for (installed with pip)
WITHOUT_ROSDEP_KEY = {"ripser", "distributed", "foxglove-sdk", "zstandard", "mujoco"}
TEST_KEYS = {"pytest": "python3-pytest", "pytest-timeout": "python3-pytest-timeout",
             "pytest-xdist": "python3-pytest-xdist", "websockets": "python3-websockets"}
# building and testing tools of the venv, not dependencies of the package
TOOLS = {"colcon-core", "colcon-ros", "colcon-python-setup-py", "coverage", "setuptools",
         "wheel"}
# dependencies of ROS packages that come with the ones above, not from requirements.in
ROS_ONLY = {"ament_index_python", "launch", "launch_ros"}


def test_every_requirement_is_classified_once():
    names = requirement_names()
    groups = [set(RUNTIME_KEYS), WITHOUT_ROSDEP_KEY, set(TEST_KEYS), TOOLS]
    unclassified = [n for n in names if not any(n in g for g in groups)]
    assert not unclassified, (f"requirements.in names {unclassified}: map each to its rosdep "
                              "key here (and in package.xml) or classify it as a tool")
    twice = [n for n in names if sum(n in g for g in groups) > 1]
    assert not twice
    stale = set().union(*groups) - set(names)
    assert not stale, f"classified here but not in requirements.in: {sorted(stale)}"


def test_every_runtime_requirement_is_an_exec_depend():
    exec_depends = dependencies("exec_depend")
    missing = {name: key for name, key in RUNTIME_KEYS.items() if key not in exec_depends}
    assert not missing, f"package.xml lacks <exec_depend> for {missing}"


def test_requirements_without_rosdep_key_are_named_in_package_xml():
    comments = package_xml_comments()
    assert not [n for n in WITHOUT_ROSDEP_KEY if not re.search(rf"\b{re.escape(n)}\b", comments)]
    assert not WITHOUT_ROSDEP_KEY & dependencies("exec_depend"), "no invented keys"


def test_test_requirements_are_test_depends():
    assert set(TEST_KEYS.values()) <= dependencies("test_depend")


def test_no_exec_depend_is_unaccounted_for():
    extra = dependencies("exec_depend") - set(RUNTIME_KEYS.values()) - ROS_ONLY
    assert not extra, f"package.xml depends on {sorted(extra)}, which nothing here explains"


def test_ros_only_dependencies_are_what_the_code_and_launch_file_import():
    imported = set()
    for path in [LAUNCH_FILE, *(REPO / PACKAGE).rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                imported.add(node.module.split(".")[0])
            elif isinstance(node, ast.Import):
                imported.update(alias.name.split(".")[0] for alias in node.names)
    assert ROS_ONLY <= imported


def test_format_3_ament_python_and_setup_py_agree():
    root = package_xml()
    assert root.get("format") == "3"
    assert root.findtext("export/build_type") == "ament_python"
    assert root.findtext("name") == PACKAGE == setup_keyword("name")
    assert root.findtext("version") == setup_keyword("version")
    assert root.findtext("license") == setup_keyword("license")


def test_maintainer_is_real_and_the_same_in_setup_py():
    maintainer = package_xml().find("maintainer")
    name, email = maintainer.text.strip(), maintainer.get("email")
    for value in (name, email, setup_keyword("maintainer"), setup_keyword("maintainer_email")):
        assert "todo" not in value.lower(), value
    assert re.fullmatch(r"[^@\s]+@[^@\s]+\.[a-z]{2,}", email), email
    assert (name, email) == (setup_keyword("maintainer"), setup_keyword("maintainer_email"))
    assert PACKAGE_XML.read_text().count("<maintainer") == 1
