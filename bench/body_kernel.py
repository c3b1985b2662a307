"""The simulated body's compiled kernel on every catalogue body, against the
paper arm's written-out loop measured in the same run.

For the paper body, ``simulate`` (what ``SimulatedBody.sense`` calls) is
timed against a direct call of the paper arm's compiled loop
(``core.body._simulate_rows_compiled``): the ratio is the cost of
dispatching by body. The generic chain kernel on the same three unit links
is timed too. Then microseconds per row of ``simulate`` on each body of
``config/bodies/``.

Then ``SimulatedBody.sense`` on the paper body, perfect and with each
imperfection of ``config/noisy-smoke.yaml`` (and all of them), per call.

``--against DIR`` also times ``SimulatedBody.sense`` on the paper body in
child processes alternating between this checkout and the one at ``DIR``
(e.g. a ``git worktree`` of an earlier commit), three rounds, best of each:

    .venv/bin/python -m bench.body_kernel [--against DIR]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from sensorispace_ros import config
from sensorispace_ros.core import body as body_module
from sensorispace_ros.core.arm import PAPER_ARM
from sensorispace_ros.core.body import EYE_CODES, simulate
from sensorispace_ros.graph.framework import build_world

CATALOGUE = Path(__file__).resolve().parents[1] / "config" / "bodies"
BATCHES = (1, 100, 2000)


def _best(fn, repeats: int) -> float:
    """Smallest wall time of ``repeats`` calls (seconds)."""
    best = np.inf
    for _ in range(repeats):
        started = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - started)
    return best


def paper_body_ratios(repeats: int = 2000) -> dict:
    """``simulate`` and the chain kernel over the paper arm's own loop, per batch size."""
    world = build_world(config.load_config())
    lights, receptors = world.initial_lights, world.receptors
    out = {}
    for rows in BATCHES:
        motor = np.random.default_rng(0).uniform(-3, 3, (rows, 4))
        sens, poses = np.empty((rows, len(receptors))), np.empty((rows, 3))
        own = _best(lambda: body_module._simulate_rows_compiled(motor, lights, receptors,
                                                                sens, poses), repeats)
        dispatched = _best(lambda: simulate(motor, lights, receptors, "numba", PAPER_ARM),
                           repeats)
        chain = _best(lambda: body_module._simulate_chain_compiled(
            motor, np.ones(3), EYE_CODES["joint"], lights, receptors, sens, poses), repeats)
        out[rows] = {"own_us": 1e6 * own, "simulate_us": 1e6 * dispatched,
                     "chain_us": 1e6 * chain, "simulate_ratio": dispatched / own,
                     "chain_ratio": chain / own}
    return out


def catalogue_us_per_row(rows: int = 2000, repeats: int = 200) -> dict:
    out = {}
    for path in sorted(CATALOGUE.glob("*.yaml")):
        world = build_world(config.load_config(path))
        body = world.body(lights=world.initial_lights)
        motor = world.arm.from_radians(
            np.random.default_rng(0).uniform(-3, 3, (rows, world.arm.n_joints)))
        out[path.stem] = 1e6 * _best(lambda: body.sense(motor), repeats) / rows
    return out


IMPERFECTIONS = {"perfect": {}, "noise": {"world.retina.noise": 1e-3},
                 "quantum": {"world.retina.quantum": 1e-3},
                 "float32": {"world.retina.dtype": "float32"},
                 "dropout": {"world.retina.dropout": 1e-3},
                 "motor_noise": {"arm.motor_noise": 1e-3},
                 "all": {"world.retina.noise": 1e-3, "world.retina.quantum": 1e-3,
                         "world.retina.dtype": "float32", "world.retina.dropout": 1e-3,
                         "arm.motor_noise": 1e-3}}


def imperfect_sense_us(repeats: int = 3000) -> dict:
    """``SimulatedBody.sense`` (us per call) on the paper body for each entry of
    IMPERFECTIONS, per batch size."""
    out = {}
    for name, overrides in IMPERFECTIONS.items():
        world = build_world(config.load_config(overrides=config.unflatten(overrides)))
        body = world.body(lights=world.initial_lights)
        out[name] = {}
        for rows in BATCHES:
            motor = np.random.default_rng(0).uniform(-3, 3, (rows, 4))
            body.sense(motor)
            out[name][rows] = 1e6 * _best(lambda: body.sense(motor),
                                          repeats if rows < 2000 else repeats // 6)
    return out


# Timed in a child process of either checkout: only what both have.
_SENSE_TIMES = """
import json, sys, time
import numpy as np
from sensorispace_ros import config
from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.graph.framework import build_world
assert sys.modules["sensorispace_ros"].__file__.startswith(sys.argv[1]), "wrong checkout"
world = build_world(config.load_config())
body = SimulatedBody(world.receptors, world.initial_lights)
out = {}
for rows in (1, 100, 2000):
    motor = np.random.default_rng(0).uniform(-3, 3, (rows, 4))
    body.sense(motor)
    best = np.inf
    for _ in range(3000 if rows < 2000 else 500):
        started = time.perf_counter()
        body.sense(motor)
        best = min(best, time.perf_counter() - started)
    out[rows] = 1e6 * best
print(json.dumps(out))
"""


def compare_with(tree: Path, rounds: int = 3) -> None:
    """``SimulatedBody.sense`` (us) on the paper body here and in ``tree``,
    alternating, best of ``rounds``."""
    here = Path(__file__).resolve().parents[1]
    best = {"here": {}, "there": {}}
    for _ in range(rounds):
        for side, root in (("there", Path(tree).resolve()), ("here", here)):
            done = subprocess.run([sys.executable, "-c", _SENSE_TIMES, str(root)], cwd=root,
                                  env={**os.environ, "PYTHONPATH": str(root)}, check=True,
                                  capture_output=True, text=True)
            for rows, us in json.loads(done.stdout).items():
                best[side][rows] = min(best[side].get(rows, np.inf), us)
    print(f"SimulatedBody.sense on the paper body, here against {tree}:")
    for rows in best["here"]:
        print(f"  {rows:>5} rows  {best['there'][rows]:8.2f} us -> {best['here'][rows]:8.2f} us"
              f"  ratio {best['here'][rows] / best['there'][rows]:.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--against", type=Path, help="another checkout to time against")
    args = parser.parse_args()
    if args.against is not None:
        compare_with(args.against)
    if not body_module.numba_available():
        raise SystemExit("numba is not installed: nothing compiled to time")
    simulate(np.zeros((1, 4)), np.ones((1, 2)), np.zeros(1), "numba", PAPER_ARM)   # compile
    print("paper body: rows, the paper loop (us), simulate (us, ratio), chain kernel (us, ratio)")
    for rows, r in paper_body_ratios().items():
        print(f"  {rows:5d}  {r['own_us']:8.2f}  {r['simulate_us']:8.2f} ({r['simulate_ratio']:.3f})"
              f"  {r['chain_us']:8.2f} ({r['chain_ratio']:.3f})")
    print("SimulatedBody.sense on the paper body, us per call: rows " +
          "  ".join(f"{rows:>8d}" for rows in BATCHES))
    for name, by_rows in imperfect_sense_us().items():
        print(f"  {name:12s}" + "  ".join(f"{us:8.2f}" for us in by_rows.values()))
    print("us per row of SimulatedBody.sense, 2000-row batches:")
    for name, us in catalogue_us_per_row().items():
        print(f"  {name:18s} {us:.3f}")


if __name__ == "__main__":
    main()
