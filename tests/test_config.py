"""Configuration: paper defaults, strict validation, the ROS parameter-file format."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from sensorispace_ros import config
from sensorispace_ros.config import ConfigError, flatten, load_config, unflatten, validate_config

from shared import REPO, SMOKE
PAPER = REPO / "config" / "paper.yaml"


def write(tmp_path: Path, params: dict, wrapped: bool = True) -> Path:
    path = tmp_path / "params.yaml"
    document = {"/**": {"ros__parameters": params}} if wrapped else params
    path.write_text(yaml.safe_dump(document))
    return path


# ---------------------------------------------------------------------------
# Defaults are the paper's values


def test_defaults_are_the_papers_values():
    cfg = load_config()
    # Values read from the paper (Sec. 3-5; its set-up's 62^2 grid), not from the code.
    assert cfg["world"]["grid_half_width"] == 6.0
    assert cfg["world"]["grid_count"] == 62
    assert cfg["world"]["redistribution_probability"] == 0.1
    assert cfg["world"]["schedule"] == "random"
    assert cfg["world"]["lights"]["count"] == 10
    assert cfg["world"]["retina"]["receptors"] == 6
    assert cfg["arm"]["initial_motor_state"] == [0.1, -1.5, 2.2, -3.0]
    assert cfg["arm"]["segments"] == [1.0, 1.0, 1.0] and cfg["arm"]["eye"] == "joint"
    assert cfg["arm"]["motor_unit"] == "rad" and cfg["world"]["retina"]["code"] == "identity"
    # n_samples_2d is for bodies with 2-D points of view, which the paper has not.
    paper_pov = {key: value for key, value in cfg["pov"].items() if key != "n_samples_2d"}
    assert paper_pov == {"n_samples": 100, "step": 1e-3, "min_steps": 50, "close_tol": 1e-2}
    assert cfg["compensation"]["threshold"] == 1e-3
    assert cfg["representation"]["regularization"]["iterations"] == 10
    assert cfg["representation"]["reaching"]["max_degree"] == 50


def test_paper_file_equals_defaults_and_smoke_file_is_smaller():
    assert load_config(PAPER) == load_config()
    smoke = load_config(SMOKE)
    assert smoke["world"]["grid_count"] < 62
    assert smoke["representation"]["cca"]["n_epochs"] < load_config()["representation"]["cca"]["n_epochs"]


def test_defaults_are_a_fresh_copy():
    first = load_config()
    first["arm"]["initial_motor_state"][0] = 99.0
    first["world"]["grid_count"] = 3
    assert load_config()["arm"]["initial_motor_state"][0] == 0.1
    assert load_config()["world"]["grid_count"] == 62


# ---------------------------------------------------------------------------
# Every kind of bad value names the parameter


BAD_VALUES = [
    ("world.grid_count", 1, "must be an integer >= 2, got 1"),
    ("world.grid_count", 16.0, "must be an integer"),
    ("world.grid_count", "62", "must be an integer"),
    ("world.grid_count", True, "must be an integer"),
    ("seed", -1, "must be an integer >= 0"),
    ("world.grid_half_width", 0.0, "must be a finite number > 0"),
    ("world.grid_half_width", float("nan"), "finite"),
    ("world.grid_half_width", float("inf"), "finite"),
    ("world.grid_half_width", "six", "finite number"),
    ("world.grid_half_width", None, "finite number"),
    ("world.redistribution_probability", 1.5, "<= 1.0"),
    ("world.redistribution_probability", -0.1, ">= 0.0"),
    ("world.schedule", "spiral", "one of random, tracking"),
    ("world.lights.count", 0, ">= 1"),
    ("world.retina.half_width", -1.0, "> 0"),
    ("arm.initial_motor_state", [0.1, -1.5, 2.2], "one value per joint (4: 3 links"),
    ("arm.initial_motor_state", [0.1, -1.5, 2.2, "x"], "a non-empty list of finite numbers"),
    ("arm.initial_motor_state", 0.1, "a non-empty list of finite numbers"),
    ("arm.segments", [], "a non-empty list of finite numbers"),
    ("arm.segments", [1.0, -0.5], "every link length must be finite and > 0"),
    ("arm.segments", [1.0, "x"], "a non-empty list of finite numbers"),
    ("arm.eye", "wrist", "one of joint, link, level"),
    ("arm.motor_unit", "grad", "one of rad, deg"),
    ("world.retina.code", "sqrt", "one of identity, scale, log, power, mix"),
    ("world.retina.code_value", 0.0, "must be a finite number > 0.0"),
    ("pov.n_samples", 2, ">= 3"),
    ("pov.step", 0, "> 0"),
    ("compensation.threshold", -1e-3, "> 0"),
    ("representation.cca.lambda0", -2.0, "> 0"),
    ("representation.cca.n_epochs", 0, ">= 1"),
    ("representation.reaching.radius", 0.0, "> 0"),
    ("representation.regularization.iterations", 2.5, "an integer"),
    ("output.figures", "yes", "true or false"),
    ("output.figures", 1, "true or false"),
    ("world.lights", 5, "must be a mapping"),
    ("naive", [1, 2], "must be a mapping"),
    ("naive.lm_max_step", 0, "must be a finite number > 0.0, got 0"),
    ("naive.n_samples", 1, "must be an integer >= 2, got 1"),
    ("naive.lm_restarts", 1.5, "must be an integer >= 1"),
    ("naive.min_singular", -1e-4, ">= 0.0"),
    ("naive.remember_split_povs", 1, "true or false"),
]


@pytest.mark.parametrize("name, value, reason", BAD_VALUES,
                         ids=[f"{n}={v!r}" for n, v, _ in BAD_VALUES])
def test_bad_value_names_the_parameter_and_the_reason(name, value, reason):
    with pytest.raises(ConfigError) as caught:
        load_config(overrides={name: value})
    message = str(caught.value)
    assert message.startswith(f"{name}: "), message
    assert reason in message
    assert "\n" not in message


def test_error_message_format_is_the_documented_one():
    with pytest.raises(ConfigError, match=r"^world\.grid_count: must be an integer >= 2, got 1$"):
        load_config(overrides={"world": {"grid_count": 1}})


def test_config_error_is_a_value_error():
    with pytest.raises(ValueError):
        load_config(overrides={"seed": "zero"})


def test_cross_field_constraints():
    with pytest.raises(ConfigError, match=r"^world\.lights\.radius_max: must be > "):
        load_config(overrides={"world.lights.radius_max": 3.0})
    with pytest.raises(ConfigError, match=r"^world\.lights\.min_in_view: must be <= "):
        load_config(overrides={"world.lights.count": 2, "world.lights.min_in_view": 3})


def test_optional_parameters_accept_null_and_a_positive_value():
    cfg = load_config(overrides={"representation.cca.lambda0": None,
                                 "representation.reaching.radius": 0.72})
    assert cfg["representation"]["cca"]["lambda0"] is None
    assert cfg["representation"]["reaching"]["radius"] == 0.72


def test_integers_are_accepted_for_reals_and_normalised():
    cfg = load_config(overrides={"world.grid_half_width": 6, "arm.initial_motor_state": [0, 1, 2, 3]})
    assert isinstance(cfg["world"]["grid_half_width"], float)
    assert all(isinstance(v, float) for v in cfg["arm"]["initial_motor_state"])


# ---------------------------------------------------------------------------
# Unknown keys are errors at every level


@pytest.mark.parametrize("name", ["grid_count", "world.gridcount", "world.lights.colour",
                                  "representation.cca.epochs", "output.figure", "naive.seed"])
def test_unknown_keys_are_rejected(name):
    with pytest.raises(ConfigError) as caught:
        load_config(overrides={name: 3})
    assert str(caught.value).startswith(f"{name}: unknown parameter")


def test_unknown_key_in_a_file_is_rejected(tmp_path):
    path = write(tmp_path, {"world": {"grid_count": 16, "grid_cout": 3}})
    with pytest.raises(ConfigError, match=r"^world\.grid_cout: unknown parameter"):
        load_config(path)


def test_missing_key_in_an_incomplete_dict_is_reported():
    cfg = load_config()
    del cfg["pov"]["step"]
    with pytest.raises(ConfigError, match=r"^pov\.step: missing$"):
        validate_config(cfg)


# ---------------------------------------------------------------------------
# The naive agent's and the graph's parameters are schema entries too


def test_naive_section_is_checked_like_any_other():
    cfg = load_config(overrides={"naive": {"lm_restarts": 3}})
    assert cfg["naive"]["lm_restarts"] == 3
    assert cfg["naive"]["lm_max_step"] == 0.5             # untouched default
    with pytest.raises(ConfigError, match=r"^naive\.lm_restart: unknown parameter \(known here: "):
        load_config(overrides={"naive.lm_restart": 3})
    with pytest.raises(ConfigError,
                       match=r"^naive\.lm_max_step: must be a finite number > 0\.0, got 0$"):
        load_config(overrides={"naive.lm_max_step": 0})


def test_a_bad_naive_value_in_a_file_is_named(tmp_path):
    path = write(tmp_path, {"naive": {"remember_sensations": "yes"}})
    with pytest.raises(ConfigError, match=r"^naive\.remember_sensations: must be true or false"):
        load_config(path)


def test_naive_cross_field_constraints():
    with pytest.raises(ConfigError, match=r"^naive\.pov_initial_step: must lie in "):
        load_config(overrides={"naive.pov_initial_step": 0.2})
    with pytest.raises(ConfigError, match=r"^naive\.match_tol: must be < naive\.match_separation"):
        load_config(overrides={"naive.match_tol": 1e-3})


def test_naive_params_are_the_naive_section():
    """NaiveParams has one field per naive.* entry, with its default; it checks as the
    config does."""
    from sensorispace_ros.core.naive.params import NaiveParams

    assert NaiveParams().__dict__ == load_config()["naive"]
    assert NaiveParams(**load_config(overrides={"naive.lm_restarts": 5})["naive"]).lm_restarts == 5
    with pytest.raises(ConfigError, match=r"^naive\.lm_max_step: must be a finite number > 0"):
        NaiveParams(lm_max_step=-1.0)
    assert isinstance(NaiveParams(lm_max_step=1).lm_max_step, float)     # normalised as here


def test_every_parameter_has_a_default_that_passes_its_check_and_a_meaning():
    for schema, prefix in ((config.SCHEMA, ""), (config.GRAPH_SCHEMA, "graph."),
                           (config.RECORDER_SCHEMA, "recorder."), (config.REPLAY_SCHEMA, "")):
        entries = config.parameters(schema, prefix)
        for name, param in entries.items():
            assert param.check(name, param.default) == param.default, name
            assert param.meaning.strip() and "\n" not in param.meaning, name
    assert {"seed", "world.grid_count", "naive.lm_max_step"} <= set(config.parameters())
    assert "graph.executor" in config.parameters(config.GRAPH_SCHEMA, "graph.")


def test_graph_parameters_are_checked_with_the_same_messages():
    graph = config.load_graph({"resend_period_s": 1})
    assert graph["resend_period_s"] == 1.0 and graph["executor"] == "events"
    assert graph["wait_for_nodes"] == ["body", "agent"]
    with pytest.raises(ConfigError, match=r"^graph\.resend_period_s: must be a finite number > 0"):
        config.load_graph({"resend_period_s": 0.0})
    with pytest.raises(ConfigError, match=r"^graph\.executor: must be one of events, single_threaded"):
        config.load_graph({"executor": "multi_threaded"})
    with pytest.raises(ConfigError, match=r"^graph\.result_dir: unknown parameter"):
        config.load_graph({"result_dir": "x"})
    with pytest.raises(ConfigError, match=r"^graph\.wait_for_nodes: must be a list of non-empty"):
        config.load_graph({"wait_for_nodes": "body"})


def test_graph_parameters_are_no_part_of_the_run_configuration():
    assert "graph" not in load_config()
    with pytest.raises(ConfigError, match=r"^graph: unknown parameter"):
        load_config(overrides={"graph.results_dir": "x"})


# ---------------------------------------------------------------------------
# Files and overrides


def test_file_then_overrides_are_merged_over_defaults(tmp_path):
    path = write(tmp_path, {"seed": 3, "world": {"grid_count": 20}})
    cfg = load_config(path, overrides={"world.grid_count": 24, "pov": {"n_samples": 60}})
    assert cfg["seed"] == 3
    assert cfg["world"]["grid_count"] == 24
    assert cfg["pov"]["n_samples"] == 60
    assert cfg["world"]["grid_half_width"] == 6.0          # untouched default


def test_plain_mapping_without_ros_wrapper_is_accepted(tmp_path):
    path = write(tmp_path, {"world": {"grid_count": 20}}, wrapped=False)
    assert load_config(path)["world"]["grid_count"] == 20


def test_missing_file_is_a_config_error_naming_the_path(tmp_path):
    missing = tmp_path / "nope.yaml"
    with pytest.raises(ConfigError, match="nope.yaml: no such configuration file"):
        load_config(missing)


def test_invalid_yaml_is_a_one_line_config_error_with_the_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("/**:\n  ros__parameters:\n    seed: [1, 2\n    world: {}\n")
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    assert "broken.yaml" in str(caught.value) and "line" in str(caught.value)
    assert "\n" not in str(caught.value)


def test_stray_top_level_key_next_to_a_node_section_is_rejected(tmp_path):
    path = tmp_path / "stray.yaml"
    path.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"seed": 1}}, "seed": 2}))
    with pytest.raises(ConfigError, match="is not a node section"):
        load_config(path)


# ---------------------------------------------------------------------------
# Dotted names (ROS side)


def test_flatten_gives_dotted_ros_names_and_unflatten_inverts_it():
    cfg = load_config()
    flat = flatten(cfg)
    assert flat["world.grid_count"] == 62
    assert flat["world.lights.radius_max"] == 7.0
    assert flat["arm.initial_motor_state"] == [0.1, -1.5, 2.2, -3.0]
    assert all(not isinstance(v, dict) for v in flat.values())
    assert flat["naive.lm_max_step"] == 0.5
    assert unflatten(flat) == cfg


def test_unflatten_rejects_a_value_used_as_a_section():
    with pytest.raises(ConfigError):
        unflatten({"seed": 1, "seed.x": 2})


def test_to_parameter_file_round_trips_and_omits_nulls(tmp_path):
    cfg = load_config(overrides={"world.grid_count": 30, "representation.reaching.radius": 0.5})
    text = config.to_parameter_file(cfg)
    assert "null" not in text
    path = tmp_path / "out.yaml"
    path.write_text(text)
    assert load_config(path) == cfg


GENERATED = "generated"


@pytest.mark.parametrize("path", [PAPER, SMOKE, GENERATED], ids=["paper", "smoke", GENERATED])
def test_config_files_are_valid_ros_parameter_files(path, monkeypatch, tmp_path):
    """rcl's own parser reads the file and a node sees the same values."""
    if path == GENERATED:
        path = tmp_path / "generated.yaml"
        path.write_text(config.to_parameter_file(load_config(SMOKE)))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    context = Context()
    rclpy.init(args=["--ros-args", "--params-file", str(path)], context=context,
               domain_id=97)
    try:
        node = Node("config_check", context=context,
                    automatically_declare_parameters_from_overrides=True)
        seen = {name: parameter.value for name, parameter in node._parameters.items()
                if name not in ("use_sim_time", "start_type_description_service")}
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    in_file = flatten(config.read_parameter_file(path))
    expected = flatten(load_config(path))
    assert set(seen) == set(in_file)
    for name, value in seen.items():
        if isinstance(expected[name], list):
            assert list(value) == expected[name], name
        else:
            assert value == expected[name], name
            assert type(value) is type(expected[name]), name
    assert not any(isinstance(v, float) and math.isnan(v) for v in seen.values())


