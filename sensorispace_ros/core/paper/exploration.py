"""Simulation 1 with the paper's analytic strategy: the object visits every
grid position, the agent compensates each change it can (paper Sec. 4.2,
"Estimating spatially related points of view").

Two steps, kept apart so the POVs of all compensating states are sampled in
one batch (``points_of_view.sample_points_of_view`` walks them together):

    world = build_world(seed, params)
    result = explore_paper(m0=world.m0, grid=world.grid, events=world.events,
                           initial_center=world.initial_center, body_arm=world.arm)
    povs = sample_points_of_view(result.motor_states, body_arm=world.arm)

Any body (``core.arm.Arm``): the paper arm keeps the paper's literal tests
(``|tip| < 1`` is a split POV, ``1 <= |tip| <= 3`` the working ring); another
arm uses the geometry they come from (``fibres.fibre_is_split``, its reach).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from sensorispace_ros.core import arm, retina, world as world_mod
from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.core.imperfections import BodyNoise, Imperfections
from sensorispace_ros.core.paper.compensation import compensate_pose
from sensorispace_ros.core.paper.fibres import fibre_is_split
from sensorispace_ros.core.sensor_code import SensorCode
from sensorispace_ros.core.seeding import rng_for

# Paper values (Sec. 4); receptor and light layouts are ours (the paper
# leaves them open), see retina.draw_receptor_positions and
# world.draw_light_offsets.
PAPER_PARAMS = {
    "m0": (0.1, -1.5, 2.2, -3.0),
    "grid_half_width": 6.0,
    "grid_count": 62,
    "initial_center": "grid",      # or (x, y): see initial_object_center
    "n_lights": 10,
    "light_radius_min": 3.5,
    "light_radius_max": 7.0,
    "n_receptors": 6,
    "retina_half_width": 1.0,
    "min_lights_in_view": 3,
    "max_light_draws": 10_000,
    "redistribution_probability": 0.1,
    "order": "random",
    # Object orientations over a full turn (0: the object only translates, the paper).
    "rotation_count": 0,
    "segments": arm.SEGMENT_LENGTHS,
    "eye": "joint",
    "motor_unit": "rad",
    "code": "identity",
    "code_value": 1.0,
    # A perfect body (core.imperfections): the naive agent's body only; the
    # paper strategy computes with the forward model and never senses.
    "retina_noise": 0.0,
    "retina_quantum": 0.0,
    "retina_dtype": "float64",
    "retina_dropout": 0.0,
    "motor_noise": 0.0,
}

# Reasons an environmental change is not compensated.
NOT_CONVERGED = "not_converged"          # Nelder-Mead error above threshold
SPLIT_POINT_OF_VIEW = "split_point_of_view"  # a 1-D fibre in two pieces: the walk covers one
STATE_CHANGE = "state_change"            # the light set did not move rigidly


@dataclass(frozen=True)
class World:
    """Everything random about one run, drawn from ``seed`` (ground truth)."""

    seed: int
    params: dict
    m0: np.ndarray
    receptors: np.ndarray
    arm: arm.Arm
    code: SensorCode
    initial_center: np.ndarray
    initial_offsets: np.ndarray
    grid: np.ndarray
    spacing: float
    events: list

    @property
    def initial_lights(self) -> np.ndarray:
        return self.initial_center + self.initial_offsets

    @property
    def imperfections(self) -> Imperfections:
        """What the body does wrong (a perfect body by default)."""
        return imperfections_of(self.params)

    def body(self, kernel: str = "auto", lights: np.ndarray | None = None) -> SimulatedBody:
        """The simulated body of this world, resting at ``m0``, with its
        imperfections drawn from ``seed`` (``core.imperfections``)."""
        imperfect = self.imperfections
        return SimulatedBody(self.receptors, lights, self.m0.copy(), kernel,
                             body_arm=self.arm, code=self.code,
                             noise=None if imperfect.perfect else BodyNoise(imperfect, self.seed))


def imperfections_of(params: dict) -> Imperfections:
    """The body's imperfections among world parameters (``PAPER_PARAMS`` keys)."""
    return Imperfections(noise=float(params["retina_noise"]),
                         quantum=float(params["retina_quantum"]),
                         dtype=str(params["retina_dtype"]), dropout=float(params["retina_dropout"]),
                         motor_noise=float(params["motor_noise"]))


