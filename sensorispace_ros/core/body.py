"""The body as the naive agent meets it: motor states in, sensations out.

``SensingBody`` is the whole interface the naive strategy receives. The
simulator behind it (``SimulatedBody``) also knows the lights and the arm's
geometry. The naive code is handed ``SensingOnly(body)``, which exposes
``sense`` and the two vector sizes; Python cannot truly hide the simulator
behind it, so the tests also run the naive strategy against a body written
as a bare closure with nothing else to reach.

With numba installed (``kernel="auto"``) the simulator runs the forward
model and the retina in one compiled loop over rows (``simulate``). It does
the floating-point operations of ``arm.forward`` + ``retina.sensation`` in
their order, and numba's ``math.cos/sin/exp/hypot`` are the C library's,
which NumPy calls too where ``core.numpy_math.numpy_calls_c_math()`` (on a
machine without AVX-512: float64 has no SIMD path there), so the bits are
equal (tests/core/test_body_simulation.py checks it; on AVX-512 NumPy's own
exp is within one ulp); those two NumPy functions stay the reference and
the fallback. The kernel is single-threaded: the simulator sits inside every
round trip of the graph, where splitting a batch over threads costs more in
wake-ups than it saves (docs/benchmarks.md, "kernels").
"""
from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from sensorispace_ros.core import retina
from sensorispace_ros.core.arm import LEVEL_DIRECTION as _LEVEL_DIRECTION
from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.core.imperfections import BodyNoise
from sensorispace_ros.core.sensor_code import SensorCode

try:
    import numba
except ImportError:             # optional: the NumPy path is the fallback
    numba = None

KERNELS = ("auto", "numpy", "numba")


@runtime_checkable
class SensingBody(Protocol):
    n_motors: int
    n_sensors: int

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        """Sensations ``(B, n_sensors)`` for motor states ``(B, n_motors)``,
        probed one after the other in a static environment; the arm rests at
        the last row afterwards."""

    # Optional: ``move(motor_states)``, the same command when the caller
    # already has its sensations (``SensingOnly`` falls back to ``sense``).


# exp(-x) rounds to +0.0 from x = 745.1332... on (below half the smallest subnormal,
# 2**-1075); checked against the C library in tests/core/test_body_simulation.py.
_EXP_ZERO = 746.0


def _simulate_rows(motor, lights, receptors, sensations, poses):
    """``arm.forward`` + ``retina.sensation`` of each row of ``motor`` (B, 4),
    unit segments, lights (L, 2), into ``sensations`` (B, R) and ``poses``
    (B, 3). Written for numba; every operation and its order is the NumPy
    path's: hidden lights and underflowing terms add nothing (NumPy adds an
    exact 0.0), the sum over lights runs in light order from 0.0."""
    n_lights = lights.shape[0]
    n_receptors = receptors.shape[0]
    for b in range(motor.shape[0]):
        joint0 = motor[b, 0]
        theta1 = joint0 + motor[b, 1]
        theta2 = theta1 + motor[b, 2]
        x = math.cos(joint0) + math.cos(theta1)
        x += math.cos(theta2)
        y = math.sin(joint0) + math.sin(theta1)
        y += math.sin(theta2)
        alpha = joint0 + motor[b, 1]
        for k in range(2, motor.shape[1]):
            alpha += motor[b, k]
        poses[b, 0] = x
        poses[b, 1] = y
        poses[b, 2] = alpha
        cos_a = math.cos(alpha)
        sin_a = math.sin(alpha)
        for r in range(n_receptors):
            sensations[b, r] = 0.0
        for light in range(n_lights):
            rel_x = lights[light, 0] - x
            rel_y = lights[light, 1] - y
            depth = rel_x * cos_a + rel_y * sin_a
            if depth > 0.0:
                projection = (-rel_x * sin_a + rel_y * cos_a) / depth
                distance = math.hypot(rel_x, rel_y)
                for r in range(n_receptors):
                    exponent = receptors[r] - projection
                    exponent *= exponent
                    # Past _EXP_ZERO the term is exactly +0.0 (NumPy computes it, clipped
                    # at 800), and adding +0.0 to a sum of non-negative terms begun at
                    # +0.0 changes no bit: no call, and no trip through the C library's
                    # slow underflow path. NaN still goes through exp.
                    if not exponent >= _EXP_ZERO:
                        sensations[b, r] += math.exp(-exponent) / distance


