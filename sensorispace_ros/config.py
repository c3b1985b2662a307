"""Run configuration: one file format for the offline pipeline and the ROS nodes.

A configuration file is a ROS 2 parameter file::

    /**:
      ros__parameters:
        seed: 0
        world:
          grid_count: 62
          ...

so ``--ros-args --params-file config/paper.yaml`` hands the same values to
every node (nested mappings become dotted parameter names such as
``world.grid_count``; each node declares the subset it needs) and
``load_config`` reads it for ``sensorispace reproduce``.

ROS parameters cannot be null. A parameter whose value is ``None`` here
("choose automatically", e.g. ``representation.cca.lambda0``) is therefore
left out of the YAML files; an absent key takes its default. A plain mapping
without the ``/**: ros__parameters:`` wrapper is accepted too.

Every parameter is one ``Param`` of ``SCHEMA`` (default, check, one-line
meaning), the naive agent's too (``naive.*``, the fields of
``core.naive.params.NaiveParams``); the graph's own ``graph.*`` are
``GRAPH_SCHEMA``'s. Every value is checked (``validate_config``,
``load_graph``); a bad value or an unknown key raises ``ConfigError`` naming
the dotted parameter and the reason, so a typo can never pass silently.
This module needs only yaml and numpy: ``core`` may import it.
"""
from __future__ import annotations

import copy
import math
import numbers
import re
from pathlib import Path
from typing import Any, Callable, NamedTuple

import numpy as np
import yaml

ROS_WRAPPER = "ros__parameters"


class ConfigError(ValueError):
    """A configuration value is missing, unknown or out of range."""


# ---------------------------------------------------------------------------
# Value checks. Each takes (name, value) and returns the normalised value or
# raises ConfigError("<name>: must be ..., got ...").


def _fail(name: str, requirement: str, value: Any) -> None:
    raise ConfigError(f"{name}: must be {requirement}, got {value!r}")


def _is_int(value: Any) -> bool:
    # bool is an int subclass in Python; a YAML `true` is not a count.
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return (_is_int(value) or isinstance(value, numbers.Real) and not isinstance(value, bool)) \
        and math.isfinite(value)


def integer(minimum: int | None = None) -> Callable[[str, Any], int]:
    def check(name, value):
        requirement = "an integer" + ("" if minimum is None else f" >= {minimum}")
        if not _is_int(value) or (minimum is not None and value < minimum):
            _fail(name, requirement, value)
        return int(value)
    return check


def real(low: float | None = None, high: float | None = None, low_open: bool = False,
         optional: bool = False) -> Callable[[str, Any], float | None]:
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low}")
    if high is not None:
        parts.append(f"<= {high}")
    requirement = "a finite number" + (" " + " and ".join(parts) if parts else "")
    if optional:
        requirement += " (or null for automatic)"

    def check(name, value):
        if value is None and optional:
            return None
        if not _is_real(value):
            _fail(name, requirement, value)
        if low is not None and (value <= low if low_open else value < low):
            _fail(name, requirement, value)
        if high is not None and value > high:
            _fail(name, requirement, value)
        return float(value)
    return check


def choice(*options: str) -> Callable[[str, Any], str]:
    def check(name, value):
        if value not in options:
            _fail(name, "one of " + ", ".join(options), value)
        return value
    check.options = options
    return check


def boolean(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        _fail(name, "true or false", value)
    return value


def real_vector(length: int) -> Callable[[str, Any], list[float]]:
    def check(name, value):
        if (not isinstance(value, (list, tuple)) or len(value) != length
                or not all(_is_real(v) for v in value)):
            _fail(name, f"a list of {length} finite numbers", value)
        return [float(v) for v in value]
    return check


def integer_vector(length: int, minimum: int = 1) -> Callable[[str, Any], list[int]]:
    def check(name, value):
        if (not isinstance(value, (list, tuple)) or len(value) != length
                or not all(_is_int(v) and v >= minimum for v in value)):
            _fail(name, f"a list of {length} integers >= {minimum}", value)
        return [int(v) for v in value]
    return check


def real_list(name: str, value: Any) -> list[float]:
    if (not isinstance(value, (list, tuple)) or not value
            or not all(_is_real(v) for v in value)):
        _fail(name, "a non-empty list of finite numbers", value)
    return [float(v) for v in value]


def text(empty: bool = False) -> Callable[[str, Any], str]:
    def check(name, value):
        if not isinstance(value, str) or (not empty and not value):
            _fail(name, "a string" if empty else "a non-empty string", value)
        return value
    return check


def text_list(name: str, value: Any) -> list[str]:
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) and v for v in value):
        _fail(name, "a list of non-empty strings", value)
    return list(value)