def build_world(seed: int, params: dict | None = None) -> World:
    """Receptors, initial light offsets, object grid and event schedule.

    Streams: ``"retina"`` draws the receptors, ``"lights"`` the initial
    offsets (redrawn until the initial pose sees at least
    ``min_lights_in_view`` lights, otherwise the sensation does not pin the
    pose), ``"schedule"`` the visiting order and the redistributions.
    ``params`` overrides ``PAPER_PARAMS``; unknown keys are an error.
    """
    merged = dict(PAPER_PARAMS)
    unknown = set(params or {}) - set(PAPER_PARAMS)
    if unknown:
        raise ValueError(f"unknown world parameters {sorted(unknown)}; "
                         f"known: {sorted(PAPER_PARAMS)}")
    merged.update(params or {})
    body_arm = arm.Arm(tuple(merged["segments"]), merged["eye"], merged["motor_unit"])
    m0 = np.asarray(merged["m0"], dtype=float)
    if m0.shape != (body_arm.n_joints,):
        raise ValueError(f"m0 must have {body_arm.n_joints} joint values, got {merged['m0']}")
    grid = world_mod.position_grid(float(merged["grid_half_width"]), int(merged["grid_count"]))
    center = initial_object_center(merged["initial_center"], grid)
    on_grid = np.flatnonzero(np.all(grid == center, axis=1))

    receptors = retina.draw_receptor_positions(rng_for(seed, "retina"),
                                               int(merged["n_receptors"]),
                                               half_width=float(merged["retina_half_width"]))
    light_kwargs = {"count": int(merged["n_lights"]),
                    "radius_min": float(merged["light_radius_min"]),
                    "radius_max": float(merged["light_radius_max"])}
    code = SensorCode(merged["code"], merged["code_value"], len(receptors),
                      rng_for(seed, "sensor_code") if merged["code"] == "mix" else None)
    pose0 = body_arm.forward(m0)
    imperfections_of(merged)            # a bad imperfection fails here, naming its parameter
    light_rng = rng_for(seed, "lights")
    for _ in range(int(merged["max_light_draws"])):
        offsets = world_mod.draw_light_offsets(light_rng, **light_kwargs)
        if retina.lights_in_view(pose0, center + offsets, receptors) >= merged["min_lights_in_view"]:
            break
    else:
        raise ValueError(f"no light layout out of {merged['max_light_draws']} draws puts "
                         f"min_lights_in_view={merged['min_lights_in_view']} lights in view")
    events = world_mod.schedule(grid, rng_for(seed, "schedule"), offsets,
                                redistribution_probability=float(merged["redistribution_probability"]),
                                order=merged["order"], light_kwargs=light_kwargs,
                                rotation_count=int(merged["rotation_count"]),
                                start_index=int(on_grid[0]) if len(on_grid) else None)
    return World(seed=int(seed), params=merged, m0=m0, receptors=receptors, arm=body_arm,
                 code=code,
                 initial_center=center, initial_offsets=offsets, grid=grid,
                 spacing=world_mod.grid_spacing(float(merged["grid_half_width"]),
                                                int(merged["grid_count"])),
                 events=events)


def initial_object_center(where, grid: np.ndarray) -> np.ndarray:
    """The object's position before the first change.

    ``"grid"``: the grid position nearest [0, 0]. Every change then moves the object by a whole number
    of grid steps, so an anchor recorded at the start and one recorded after
    any change give the same lattice of compensating sensor positions.
    ``"center"``: [0, 0], half a step off the grid when ``grid_count`` is
    even; anchors recorded before and after the first change then give two
    lattices offset by half a step. ``(x, y)``: that position.
    """
    if isinstance(where, str):
        if where == "grid":
            return grid[int(np.argmin(np.einsum("ij,ij->i", grid, grid)))].astype(float)
        if where == "center":
            return np.zeros(2)
        raise ValueError(f"initial_center must be 'grid', 'center' or (x, y), got {where!r}")
    center = np.asarray(where, dtype=float)
    if center.shape != (2,):
        raise ValueError(f"initial_center must be (x, y), got {where!r}")
    return center


