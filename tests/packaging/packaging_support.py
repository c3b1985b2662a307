"""What the packaging files declare, read without running them (AST, XML, text)."""
from __future__ import annotations

import ast
import re
import xml.etree.ElementTree as ET
from pathlib import Path

from shared import REPO
PACKAGE = "sensorispace_ros"
SETUP_PY = REPO / "setup.py"
PACKAGE_XML = REPO / "package.xml"
REQUIREMENTS_IN = REPO / "requirements.in"
LAUNCH_FILE = REPO / "launch" / "graph.launch.py"
CONFIG_DIR = REPO / "config"


def setup_keyword(name: str, path: Path = SETUP_PY):
    """A keyword argument of setup(): a literal, or a module-level string constant."""
    tree = ast.parse(path.read_text(), filename=str(path))
    constants = {target.id: node.value.value for node in tree.body
                 if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant)
                 for target in node.targets if isinstance(target, ast.Name)}
    calls = [node for node in ast.walk(tree) if isinstance(node, ast.Call)
             and isinstance(node.func, ast.Name) and node.func.id == "setup"]
    assert len(calls) == 1, f"{path}: expected one setup() call, found {len(calls)}"
    for keyword in calls[0].keywords:
        if keyword.arg == name:
            if isinstance(keyword.value, ast.Name):
                return constants[keyword.value.id]
            return ast.literal_eval(keyword.value)
    raise KeyError(f"{path}: setup() has no {name}=")


def console_scripts(path: Path = SETUP_PY) -> dict[str, str]:
    """``name -> module:function`` of setup.py's console_scripts."""
    entries = setup_keyword("entry_points", path)["console_scripts"]
    return {name.strip(): target.strip()
            for name, target in (entry.split("=", 1) for entry in entries)}


def package_xml(path: Path = PACKAGE_XML) -> ET.Element:
    return ET.parse(path).getroot()


def package_xml_comments(path: Path = PACKAGE_XML) -> str:
    return " ".join(re.findall(r"<!--(.*?)-->", path.read_text(), flags=re.S))


def dependencies(kind: str, root: ET.Element | None = None) -> set[str]:
    """Keys of ``<kind>`` and of ``<depend>`` (which implies every kind)."""
    root = package_xml() if root is None else root
    return {e.text.strip() for tag in (kind, "depend") for e in root.findall(tag)}


def requirement_names(path: Path = REQUIREMENTS_IN) -> list[str]:
    """Top-level requirement names of requirements.in, normalised (PEP 503)."""
    names = []
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name = re.match(r"[A-Za-z0-9][A-Za-z0-9._-]*", line).group(0)
            names.append(re.sub(r"[-_.]+", "-", name).lower())
    return names