class Param(NamedTuple):
    """One parameter: its default, its check and what it means (one line)."""
    default: Any
    check: Callable[[str, Any], Any]
    meaning: str


def check_from_spec(spec: str) -> Callable[[str, Any], Any]:
    """The check a parameter table names (the grammar heads parameters.yaml)."""
    simple = {"boolean": boolean, "text list": text_list, "real list": real_list, "text": text(),
              "text or empty": text(empty=True)}
    if spec in simple:
        return simple[spec]
    if match := re.fullmatch(r"integer(?: >= (-?\d+))?", spec):
        return integer(None if match[1] is None else int(match[1]))
    if match := re.fullmatch(r"real vector of (\d+)", spec):
        return real_vector(int(match[1]))
    if match := re.fullmatch(r"integer vector of (\d+)", spec):
        return integer_vector(int(match[1]))
    if match := re.fullmatch(r"one of (.+)", spec):
        return choice(*match[1].split(", "))
    if match := re.fullmatch(r"real(?: (>=|>) ([-+.\deE]+))?(?: and <= ([-+.\deE]+))?"
                             r"( or null)?", spec):
        return real(None if match[2] is None else float(match[2]),
                    None if match[3] is None else float(match[3]),
                    low_open=match[1] == ">", optional=bool(match[4]))
    raise ValueError(f"parameters.yaml: unknown check {spec!r}")


def _table(node: dict, prefix: str = "") -> dict:
    """A nested table of ``Param`` from parameters.yaml's mapping ``node``."""
    out = {}
    for key, entry in node.items():
        if set(entry) == {"default", "check", "meaning"}:
            out[key] = Param(entry["default"], check_from_spec(entry["check"]),
                             entry["meaning"])
        else:
            out[key] = _table(entry, f"{prefix}{key}.")
    return out


PARAMETERS_FILE = Path(__file__).with_name("parameters.yaml")
_TABLES = yaml.safe_load(PARAMETERS_FILE.read_text())
SCHEMA: dict[str, Any] = _table(_TABLES["run"])
WORLD = SCHEMA["world"]
NAIVE = SCHEMA["naive"]
# The graph's own parameters (``graph.*``); not part of the run configuration
# (neither in metrics.json nor in a bag's stored configuration).
GRAPH_PREFIX = "graph."
GRAPH_SCHEMA: dict[str, Param] = _table(_TABLES["graph"])
# The recorder's own parameters (``recorder.*``), not part of the run configuration either.
RECORDER_PREFIX = "recorder."
RECORDER_SCHEMA: dict[str, Param] = _table(_TABLES["recorder"])
# The replay node's own parameters, named without a prefix (``rate``, ``topics``, ...).
REPLAY_SCHEMA: dict[str, Param] = _table(_TABLES["replay"])


def _is_spec(node: Any) -> bool:
    return isinstance(node, Param)


def _defaults_of(schema: dict) -> dict:
    out = {}
    for key, node in schema.items():
        out[key] = copy.deepcopy(node.default) if _is_spec(node) else _defaults_of(node)
    return out


def defaults() -> dict:
    """The paper configuration as a nested dict (a fresh copy)."""
    return _defaults_of(SCHEMA)


def parameters(schema: dict = SCHEMA, prefix: str = "") -> dict[str, Param]:
    """Every parameter of ``schema`` by dotted name."""
    out = {}
    for key, node in schema.items():
        if _is_spec(node):
            out[prefix + key] = node
        else:
            out.update(parameters(node, f"{prefix}{key}."))
    return out


# ---------------------------------------------------------------------------


def validate_config(cfg: dict, simulated_body: bool = True) -> dict:
    """Check every value of ``cfg``; return a normalised copy.

    ``cfg`` must be complete (as ``load_config`` makes it). Raises
    ``ConfigError`` naming the first bad parameter. ``arm.initial_motor_state``
    is checked against the simulated arm only with ``simulated_body``: a body
    of one's own is checked against its own description, by the agent.
    """
    if not isinstance(cfg, dict):
        raise ConfigError(f"configuration must be a mapping, got {type(cfg).__name__}")
    out = _validate_section(cfg, SCHEMA, "")
    lights = out["world"]["lights"]
    if lights["radius_max"] <= lights["radius_min"]:
        raise ConfigError("world.lights.radius_max: must be > world.lights.radius_min "
                          f"({lights['radius_min']!r}), got {lights['radius_max']!r}")
    if lights["min_in_view"] > lights["count"]:
        raise ConfigError("world.lights.min_in_view: must be <= world.lights.count "
                          f"({lights['count']}), got {lights['min_in_view']}")
    _check_naive_relations(out["naive"])
    _check_body(out, simulated_body)
    return out