@dataclass
class ExplorationResult:
    """Compensating motor states of one exploration (simulation 1).

    ``motor_states[0]`` is ``m0`` (the initial POV, ``events_index`` -1);
    the others are the successful compensations in event order.
    ``true_poses``/``grid_index`` are ground truth, for evaluation only
    (``grid_index`` is -1 for the initial state).
    """

    motor_states: np.ndarray
    events_index: np.ndarray
    true_poses: np.ndarray
    grid_index: np.ndarray
    events: int
    state_changes: int
    compensated: int
    state_changes_compensated: int
    failures_by_reason: dict
    missed_in_ring: np.ndarray       # ground truth: grid indices with a reachable, whole target not compensated
    timings_s: dict = field(default_factory=dict)


def rigid_translation_fit(lights_before: np.ndarray, lights_after: np.ndarray):
    """Best translation between two light sets (light l -> light l) and the
    RMS residual of that fit."""
    before = np.asarray(lights_before, dtype=float)
    after = np.asarray(lights_after, dtype=float)
    if before.shape != after.shape or before.ndim != 2 or before.shape[1] != 2:
        raise ValueError(f"light sets must both be (L, 2), got {before.shape} and {after.shape}")
    delta = np.mean(after - before, axis=0)
    residual = after - before - delta
    return delta, float(np.sqrt(np.mean(np.sum(residual * residual, axis=1))))


def rigid_motion_residual(lights_before: np.ndarray, lights_after: np.ndarray):
    """RMS residual of the best rigid motion (rotation and translation, light
    l -> light l, Kabsch) between two light sets: 0 for a displacement of the
    object, positive for a redistribution."""
    before = np.asarray(lights_before, dtype=float)
    after = np.asarray(lights_after, dtype=float)
    if before.shape != after.shape or before.ndim != 2 or before.shape[1] != 2:
        raise ValueError(f"light sets must both be (L, 2), got {before.shape} and {after.shape}")
    a, b = before - before.mean(axis=0), after - after.mean(axis=0)
    u, _, vt = np.linalg.svd(a.T @ b)
    flip = np.diag([1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])
    rotation = (u @ flip @ vt).T
    residual = b - a @ rotation.T
    return rotation, float(np.sqrt(np.mean(np.sum(residual * residual, axis=1))))


def moved_pose(pose, center_before, center_after, turn: float) -> np.ndarray:
    """The sensor pose that sees the object moved from ``center_before`` to
    ``center_after`` and turned by ``turn`` (rad, about its centre) as ``pose``
    saw it before: the pose relative to the object is kept (the eye turns with
    it). With ``turn`` 0, ``pose`` plus the centre's displacement."""
    pose = np.asarray(pose, dtype=float)
    center_before = np.asarray(center_before, dtype=float)
    center_after = np.asarray(center_after, dtype=float)
    if turn == 0.0:
        return pose + np.array([*(center_after - center_before), 0.0])
    xy = center_after + world_mod.rotation_matrix(turn) @ (pose[:2] - center_before)
    return np.array([xy[0], xy[1], pose[2] + turn])