def test_parameters_file_checks_are_the_named_checks_and_an_unknown_one_is_refused():
    assert config.check_from_spec("integer >= 2")("x", 2) == 2
    with pytest.raises(config.ConfigError, match="x: must be an integer >= 2, got 1"):
        config.check_from_spec("integer >= 2")("x", 1)
    with pytest.raises(config.ConfigError, match="x: must be a finite number > 0.0, got 0"):
        config.check_from_spec("real > 0.0")("x", 0)
    assert config.check_from_spec("real > 0.0 or null")("x", None) is None
    with pytest.raises(config.ConfigError, match=r"<= 1.0, got 1.5"):
        config.check_from_spec("real >= 0.0 and <= 1.0")("x", 1.5)
    assert config.check_from_spec("one of a, b").options == ("a", "b")
    with pytest.raises(config.ConfigError, match="a list of 2 finite numbers"):
        config.check_from_spec("real vector of 2")("x", [1.0])
    with pytest.raises(ValueError, match="unknown check 'positive number'"):
        config.check_from_spec("positive number")


def test_naive_params_with_counts_changes_a_copy_and_checks_the_counts():
    from sensorispace_ros.core.naive.params import NaiveParams

    params = NaiveParams()
    changed = params.with_counts(unconfirmed_max_povs=700, unconfirmed_attempts=0)
    assert (changed.unconfirmed_max_povs, changed.unconfirmed_attempts) == (700, 0)
    assert (params.unconfirmed_max_povs, params.unconfirmed_attempts) != (700, 0)
    assert changed.frontier_attempts == params.frontier_attempts
    with pytest.raises(ValueError, match="naive.unconfirmed_attempts"):
        params.with_counts(unconfirmed_attempts=-1)
