"""Bodies the project did not write, behind the body contract.

``run_world(cfg, seed)`` is the run's world for any ``body.kind``: the
simulated arm (``core.run_world``) or a MuJoCo model (``mujoco_world``:
its camera's pixels are the receptors, docs/mujoco.md). MuJoCo is imported
only when a MuJoCo body is asked for.
"""
from __future__ import annotations

from sensorispace_ros.core.run_world import run_world as simulated_world


def run_world(cfg: dict, seed: int | None = None):
    """The world (ground truth, schedule, ``body()``) of a run of the validated
    configuration ``cfg``, seeded by ``seed`` (``cfg["seed"]`` by default)."""
    if cfg.get("body", {}).get("kind", "simulated") == "mujoco":
        from sensorispace_ros.bodies.mujoco_world import mujoco_world
        return mujoco_world(cfg, seed)
    return simulated_world(cfg, seed)