def explore_paper(*, m0, grid, events, initial_center=(0.0, 0.0), threshold: float = 1e-3,
                  rigid_tol: float = 1e-9, compensation_options: dict | None = None,
                  skip_certain_failures: bool = True, progress=None,
                  body_arm: Arm = PAPER_ARM) -> ExplorationResult:
    """Walk the event list and compensate every change the analytic shortcut can.

    Translation: the target pose is the pose at the *last successful*
    compensation plus the object's displacement since then (the only
    reading that reproduces the paper's 648 compensations and its Fig. 7a;
    "current pose + this event's displacement" re-anchors after every
    failure). Nelder-Mead starts from the arm's current state (the last
    compensating one: after a failure "the arm resumes its previous
    configuration").

    Redistribution: the analytic shortcut only knows rigid translations of
    the light set (paper Eq. displacementobject). Its stand-in for "no motor
    change can restore the sensation" is the residual of the best
    translation between the light sets before and after: above ``rigid_tol``
    the change is declared non-compensable. (The paper's formula, with a
    null displacement, would "compensate" it trivially.)

    Compensations whose 1-D POV is split (two loops, paper Fig. 5b) are
    discarded and the arm stays put; 0-D and 2-D POVs are sampled whole.

    ``skip_certain_failures``: a target farther than ``threshold`` from the
    tip's workspace (the annulus ``inner_reach <= |xy| <= reach``) cannot be
    compensated by any motor state (the pose error is at least the distance
    of its position to that annulus, whatever the eye's orientation), and on
    the paper arm one with ``|target_xy| < 1 - threshold`` can only be
    reached with a split POV; all are decided without running Nelder-Mead,
    with the same outcome. ``grid`` is the object's grid (checked against
    the events' grid indices). ``progress(done, total)``: every 100 events.
    """
    m0 = _checked_exploration(m0, grid, events, threshold, rigid_tol, body_arm)
    started = time.perf_counter()
    pose0 = body_arm.forward(m0)
    tally = _Tally(states=[m0.copy()], event_ids=[-1], poses=[pose0], grid_ids=[-1],
                   body_arm=body_arm, threshold=threshold,
                   options=dict(compensation_options or {}))
    anchor_pose, anchor_center, anchor_turn = pose0.copy(), np.asarray(initial_center, float), 0.0
    fit = rigid_motion_residual if any(e.orientation for e in events) else rigid_translation_fit
    lights = anchor_center + events[0].offsets if events else None
    for k, event in enumerate(events):
        residual, lights = fit(lights, event.lights)[-1], event.lights
        is_redistribution = event.kind == world_mod.REDISTRIBUTION
        tally.state_changes += is_redistribution
        if residual > rigid_tol:
            tally.failures[STATE_CHANGE] += 1
            continue
        tally.state_changes_compensated += is_redistribution
        center = event.center
        target = moved_pose(anchor_pose, anchor_center, center, event.orientation - anchor_turn)
        if tally.follow(target, event, skip_certain_failures):
            anchor_pose, anchor_center = tally.poses[-1], center.copy()
            anchor_turn = event.orientation
        if progress is not None and (k + 1) % 100 == 0:
            progress(k + 1, len(events))
    if progress is not None:
        progress(len(events), len(events))
    return tally.result(len(events), time.perf_counter() - started)


def _checked_exploration(m0, grid, events, threshold, rigid_tol, body_arm) -> np.ndarray:
    """``m0`` as a float array, after checking ``explore_paper``'s arguments."""
    m0 = np.asarray(m0, dtype=float)
    if m0.shape != (body_arm.n_joints,):
        raise ValueError(f"m0 must have {body_arm.n_joints} joint angles, got {m0}")
    grid = np.asarray(grid, dtype=float)
    if grid.ndim != 2 or grid.shape[1] != 2:
        raise ValueError(f"grid must have shape (G, 2), got {grid.shape}")
    on_grid = [e for e in events if e.grid_index >= 0]
    if on_grid and not np.allclose([e.center for e in on_grid],
                                   grid[[e.grid_index for e in on_grid]]):
        raise ValueError("events: an event's centre is not the grid position of its grid_index")
    if not threshold > 0:
        raise ValueError(f"threshold must be > 0, got {threshold}")
    if not rigid_tol >= 0:
        raise ValueError(f"rigid_tol must be >= 0, got {rigid_tol}")
    return m0


def _certain_failure(target_reach, body_arm: Arm, threshold) -> str | None:
    """Why a target at ``target_reach`` from the base cannot be compensated
    whatever the search does (None: it may be)."""
    if body_arm.is_paper:
        reach = float(sum(arm.SEGMENT_LENGTHS))
        if target_reach > reach + threshold:
            return NOT_CONVERGED
        if target_reach < 1.0 - threshold:
            return SPLIT_POINT_OF_VIEW
        return None
    if target_reach > body_arm.reach + threshold or target_reach < body_arm.inner_reach - threshold:
        return NOT_CONVERGED
    return None


