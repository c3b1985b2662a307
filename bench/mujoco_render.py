"""Rendering cost of a MuJoCo body's frames (docs/benchmarks.md, "A MuJoCo body").

    .venv/bin/python -m bench.mujoco_render [--config config/mujoco-arm.yaml] [--frames 512]

Times, per frame, at the same motor states of the configuration's model:
the body's own path (``MujocoBody.sense``: tiles, effects off; wall time
and the process's CPU time, every thread's, which does not depend on what
else the machine runs), and as
baselines ``mujoco.Renderer`` one frame at a time with MuJoCo's default
visual settings, and with the body's settings (shadows, reflections, skybox
and the other effects off, no multisampling), without and with a ``plane``
floor. Also the singular values,
relative to the first, of the central-difference Jacobian of the images at
the start, at several steps (rad): the kinematics make the last one 0
wherever the joints outnumber the pose's 3 degrees of freedom; and with
``mujoco.settle: physics`` the cost of a row and how far its joints land
from the command. Prints JSON.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np


PLANE = '<geom name="bench_floor" type="plane" size="20 20 0.1" rgba="0 0 0 1"/>'


def _renderer_ms(world, states, effects_off: bool, plane: bool = False) -> float:
    import mujoco

    xml = world.spec.path.read_text()
    if plane:
        xml = xml.replace("<worldbody>", "<worldbody>" + PLANE, 1)
    model = mujoco.MjModel.from_xml_string(xml)
    if effects_off:
        model.vis.quality.offsamples = 0
    width, height = world.mujoco_cfg["image"]
    renderer = mujoco.Renderer(model, height, width)
    if effects_off:
        for flag in range(mujoco.mjtRndFlag.mjNRNDFLAG):
            renderer.scene.flags[flag] = 0
    data = mujoco.MjData(model)
    address = model.jnt_qposadr[list(world.spec.joints)]
    started = time.perf_counter()
    for state in states:
        data.qpos[address] = state
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)
        renderer.update_scene(data, int(world.spec.camera))
        renderer.render()
    elapsed = time.perf_counter() - started
    renderer.close()
    return 1e3 * elapsed / len(states)


def _jacobian_spectrum(world, steps=(1e-3, 3e-3, 1e-2, 3e-2, 1e-1)) -> dict:
    body = world.body(lights=world.initial_lights)
    joints = np.eye(len(world.m0))
    out = {}
    for step in steps:
        rows = np.vstack([world.m0 + step * joints, world.m0 - step * joints])
        images = body.sense(rows).astype(float)
        jacobian = (images[:len(joints)] - images[len(joints):]).T / (2 * step)
        values = np.linalg.svd(jacobian, compute_uv=False)
        out[f"{step:g}"] = [round(float(v), 4) for v in values / values[0]]
    return out


def _physics(world, states) -> dict:
    """``mujoco.settle: physics``: the cost of a row and how far the joints land."""
    body = world.body(lights=world.initial_lights)
    started = time.perf_counter()
    body.sense(states)
    return {"physics_settle_ms_per_row": 1e3 * (time.perf_counter() - started) / len(states),
            "physics_max_joint_error_rad": float(np.abs(body.last_reached - states).max())}


def main(argv=None) -> int:
    from sensorispace_ros import config
    from sensorispace_ros.bodies import run_world

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="config/mujoco-arm.yaml")
    parser.add_argument("--frames", type=int, default=512)
    args = parser.parse_args(argv)
    world = run_world(config.load_config(args.config))
    physics = run_world(config.load_config(args.config, {"mujoco.settle": "physics"}))
    states = world.m0 + np.random.default_rng(0).uniform(-0.3, 0.3, (args.frames, len(world.m0)))
    body = world.body(lights=world.initial_lights)
    body.sense(states[:64])                                       # warm-up
    started, cpu = time.perf_counter(), time.process_time()
    body.sense(states)
    body_ms = 1e3 * (time.perf_counter() - started) / len(states)
    # CPU time of the process (every thread, Mesa's too): what a frame costs
    # whatever else the machine runs.
    body_cpu_ms = 1e3 * (time.process_time() - cpu) / len(states)
    results = {"config": args.config, "frames": args.frames,
               "image": world.mujoco_cfg["image"], "channels": world.mujoco_cfg["channels"],
               "supersample": world.mujoco_cfg["supersample"], "blur": world.mujoco_cfg["blur"],
               "body_ms_per_frame": body_ms, "body_cpu_ms_per_frame": body_cpu_ms,
               "renderer_effects_off_ms_per_frame": _renderer_ms(world, states[:128], True),
               "renderer_defaults_ms_per_frame": _renderer_ms(world, states[:64], False),
               "renderer_effects_off_with_plane_ms_per_frame":
                   _renderer_ms(world, states[:128], True, plane=True),
               "jacobian_relative_singular_values": _jacobian_spectrum(world),
               **_physics(physics, states[:32])}
    print(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