def _check_body(cfg: dict, simulated_body: bool) -> None:
    """The arm and the sensor code make sense together (``core.arm.Arm`` and
    ``core.sensor_code.SensorCode`` name the parameter in their errors)."""
    from sensorispace_ros.core.arm import Arm
    from sensorispace_ros.core.imperfections import Imperfections
    from sensorispace_ros.core.sensor_code import SensorCode
    arm_cfg, retina = cfg["arm"], cfg["world"]["retina"]
    try:
        body_arm = Arm(tuple(arm_cfg["segments"]), arm_cfg["eye"], arm_cfg["motor_unit"])
        SensorCode(retina["code"], retina["code_value"], retina["receptors"],
                   np.random.default_rng(0))
        Imperfections(noise=retina["noise"], quantum=retina["quantum"], dtype=retina["dtype"],
                      dropout=retina["dropout"], motor_noise=arm_cfg["motor_noise"])
    except ValueError as error:
        raise ConfigError(str(error)) from None
    # A MuJoCo body checks the start against its model's joints (bodies.mujoco_world).
    simulated_body = simulated_body and cfg["body"]["kind"] == "simulated"
    if simulated_body and len(arm_cfg["initial_motor_state"]) != body_arm.n_joints:
        raise ConfigError(f"arm.initial_motor_state: must hold one value per joint "
                          f"({body_arm.n_joints}: {body_arm.n_links} links, eye "
                          f"{body_arm.eye!r}), got {arm_cfg['initial_motor_state']!r}")


def validate_naive(values: dict) -> dict:
    """Check a complete ``naive`` section (``NaiveParams``' fields); return it normalised."""
    _check_naive_relations(out := _validate_section(values, NAIVE, "naive."))
    return out


def _check_naive_relations(naive: dict) -> None:
    if not naive["pov_min_step"] <= naive["pov_initial_step"] <= naive["pov_max_step"]:
        raise ConfigError("naive.pov_initial_step: must lie in [naive.pov_min_step "
                          f"({naive['pov_min_step']!r}), naive.pov_max_step "
                          f"({naive['pov_max_step']!r})], got {naive['pov_initial_step']!r}")
    if not naive["noise_confidence"] < 1.0:
        raise ConfigError("naive.noise_confidence: must be < 1, got "
                          f"{naive['noise_confidence']!r}")
    if not naive["match_tol"] < naive["match_separation"]:
        raise ConfigError("naive.match_tol: must be < naive.match_separation "
                          f"({naive['match_separation']!r}), got {naive['match_tol']!r}")


def _validate_section(section: Any, schema: dict, prefix: str) -> dict:
    where = prefix.rstrip(".") or "configuration"
    if not isinstance(section, dict):
        raise ConfigError(f"{where}: must be a mapping, got {section!r}")
    unknown = sorted(set(section) - set(schema), key=str)
    if unknown:
        known = ", ".join(sorted(schema))
        raise ConfigError(f"{prefix}{unknown[0]}: unknown parameter (known here: {known})")
    out = {}
    for key, node in schema.items():
        name = prefix + key
        if key not in section:
            raise ConfigError(f"{name}: missing")
        value = section[key]
        if _is_spec(node):
            out[key] = node.check(name, value)
        else:
            out[key] = _validate_section(value, node, name + ".")
    return out


def load_graph(overrides: dict | None = None) -> dict:
    """The ``graph.*`` parameters: defaults, then ``overrides`` (names without
    the ``graph.`` prefix); validated like the run configuration."""
    values = _defaults_of(GRAPH_SCHEMA)
    values.update(copy.deepcopy(overrides or {}))
    return _validate_section(values, GRAPH_SCHEMA, GRAPH_PREFIX)


def load_recorder(overrides: dict | None = None) -> dict:
    """The ``recorder.*`` parameters, as ``load_graph`` the ``graph.*`` ones."""
    values = _defaults_of(RECORDER_SCHEMA)
    values.update(copy.deepcopy(overrides or {}))
    return _validate_section(values, RECORDER_SCHEMA, RECORDER_PREFIX)


def load_replay(overrides: dict | None = None) -> dict:
    """The replay node's parameters, as ``load_graph`` the ``graph.*`` ones."""
    values = _defaults_of(REPLAY_SCHEMA)
    values.update(copy.deepcopy(overrides or {}))
    return _validate_section(values, REPLAY_SCHEMA, "")


# ---------------------------------------------------------------------------