_simulate_rows_compiled = (None if numba is None
                           else numba.njit(nogil=True, cache=True)(_simulate_rows))

EYE_CODES = {"joint": 0, "link": 1, "level": 2}


def _simulate_chain_rows(angles, lengths, eye, lights, receptors, sensations, poses):
    """``Arm.forward`` + ``retina.sensation`` of each row of ``angles`` (B, J,
    radians) for any chain of ``lengths``; ``eye`` as ``EYE_CODES``. The
    operations of the NumPy path in its order, like ``_simulate_rows``."""
    n_links = lengths.shape[0]
    n_lights = lights.shape[0]
    n_receptors = receptors.shape[0]
    for b in range(angles.shape[0]):
        theta = 0.0
        x = 0.0
        y = 0.0
        for k in range(n_links):
            theta += angles[b, k]
            x += lengths[k] * math.cos(theta)
            y += lengths[k] * math.sin(theta)
        alpha = _LEVEL_DIRECTION
        if eye == 0:
            alpha = theta + angles[b, n_links]
        elif eye == 1:
            alpha = theta
        poses[b, 0] = x
        poses[b, 1] = y
        poses[b, 2] = alpha
        _sense_row(x, y, alpha, lights, receptors, sensations[b], n_lights, n_receptors)


def _sense_row(x, y, alpha, lights, receptors, out, n_lights, n_receptors):
    """The retina of one pose into ``out`` (R,), as ``_simulate_rows`` does.
    ``_simulate_rows`` keeps these lines written out rather than calling this:
    the call, even inlined, makes the paper body's batches measurably slower
    (``bench/body_kernel --against`` a checkout that calls it)."""
    cos_a = math.cos(alpha)
    sin_a = math.sin(alpha)
    for r in range(n_receptors):
        out[r] = 0.0
    for light in range(n_lights):
        rel_x = lights[light, 0] - x
        rel_y = lights[light, 1] - y
        depth = rel_x * cos_a + rel_y * sin_a
        if depth > 0.0:
            projection = (-rel_x * sin_a + rel_y * cos_a) / depth
            distance = math.hypot(rel_x, rel_y)
            for r in range(n_receptors):
                exponent = receptors[r] - projection
                exponent *= exponent
                if not exponent >= _EXP_ZERO:
                    out[r] += math.exp(-exponent) / distance


if numba is None:
    _simulate_chain_compiled = None
else:
    _sense_row = numba.njit(nogil=True, cache=True, inline="always")(_sense_row)
    _simulate_chain_compiled = numba.njit(nogil=True, cache=True)(_simulate_chain_rows)


def numba_available() -> bool:
    """True when the compiled simulator can be used."""
    return numba is not None


def simulate(motor_states: np.ndarray, lights_world: np.ndarray,
             receptor_positions: np.ndarray, kernel: str = "auto", body_arm: Arm = PAPER_ARM
             ) -> tuple[np.ndarray, np.ndarray]:
    """Raw receptor outputs ``(B, R)`` and eye poses ``(B, 3)`` of motor states
    ``(B, J)`` in the lights ``(L, 2)``: ``retina.sensation(body_arm.forward(m))``
    and ``body_arm.forward(m)``, bit for bit, by the compiled loop when
    ``kernel`` allows it (the paper arm has a loop of its own, written out
    for its three unit segments)."""
    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    if kernel == "numba" and numba is None:
        raise ValueError("kernel 'numba' needs the numba package, which is not installed")
    motor_states = np.asarray(motor_states, dtype=float)
    lights = np.asarray(lights_world, dtype=float)
    receptors = np.asarray(receptor_positions, dtype=float)
    if kernel == "numpy" or numba is None:
        pose = body_arm.forward(motor_states)
        return retina.sensation(pose, lights, receptors), pose
    if motor_states.ndim != 2 or motor_states.shape[1] != body_arm._joints:
        raise ValueError(f"motor_states must have shape (B, {body_arm.n_joints}), "
                         f"got {motor_states.shape}")
    if lights.ndim != 2 or lights.shape[1] != 2 or receptors.ndim != 1:
        raise ValueError(f"lights_world must be (L, 2) and receptor_positions 1-D, "
                         f"got {lights.shape} and {receptors.shape}")
    sensations = np.empty((len(motor_states), len(receptors)))
    poses = np.empty((len(motor_states), 3))
    lights, receptors = np.ascontiguousarray(lights), np.ascontiguousarray(receptors)
    if body_arm._paper:
        _simulate_rows_compiled(np.ascontiguousarray(motor_states), lights, receptors,
                                sensations, poses)
    else:
        _simulate_chain_compiled(np.ascontiguousarray(body_arm.to_radians(motor_states)),
                                 np.asarray(body_arm.segments), EYE_CODES[body_arm.eye],
                                 lights, receptors, sensations, poses)
    return sensations, poses


