"""A run's world from its configuration: the one place that turns the
``world.*`` and ``arm.*`` parameters into ``core.paper.exploration.build_world``
arguments. Every run producer, node and evaluator builds its world here."""
from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sensorispace_ros.core.paper.exploration import World


def world_params(cfg: dict) -> dict:
    """``core.paper.exploration.build_world`` parameters from the configuration."""
    world, lights, retina = cfg["world"], cfg["world"]["lights"], cfg["world"]["retina"]
    return {
        "m0": tuple(cfg["arm"]["initial_motor_state"]),
        "grid_half_width": world["grid_half_width"],
        "grid_count": world["grid_count"],
        "initial_center": world["initial_position"],
        "n_lights": lights["count"],
        "light_radius_min": lights["radius_min"],
        "light_radius_max": lights["radius_max"],
        "n_receptors": retina["receptors"],
        "retina_half_width": retina["half_width"],
        "min_lights_in_view": lights["min_in_view"],
        "redistribution_probability": world["redistribution_probability"],
        "order": world["schedule"],
        "rotation_count": world["rotation_count"],
        "segments": tuple(cfg["arm"]["segments"]),
        "eye": cfg["arm"]["eye"],
        "motor_unit": cfg["arm"]["motor_unit"],
        "code": retina["code"],
        "code_value": retina["code_value"],
        "retina_noise": retina["noise"],
        "retina_quantum": retina["quantum"],
        "retina_dtype": retina["dtype"],
        "retina_dropout": retina["dropout"],
        "motor_noise": cfg["arm"]["motor_noise"],
    }


def run_world(cfg: dict, seed: int | None = None) -> World:
    """The world (ground truth and schedule) of a run of the validated
    configuration ``cfg``, seeded by ``seed`` (``cfg["seed"]`` by default).
    A start of another length than the simulated arm's joints (a body of
    one's own) is replaced, for the draw, by the simulated arm's default."""
    from sensorispace_ros.core.paper import exploration   # numba and scipy: on first use

    params = world_params(cfg)
    n_joints = exploration.Arm.from_config(cfg["arm"]).n_joints
    if len(params["m0"]) != n_joints:
        # A start given for a body of one's own, not the simulated arm: the
        # lights are drawn for the simulated arm's own default start.
        default = exploration.PAPER_PARAMS["m0"]
        params["m0"] = tuple(default) if len(default) == n_joints else (0.0,) * n_joints
    return exploration.build_world(int(cfg["seed"] if seed is None else seed), params)