def load_config(path: str | Path | None = None, overrides: dict | None = None,
                simulated_body: bool = True) -> dict:
    """Paper defaults, then the file at ``path``, then ``overrides``; validated
    (``validate_config``, which says what ``simulated_body`` checks).

    ``overrides`` may be nested (``{"world": {"grid_count": 16}}``) or dotted
    (``{"world.grid_count": 16}``).
    """
    cfg = defaults()
    if path is not None:
        _merge(cfg, read_parameter_file(path), "")
    if overrides:
        _merge(cfg, unflatten(overrides), "")
    return validate_config(cfg, simulated_body)


def parse_overrides(items) -> dict:
    """Dotted overrides from ``KEY=VALUE`` texts (``--set``): a value reads as a
    number (``1e-3`` too, a string to YAML 1.1), else as YAML."""
    overrides = {}
    for key, sep, text in (item.partition("=") for item in items):
        if not (key and sep):
            raise ConfigError(f"override {key + sep + text!r}: expected KEY=VALUE")
        for kind in (int, float, yaml.safe_load):
            try:
                overrides[key] = kind(text)
                break
            except ValueError:
                continue
    return overrides


def read_parameter_file(path: str | Path) -> dict:
    """The parameters of a ROS 2 parameter file (or a plain mapping), nested."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such configuration file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{path}:{where}: invalid YAML ({problem})") from None
    if document is None:
        return {}
    if not isinstance(document, dict):
        raise ConfigError(f"{path}: must hold a mapping of parameters")
    wrapped = [key for key, value in document.items()
               if isinstance(value, dict) and ROS_WRAPPER in value]
    if not wrapped:
        if any(isinstance(key, str) and key.startswith("/") for key in document):
            raise ConfigError(f"{path}: node section without '{ROS_WRAPPER}:'")
        return document
    if len(wrapped) != len(document):
        stray = next(key for key in document if key not in wrapped)
        raise ConfigError(f"{path}: top-level key {stray!r} is not a node section "
                          f"with '{ROS_WRAPPER}:'")
    params: dict = {}
    for key in wrapped:
        section = document[key]
        if set(section) != {ROS_WRAPPER}:
            raise ConfigError(f"{path}: node section {key!r} may only hold '{ROS_WRAPPER}:'")
        _merge(params, section[ROS_WRAPPER] or {}, "")
    return params


def _merge(base: dict, update: dict, prefix: str) -> None:
    """Recursive update; a mapping replaces a leaf only where the schema has
    a section (validation reports the rest)."""
    if not isinstance(update, dict):
        raise ConfigError(f"{prefix.rstrip('.') or 'configuration'}: must be a mapping, "
                          f"got {update!r}")
    for key, value in update.items():
        if isinstance(value, dict) and isinstance(base.get(key), dict):
            _merge(base[key], value, f"{prefix}{key}.")
        else:
            base[key] = copy.deepcopy(value)


def flatten(cfg: dict, prefix: str = "") -> dict[str, Any]:
    """``{"world": {"grid_count": 62}}`` -> ``{"world.grid_count": 62}``.

    The dotted names are the ROS parameter names. An empty section has no
    parameter (as in ROS); lists are values.
    """
    out: dict[str, Any] = {}
    for key, value in cfg.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
        else:
            out[name] = value
    return out


def unflatten(flat: dict[str, Any]) -> dict:
    """Inverse of ``flatten``; nested and dotted keys may be mixed."""
    out: dict = {}
    for key, value in flat.items():
        parts = str(key).split(".")
        if any(not part for part in parts):
            raise ConfigError(f"{key}: empty component in parameter name")
        node = out
        for depth, part in enumerate(parts[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise ConfigError(f"{'.'.join(parts[:depth + 1])}: is a value, "
                                  f"cannot hold {key}")
            node = child
        leaf = parts[-1]
        if isinstance(value, dict):
            value = unflatten(value)
            if isinstance(node.get(leaf), dict):
                _merge(node[leaf], value, key + ".")
                continue
        elif isinstance(node.get(leaf), dict):
            raise ConfigError(f"{key}: is a section, cannot be set to {value!r}")
        node[leaf] = copy.deepcopy(value)
    return out


def to_parameter_file(cfg: dict) -> str:
    """``cfg`` as a ROS 2 parameter file.

    ``None`` values are left out (ROS has no null), and so are empty lists
    (untyped for ROS; a list whose default is empty means "automatic") and
    empty sections (rcl's parser rejects ``key: {}`` followed by more keys).
    """
    def ros_values(node):
        out = {}
        for key, value in node.items():
            if isinstance(value, dict):
                value = ros_values(value)
                if not value:
                    continue
            elif value is None or (isinstance(value, list) and not value):
                continue        # an empty list has no ROS type; absent, it takes its default
            out[key] = value
        return out
    return yaml.safe_dump({"/**": {ROS_WRAPPER: ros_values(cfg)}}, sort_keys=False,
                          default_flow_style=None)