class SimulatedBody:
    """Arm + retina simulator in a given light configuration (ground truth side).

    ``kernel``: "auto" (compiled when numba is installed), "numpy" or "numba"
    (see ``simulate``); the answers are the same bits. ``body_arm``: the
    chain (the paper arm by default); ``code``: the sensor code between the
    receptors and the agent (none: their raw outputs); ``noise``: its
    imperfect sensors and motors (``core.imperfections``; none: perfect).
    """

    def __init__(self, receptor_positions: np.ndarray, lights_world: np.ndarray | None = None,
                 motor_state: np.ndarray | None = None, kernel: str = "auto",
                 body_arm: Arm = PAPER_ARM, code: SensorCode | None = None,
                 noise: BodyNoise | None = None):
        if kernel not in KERNELS:
            raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
        self.kernel = kernel
        self.arm = body_arm
        self.code = None if code is None or code.is_identity else code
        self.receptor_positions = np.asarray(receptor_positions, dtype=float)
        self.n_motors = body_arm.n_joints
        self.n_sensors = len(self.receptor_positions)
        self.description = body_arm.description(self.n_sensors)
        self.lights_world = None if lights_world is None else np.asarray(lights_world, float)
        self.motor_state = None if motor_state is None else np.asarray(motor_state, float)
        self.queries = 0          # motor states probed so far
        self.calls = 0            # sense() calls (round trips in the ROS graph)
        self.changes = 0          # set_lights() calls: the number of the current layout
        # Imperfect sensors and motors (core.imperfections); None: a perfect body,
        # whose path stays as it was (one test per call).
        self.noise = None if noise is None or noise.imperfections.perfect else noise
        self.last_reached: np.ndarray | None = None   # joints the last command reached

    def set_lights(self, lights_world: np.ndarray, change: int | None = None) -> None:
        """The lights of change ``change`` (default: the one after the current)."""
        self.lights_world = np.asarray(lights_world, dtype=float)
        self.changes = self.changes + 1 if change is None else int(change)

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        return self.sense_with_poses(motor_states)[0]

    def sense_with_poses(self, motor_states: np.ndarray, call: int | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
        """``sense`` and the eye poses ``(B, 3)`` it computed on the way (ground
        truth, for the evaluator): the forward model runs once per row. With
        imperfections the poses are those of the joints reached, and ``call``
        (default: the next) numbers the command for the noise stream: a
        command answered again is given its first number."""
        if self.lights_world is None:
            raise RuntimeError("SimulatedBody.sense called before any lights were set")
        motor_states = np.asarray(motor_states, dtype=float)
        if self.noise is not None:
            rng, reached = self._reach(motor_states, call)
            raw, poses = simulate(reached, self.lights_world, self.receptor_positions,
                                  self.kernel, self.arm)
            return self.noise.perceive(raw, self.code, rng), poses
        self.move(motor_states)
        raw, poses = simulate(motor_states, self.lights_world, self.receptor_positions,
                              self.kernel, self.arm)
        return (raw if self.code is None else self.code.apply(raw)), poses

    def sense_at_rest(self, kernel: str | None = None, change: int | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
        """What the resting eye sees, ``(R,)``, and its pose ``(3,)``: not a
        query (no call is counted). ``kernel`` overrides the body's; ``change``
        (default: the current) numbers the sensation for the noise stream."""
        if self.lights_world is None or self.motor_state is None:
            raise RuntimeError("SimulatedBody.sense_at_rest needs lights and a motor state")
        raw, poses = simulate(self.motor_state[None], self.lights_world, self.receptor_positions,
                              kernel or self.kernel, self.arm)
        if self.noise is not None:
            rng = self.noise.passive(self.changes if change is None else change)
            return self.noise.perceive(raw, self.code, rng)[0], poses[0]
        return (raw if self.code is None else self.code.apply(raw))[0], poses[0]

    def resting_truth(self) -> np.ndarray | None:
        """What the resting eye sees without the body's imperfections, ``(R,)``
        (ground truth, not a query; the numpy kernel, the same bits on any
        machine); None before the arm rests anywhere."""
        if self.lights_world is None or self.motor_state is None:
            return None
        raw, _ = simulate(self.motor_state[None], self.lights_world, self.receptor_positions,
                          "numpy", self.arm)
        return (raw if self.code is None else self.code.apply(raw))[0]

    def move(self, motor_states: np.ndarray, call: int | None = None) -> None:
        """The command ``sense`` answers, for a caller that already has the
        sensations (the naive agent resting at a state it sensed since the
        last change): the arm ends at the last row (the joints reached);
        counted as a call."""
        motor_states = np.asarray(motor_states, dtype=float)
        if self.noise is not None:
            self._reach(motor_states, call)
            return
        # _count written out: this is every perfect call's path.
        if motor_states.ndim != 2 or motor_states.shape[1] != self.n_motors:
            raise ValueError(f"motor_states must have shape (B, {self.n_motors}), "
                             f"got {motor_states.shape}")
        self.queries += len(motor_states)
        self.calls += 1
        if len(motor_states):
            self.motor_state = motor_states[-1].copy()

    def _count(self, motor_states: np.ndarray) -> None:
        if motor_states.ndim != 2 or motor_states.shape[1] != self.n_motors:
            raise ValueError(f"motor_states must have shape (B, {self.n_motors}), "
                             f"got {motor_states.shape}")
        self.queries += len(motor_states)
        self.calls += 1

    def _reach(self, motor_states: np.ndarray, call: int | None
               ) -> tuple[np.random.Generator | None, np.ndarray]:
        """Count command ``call`` (default: the next) and move the imperfect arm:
        its generator (the motor draws taken) and the joints reached."""
        number = self.calls if call is None else int(call)
        self._count(motor_states)
        self.calls = number + 1
        rng = self.noise.command(number)
        reached = self.noise.reach(motor_states, rng)
        self.last_reached = reached
        if len(reached):
            self.motor_state = reached[-1].copy()
        return rng, reached

    def sensor_pose(self, motor_states: np.ndarray) -> np.ndarray:
        """Ground truth pose of the eye (evaluation only)."""
        return self.arm.forward(np.asarray(motor_states, dtype=float))


class SensingOnly:
    """Expose only ``sense`` and the vector sizes of a body: what a naive agent may touch."""

    __slots__ = ("_sense", "_move", "n_motors", "n_sensors", "description")

    def __init__(self, body: SensingBody):
        self._sense = body.sense
        self._move = getattr(body, "move", None)
        self.n_motors = int(body.n_motors)
        self.n_sensors = int(body.n_sensors)
        self.description = (getattr(body, "description", None)
                            or BodyDescription.revolute(self.n_motors, self.n_sensors))

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        """The body's answer as float64, whatever type the body senses in (the
        agent's view in the graph too: ``messages`` converts a sensation's
        columns to float64)."""
        return np.asarray(self._sense(motor_states), dtype=float)

    def move(self, motor_states: np.ndarray) -> None:
        """The body's ``move``; a body without one senses and the answer is dropped."""
        if self._move is None:
            self._sense(motor_states)
        else:
            self._move(motor_states)
