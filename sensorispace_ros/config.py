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
This module is pure Python (and yaml): ``core`` may import it.
"""
from __future__ import annotations

import copy
import math
import numbers
from pathlib import Path
from typing import Any, Callable, NamedTuple

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


P = Param
# The most common check: a finite number > 0 (steps, tolerances, radii).
positive = real(0.0, low_open=True)

# ---------------------------------------------------------------------------
# The run configuration: every parameter of the offline pipeline and the
# nodes. World, arm, POV, compensation and representation defaults are the
# paper's values (Sec. 3-5) where it gives them.

WORLD = {
    "grid_half_width": P(6.0, positive, "object positions span "
                         "[-w, w]^2 (12 x 12 units, Sec. 3.2)"),
    "grid_count": P(62, integer(2), "object positions per axis (62^2; the text's 64^2 is a typo)"),
    "schedule": P("random", choice("random", "tracking"), "order of the object positions: "
                  "random (\"in no particular order\") or neighbouring (boustrophedon)"),
    "redistribution_probability": P(0.1, real(0.0, 1.0), "chance that an event redraws the "
                                    "lights instead of moving the object (10 %)"),
    "lights": {
        "count": P(10, integer(1), "lights L in the environment (L = 10)"),
        "radius_min": P(3.5, real(0.0), "inner radius of the lights' annulus; not in the "
                        "paper: outside the arm's reach 3"),
        "radius_max": P(7.0, positive, "outer radius of the lights' annulus"),
        "min_in_view": P(3, integer(0), "lights the initial pose must see, so the sensation "
                         "pins the eye's pose"),
    },
    "retina": {
        "receptors": P(6, integer(1), "receptors of the retina"),
        "half_width": P(1.0, positive, "half width of the retina"),
    },
}

# The naive agent (core.naive.params.NaiveParams takes its fields and
# defaults from here). Meanings refer to core.naive.points_of_view
# (sample_sensory_points_of_view), core.naive.compensation (compensate) and
# core.naive.equality_sets (match_sensations).
NAIVE = {
    "n_samples": P(100, integer(2), "motor states kept per POV (N, as pov.n_samples)"),
    "fd_step": P(1e-6, positive, "finite-difference step (rad) of every "
                 "sensory Jacobian the agent estimates"),
    "pov_initial_step": P(0.05, positive, "first knot interval (rad) of a "
                          "POV walk; within [pov_min_step, pov_max_step]"),
    "pov_min_step": P(1e-3, positive, "smallest knot interval (rad) of a POV walk"),
    "pov_max_step": P(0.15, positive, "largest knot interval (rad) of a POV walk"),
    "pov_predictor_tol": P(1e-3, positive, "Gauss-Newton correction the "
                           "walk's step size aims at; a probe beyond 4x it is dropped"),
    "pov_max_queries": P(5000, integer(1), "sensed rows per POV walk before it gives up"),
    "pov_polish_iterations": P(2, integer(0), "Gauss-Newton iterations that bring a "
                               "closed POV's samples back onto the level set"),
    "lm_max_iterations": P(40, integer(1), "Levenberg-Marquardt iterations per "
                           "compensation search"),
    "lm_stall_iterations": P(3, integer(1), "a search stops when its error has not halved "
                             "in this many iterations (a local minimum)"),
    "lm_error_tol": P(1e-10, positive, "accepted sensory error; tight: "
                      "matches between sweeps need exact poses (pose error e ~ sensation "
                      "error e)"),
    "lm_motor_tol": P(1e-8, positive, "accepted motor residual (rad); tight for the same reason"),
    "lm_max_step": P(0.5, positive, "largest motor step (rad) of one "
                     "Levenberg-Marquardt iteration"),
    "lm_initial_damping": P(1e-7, positive, "initial damping, relative to "
                            "J's mean squared singular value: small = nearly Gauss-Newton"),
    "lm_restarts": P(2, integer(1), "remembered states tried per target besides the "
                     "resting state (the nearest ones)"),
    "match_tol": P(1e-6, positive, "two sensations within it are the same "
                   "pose; < match_separation"),
    "match_separation": P(1e-4, positive, "a match counts only if no other "
                          "sensation lies within it (uniqueness radius)"),
    "rank_ratio": P(1e-3, positive, "smallest 3rd/1st singular-value ratio "
                    "of the sensory Jacobian for rank 3"),
    "min_singular": P(1e-4, real(0.0), "smallest 3rd singular value of the sensory "
                      "Jacobian for rank 3"),
    "max_snapshots": P(12, integer(1), "snapshots (remembered sensations of known POVs) "
                       "kept as anchors"),
    "snapshot_patience": P(20, integer(1), "events without a match or a compensation "
                           "after which a snapshot is dropped"),
    "unconfirmed_attempts": P(4, integer(0), "anchors of unconfirmed snapshots searched "
                              "per event (most recent first)"),
    "unconfirmed_max_povs": P(100, integer(0), "only snapshots that knew fewer POVs than "
                              "this are searched while unconfirmed"),
    "frontier_attempts": P(8, integer(0), "other rows of the most recent confirmed "
                           "snapshot searched per event"),
    "equality_snapshots": P(2, integer(0), "the most recent snapshots whose matches are "
                            "all rank-tested and become equality sets"),
    "confirm_checks": P(3, integer(1), "rank tests at most that confirm an older snapshot"),
    "remember_sensations": P(True, boolean, "calls-only switch: answer a repeated sense "
                             "request from memory; tests prove it changes no bit"),
    "remember_split_povs": P(True, boolean, "calls-only switch: skip walking a state that "
                             "senses as a known split POV; tests prove it changes no bit"),
}

SCHEMA: dict[str, Any] = {
    "seed": P(0, integer(0), "every random choice (world, schedule, representation) comes "
              "from it through named streams (core.seeding)"),
    "world": WORLD,
    "arm": {
        "initial_motor_state": P([0.1, -1.5, 2.2, -3.0], real_vector(4),
                                 "the arm's first motor state m0 (rad, Sec. 3.2)"),
    },
    "pov": {
        "n_samples": P(100, integer(3), "motor states kept per POV (N = 100)"),
        "step": P(1e-3, positive, "step epsilon (rad) of the Jacobian-kernel walk"),
        "min_steps": P(50, integer(1), "steps a walk takes before it may close"),
        "close_tol": P(1e-2, positive, "the walk closes within this "
                       "periodic motor distance (rad) of its start"),
    },
    "compensation": {
        "threshold": P(1e-3, positive, "xi: accepted norm of the sensory error"),
        "initial_simplex": P(0.25, positive, "Nelder-Mead simplex size "
                             "(rad); scipy's default gets stuck"),
    },
    "naive": NAIVE,
    "representation": {
        "cca": {
            "n_epochs": P(50, integer(1), "CCA epochs over the POVs"),
            "alpha0": P(0.5, positive, "CCA's initial step size (decays to alpha0 / 100)"),
            "lambda0": P(None, real(0.0, low_open=True, optional=True), "CCA's initial "
                         "neighbourhood radius; null: chosen from the distances"),
        },
        "regularization": {
            "iterations": P(10, integer(1), "regularisation passes (\"repeated 10 times\")"),
        },
        "reaching": {
            "pairs": P(100, integer(1), "random start/target pairs for the straightness median"),
            "max_degree": P(50, integer(1), "pruning: at most this many neighbours per "
                            "node (\"not more than 50 nodes\")"),
            "radius": P(None, real(0.0, low_open=True, optional=True), "pruning radius; "
                        "null: the largest keeping every degree <= max_degree"),
        },
    },
    "output": {
        "figures": P(True, boolean, "draw the paper's figures after a run"),
    },
}

# The graph's own parameters (``graph.*``): where results go and how nodes
# talk, not the science. They are no part of the run configuration (not in
# metrics.json nor in a bag's stored configuration).
GRAPH_PREFIX = "graph."
GRAPH_SCHEMA: dict[str, Param] = {
    "results_dir": P("results/graph", text(), "where the agent and the representation "
                     "write their results"),
    "resend_period_s": P(0.25, positive, "re-send period (s) of a change "
                         "or a settle not yet acknowledged"),
    "wait_for_nodes": P(["body", "agent"], text_list, "nodes the environment waits for "
                        "before its first change"),
    "exit_when_done": P(False, boolean, "the environment and the representation exit "
                        "after the last change"),
    "checkpoint_dir": P("", text(empty=True), "where a node persists what it needs to "
                        "resume after a kill -9 (<dir>/<node>.*); empty: no persistence"),
    "command_timeout_s": P(2.0, positive, "the agent re-sends a motor "
                           "command unanswered this long (s); a late duplicate is dropped"),
    "executor": P("events", choice("events", "single_threaded"), "what spins a node: "
                  "rclpy's EventsExecutor, or SingleThreadedExecutor (its fallback, and "
                  "the reference it is measured against)"),
    "view_port": P(0, integer(0), "the viewer node serves its topics to the Foxglove app "
                   "on ws://127.0.0.1:<port> (Foxglove SDK); 0: no server"),
}


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
    _check_naive_relations(out["naive"])
    return out


def validate_naive(values: dict) -> dict:
    """Check a complete ``naive`` section (``NaiveParams``' fields); return it normalised."""
    out = _validate_section(values, NAIVE, "naive.")
    _check_naive_relations(out)
    return out


def _check_naive_relations(naive: dict) -> None:
    if not naive["pov_min_step"] <= naive["pov_initial_step"] <= naive["pov_max_step"]:
        raise ConfigError("naive.pov_initial_step: must lie in [naive.pov_min_step "
                          f"({naive['pov_min_step']!r}), naive.pov_max_step "
                          f"({naive['pov_max_step']!r})], got {naive['pov_initial_step']!r}")
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
