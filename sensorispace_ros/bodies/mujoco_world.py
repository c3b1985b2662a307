"""The world of a MuJoCo body: the model's object moved over the grid.

The object (``mujoco.object``, a mocap body) starts where the model puts it;
its geoms are its "lights": the world's points are the geoms' positions, in
the frame of the chain MuJoCo's kinematics describe (``bodies.mujoco_model``).
The object visits every position of the grid (``world.grid_count`` per axis
over [-``world.grid_half_width``, ``world.grid_half_width``]², a displacement
from where it starts, which is one of them: ``_grid_about``) in the seeded order (``world.schedule``); after a move,
with probability ``world.redistribution_probability``, its geoms are
rearranged by the seed, uniformly over the annulus the model's arrangement
fills about its centre: a state change no movement of the body undoes
(``core.world.schedule``).

The run's world is a ``core.paper.exploration.World`` whose arm is that
chain, so the paper strategy, the compensable positions and the evaluator
work as for the simulated body; its ``body()`` is the ``MujocoBody``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sensorispace_ros.bodies.mujoco_body import MujocoBody
from sensorispace_ros.bodies.mujoco_model import MujocoSpec, PlanarChain, planar_chain
from sensorispace_ros.config import ConfigError
from sensorispace_ros.core import world as world_mod
from sensorispace_ros.core.paper.exploration import PAPER_PARAMS, World
from sensorispace_ros.core.run_world import world_params
from sensorispace_ros.core.sensor_code import SensorCode
from sensorispace_ros.core.seeding import rng_for


@dataclass(frozen=True)
class MujocoWorld(World):
    """A ``World`` whose body is a MuJoCo model (``spec``, ``chain``, ``mujoco.*``)."""

    spec: MujocoSpec | None = field(default=None, repr=False)
    chain: PlanarChain | None = field(default=None, repr=False)
    mujoco_cfg: dict = field(default_factory=dict, repr=False)
    sensation_dtype: str = "uint8"

    def body(self, kernel: str = "auto", lights: np.ndarray | None = None) -> MujocoBody:
        """The MuJoCo body of this world, resting at ``m0``."""
        return MujocoBody(self.spec, self.chain, self.mujoco_cfg, lights, self.m0.copy(),
                          layouts=self.layouts)

    @property
    def layouts(self) -> list:
        """The object's arrangements of its geoms, unturned (chain frame, about
        their centre): the start's and each rearrangement's."""
        return [self.initial_offsets] + [e.offsets for e in self.events
                                         if e.kind == world_mod.REDISTRIBUTION]


def _grid_about(center: np.ndarray, world: dict) -> tuple[np.ndarray, int | None]:
    """The object's grid, a displacement from where the model puts it, and the index of that start.

    ``world.initial_position: grid``: the grid is shifted so that its position nearest its centre is
    the start (half a step, for an even ``grid_count``), as the simulated world starts on its grid:
    every change is then a whole number of grid steps from the start, and anchors recorded before
    and after a change give one lattice of sensor positions. ``center``: the grid centred on the
    start, half a step off it for an even count."""
    steps = world_mod.position_grid(world["grid_half_width"], world["grid_count"])
    if world["initial_position"] != "grid":
        return center + steps, None
    nearest = int(np.argmin(np.einsum("ij,ij->i", steps, steps)))
    return center + steps - steps[nearest], nearest


def mujoco_world(cfg: dict, seed: int | None = None) -> MujocoWorld:
    """The world of a run of the validated configuration ``cfg`` with ``body.kind: mujoco``."""
    seed = int(cfg["seed"] if seed is None else seed)
    spec = MujocoSpec.load(cfg)
    chain = planar_chain(spec)
    m0 = np.asarray(cfg["arm"]["initial_motor_state"], dtype=float)
    if m0.shape != (len(spec.joints),):
        raise ConfigError(f"arm.initial_motor_state: must hold one value per joint of "
                          f"{spec.path.name} ({', '.join(spec.joint_names)}), got {m0.tolist()}")
    model = spec.model
    mocap_xy = model.body_pos[spec.object_body, :2]
    geoms_world = mocap_xy + model.geom_pos[list(spec.object_geoms), :2]
    points = _to_chain(chain, geoms_world)
    center = points.mean(axis=0)
    offsets = points - center
    radii = np.hypot(offsets[:, 0], offsets[:, 1])
    inner, outer = float(np.min(radii)), float(max(np.max(radii), 1e-6))
    world = cfg["world"]
    grid, start_index = _grid_about(center, world)
    light_kwargs = {"count": len(offsets), "radius_min": min(inner, 0.999 * outer),
                    "radius_max": outer}
    events = world_mod.schedule(grid, rng_for(seed, "schedule"), offsets,
                                redistribution_probability=world["redistribution_probability"],
                                order=world["schedule"], light_kwargs=light_kwargs,
                                rotation_count=int(world["rotation_count"]),
                                start_index=start_index)
    n_pixels = int(np.prod(cfg["mujoco"]["image"])) * (3 if cfg["mujoco"]["channels"] == "rgb"
                                                         else 1)
    params = {**PAPER_PARAMS, **world_params(cfg), "m0": tuple(m0),
              "segments": chain.arm.segments, "eye": chain.arm.eye, "motor_unit": "rad",
              "n_lights": len(offsets), "n_receptors": n_pixels}
    return MujocoWorld(seed=seed, params=params, m0=m0,
                       receptors=np.zeros(n_pixels), arm=chain.arm,
                       code=SensorCode("identity", 1.0, n_pixels, None),
                       initial_center=center, initial_offsets=offsets, grid=grid,
                       spacing=world_mod.grid_spacing(world["grid_half_width"],
                                                      world["grid_count"]),
                       events=events, spec=spec, chain=chain, mujoco_cfg=dict(cfg["mujoco"]))


def _to_chain(chain: PlanarChain, xy: np.ndarray) -> np.ndarray:
    c, s = np.cos(chain.heading), np.sin(chain.heading)
    rel = np.asarray(xy, dtype=float) - chain.base
    return np.column_stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]])