def is_split(body_arm: Arm, pose: np.ndarray) -> bool:
    """Whether the POV of ``pose`` is one the paper strategy drops: a 1-D
    fibre in two pieces (the paper arm: ``|tip| < 1``, literally)."""
    if body_arm.is_paper:
        return bool(np.hypot(pose[0], pose[1]) < 1.0)
    return body_arm.pov_dim == 1 and bool(fibre_is_split(body_arm, pose))


def in_working_region(body_arm: Arm, target: np.ndarray) -> bool:
    """Ground truth: the target pose is reachable with a POV that is kept
    (the paper arm: ``1 <= |tip| <= 3``)."""
    if body_arm.is_paper:
        return bool(1.0 <= np.hypot(target[0], target[1]) <= 3.0)
    return bool(body_arm.reachable(target[:2], float(target[2]))) and not is_split(body_arm,
                                                                                   target)


@dataclass
class _Tally:
    """``explore_paper``'s running outcome: the compensating states so far
    (with their event, true pose and grid index), the failures by reason,
    the state changes met and compensated, the missed ring positions and the
    time spent in Nelder-Mead."""

    states: list
    event_ids: list
    poses: list
    grid_ids: list
    body_arm: Arm
    threshold: float
    options: dict
    failures: dict = field(default_factory=lambda: {NOT_CONVERGED: 0, SPLIT_POINT_OF_VIEW: 0,
                                                    STATE_CHANGE: 0})
    state_changes: int = 0
    state_changes_compensated: int = 0
    missed_in_ring: list = field(default_factory=list)
    compensation_time: float = 0.0
    n_calls: int = 0

    def follow(self, target, event, skip_certain_failures) -> bool:
        """Compensate the translation to ``target`` from the current state;
        True (and the state recorded) on success."""
        target_reach = np.hypot(target[0], target[1])
        certain = _certain_failure(target_reach, self.body_arm, self.threshold)
        if skip_certain_failures and certain is not None:
            self.failures[certain] += 1
            return False
        candidate, pose, success = self.compensate(self.states[-1], target, event)
        if success:
            self.states.append(candidate)
            self.event_ids.append(event.index)
            self.poses.append(pose)
            self.grid_ids.append(event.grid_index)
        return success

    def compensate(self, motor, target, event):
        """Nelder-Mead from ``motor`` toward ``target``; a solution whose POV
        is split counts as a failure. Returns ``(candidate, its pose,
        success)``."""
        t0 = time.perf_counter()
        candidate, _, success = compensate_pose(motor, target, threshold=self.threshold,
                                                body_arm=self.body_arm, **self.options)
        self.compensation_time += time.perf_counter() - t0
        self.n_calls += 1
        pose = self.body_arm.forward(candidate)
        if success and is_split(self.body_arm, pose):
            # The kernel walk traces only one of the two loops of such a POV
            # (points_of_view flags it "split" from its winding; tests check
            # both criteria agree), so the paper ignores these positions.
            self.failures[SPLIT_POINT_OF_VIEW] += 1
            success = False
        elif not success:
            self.failures[NOT_CONVERGED] += 1
            if in_working_region(self.body_arm, target):
                self.missed_in_ring.append(event.grid_index)
        return candidate, pose, success

    def result(self, n_events: int, total: float) -> ExplorationResult:
        states = self.states
        return ExplorationResult(
            motor_states=np.asarray(states), events_index=np.asarray(self.event_ids),
            true_poses=np.asarray(self.poses), grid_index=np.asarray(self.grid_ids),
            events=n_events, state_changes=int(self.state_changes),
            compensated=len(states) - 1,
            state_changes_compensated=int(self.state_changes_compensated),
            failures_by_reason=self.failures,
            missed_in_ring=np.asarray(self.missed_in_ring, dtype=int),
            timings_s={"compensation": self.compensation_time, "total": total,
                       "compensation_ms_per_call":
                           1e3 * self.compensation_time / max(self.n_calls, 1)})
