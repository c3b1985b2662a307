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

Every value is checked (``validate_config``); a bad value or an unknown key
raises ``ConfigError`` naming the dotted parameter and the reason, so a typo
can never pass silently.
"""
from __future__ import annotations

import copy
import math
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Any, Callable

import yaml

ROS_WRAPPER = "ros__parameters"
# The ``naive`` section is passed through to the naive strategy's parameters;
# its keys are those of ``core.naive.params.NaiveParams``.
OPEN_SECTIONS = ("naive",)


class ConfigError(ValueError):
    """A configuration value is missing, unknown or out of range."""


# ---------------------------------------------------------------------------
# Value checks. Each takes (name, value) and returns the normalised value or
# raises ConfigError("<name>: must be ..., got ...").


def _fail(name: str, requirement: str, value: Any) -> None:
    raise ConfigError(f"{name}: must be {requirement}, got {value!r}")


def _is_int(value: Any) -> bool:
    # bool is an int subclass in Python; a YAML `true` is not a count.
    return isinstance(value, int) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return (_is_int(value) or isinstance(value, float)) and math.isfinite(value)


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


# ---------------------------------------------------------------------------
# The schema: default value and check of every parameter. Defaults are the
# paper's values (issue #2); comments give the source.

SCHEMA: dict[str, Any] = {
    "seed": (0, integer(0)),
    "world": {
        "grid_half_width": (6.0, real(0.0, low_open=True)),     # 12 x 12 units, Sec. 3.2
        "grid_count": (62, integer(2)),                          # 62^2 positions
        "schedule": ("random", choice("random", "tracking")),    # "in no particular order"
        "redistribution_probability": (0.1, real(0.0, 1.0)),    # 10 %
        "lights": {
            "count": (10, integer(1)),                           # L = 10
            "radius_min": (3.5, real(0.0)),                      # not in the paper: outside reach 3
            "radius_max": (7.0, real(0.0, low_open=True)),
            "min_in_view": (3, integer(0)),                      # the sensation must pin the pose
        },
        "retina": {
            "receptors": (6, integer(1)),
            "half_width": (1.0, real(0.0, low_open=True)),
        },
    },
    "arm": {
        "initial_motor_state": ([0.1, -1.5, 2.2, -3.0], real_vector(4)),   # m0, Sec. 3.2
    },
    "pov": {
        "n_samples": (100, integer(3)),                          # N = 100
        "step": (1e-3, real(0.0, low_open=True)),                # epsilon
        "min_steps": (50, integer(1)),
        "close_tol": (1e-2, real(0.0, low_open=True)),
    },
    "compensation": {
        "threshold": (1e-3, real(0.0, low_open=True)),           # xi, on the error norm
        "initial_simplex": (0.25, real(0.0, low_open=True)),     # rad; scipy's default gets stuck
    },
    "naive": {},                                                 # open: NaiveParams overrides
    "representation": {
        "cca": {
            "n_epochs": (50, integer(1)),
            "alpha0": (0.5, real(0.0, low_open=True)),
            "lambda0": (None, real(0.0, low_open=True, optional=True)),
        },
        "regularization": {
            "iterations": (10, integer(1)),                      # "repeated 10 times"
        },
        "reaching": {
            "pairs": (100, integer(1)),
            "max_degree": (50, integer(1)),                      # "not more than 50 nodes"
            "radius": (None, real(0.0, low_open=True, optional=True)),
        },
    },
    "output": {
        "figures": (True, boolean),
    },
}


def _is_spec(node: Any) -> bool:
    return isinstance(node, tuple) and len(node) == 2 and callable(node[1])


def _defaults_of(schema: dict) -> dict:
    out = {}
    for key, node in schema.items():
        out[key] = copy.deepcopy(node[0]) if _is_spec(node) else _defaults_of(node)
    return out


def defaults() -> dict:
    """The paper configuration as a nested dict (a fresh copy)."""
    return _defaults_of(SCHEMA)


# ---------------------------------------------------------------------------


def validate_config(cfg: dict) -> dict:
    """Check every value of ``cfg``; return a normalised copy.

    ``cfg`` must be complete (as ``load_config`` makes it). Raises
    ``ConfigError`` naming the first bad parameter.
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
    out["naive"] = _validate_naive(out["naive"])
    return out


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
            out[key] = node[1](name, value)
        elif key in OPEN_SECTIONS:
            if not isinstance(value, dict):
                raise ConfigError(f"{name}: must be a mapping, got {value!r}")
            out[key] = copy.deepcopy(value)
        else:
            out[key] = _validate_section(value, node, name + ".")
    return out


def _validate_naive(overrides: dict) -> dict:
    """Reject keys the naive strategy does not know, and let it check values."""
    try:
        from sensorispace_ros.core.naive.params import NaiveParams
    except ModuleNotFoundError:     # naive strategy not built yet: keys cannot be checked
        return overrides
    if is_dataclass(NaiveParams):
        known = {f.name for f in fields(NaiveParams)}
        for key in sorted(overrides, key=str):
            if key not in known:
                raise ConfigError(f"naive.{key}: unknown parameter "
                                  f"(known here: {', '.join(sorted(known))})")
    try:
        NaiveParams(**overrides)
    except (TypeError, ValueError) as exc:
        message = str(exc)
        raise ConfigError(message if message.startswith("naive.") else f"naive: {message}") from exc
    return overrides


# ---------------------------------------------------------------------------


def load_config(path: str | Path | None = None, overrides: dict | None = None) -> dict:
    """Paper defaults, then the file at ``path``, then ``overrides``; validated.

    ``overrides`` may be nested (``{"world": {"grid_count": 16}}``) or dotted
    (``{"world.grid_count": 16}``).
    """
    cfg = defaults()
    if path is not None:
        _merge(cfg, read_parameter_file(path), "")
    if overrides:
        _merge(cfg, unflatten(overrides), "")
    return validate_config(cfg)


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

    ``None`` values are left out (ROS has no null) and so are empty sections
    (rcl's parser rejects ``key: {}`` followed by more keys).
    """
    def ros_values(node):
        out = {}
        for key, value in node.items():
            if isinstance(value, dict):
                value = ros_values(value)
                if not value:
                    continue
            elif value is None:
                continue
            out[key] = value
        return out
    return yaml.safe_dump({"/**": {ROS_WRAPPER: ros_values(cfg)}}, sort_keys=False,
                          default_flow_style=None)
