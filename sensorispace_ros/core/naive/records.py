"""What the naive agent produces, as plain data: one ``Reaction`` per
``start``/``react`` call with its ``CompensationRecord``s, and the whole run's
``NaiveAgentRecords`` (what the evaluator reads, offline or from the graph).
"""
from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields

import numpy as np


EQUALITY_PASS = "equality_pass"
# Stages the agent counts its queries in (queries_by_stage, calls_by_stage,
# seconds_by_stage); fixed so offline and graph runs report the same keys.
STAGES = ("pov", "sweep", "rank", "compensation", "rest", EQUALITY_PASS)


@dataclass
class CompensationRecord:
    """One accepted compensation: the anchor recorded at the agent's event
    ``anchor_event`` with the arm resting at ``anchor_motor_state`` was
    compensated at event ``event`` by ``motor_state``, which belongs to POV
    ``pov`` (-1 when its POV could not be sampled whole, e.g. split).
    ``searched``: found by LM (False: a known POV matched the anchor)."""

    event: int
    anchor_event: int
    anchor_motor_state: np.ndarray
    motor_state: np.ndarray
    pov: int
    searched: bool


@dataclass
class Reaction:
    """What one ``start``/``react`` call did.

    ``rest_motor_state`` where the arm rests now (the last command sent);
    ``new_pov_ids`` and ``new_povs`` ``(n, N, M)`` the POVs it added;
    ``compensations`` the accepted compensations; ``equality_rows``
    ``(k, 3)`` the equality-set rows it found, columns (set id, POV from,
    POV to), set ids global; ``queries``/``calls`` it spent.
    """

    event: int
    compensated: bool
    rest_motor_state: np.ndarray
    new_pov_ids: np.ndarray
    new_povs: np.ndarray
    compensations: list = field(default_factory=list)
    equality_rows: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=int))
    queries: int = 0
    calls: int = 0


@dataclass
class NaiveAgentRecords:
    """What a naive run's agent produced, as plain data (never ground truth).

    Offline it comes from the ``NaiveAgent`` object (``from_agent``); in the
    ROS graph from the agent's topics (``/agent/points_of_view``,
    ``/agent/pov_records``, ``/agent/compensation_records``,
    ``/agent/compensations``, ``/agent/done``, ``/agent/stage_counters``),
    so both runs are evaluated by the same ``evaluate_naive_records``; a
    graph run without a bag uses the copy the agent node writes at the end
    (``to_arrays`` / ``from_arrays``). It lives with the agent, not with the
    evaluator, because the agent node builds it and must not import the
    evaluator's module (the simulator and the forward model live there).

    ``povs`` ``(P, N, M)``; ``pov_events`` / ``pov_queries`` ``(P,)`` the
    agent's event that found each POV and its walk queries; the
    ``compensation_*`` columns ``(C,)`` / ``(C, M)`` are the accepted
    ``CompensationRecord`` fields; ``compensation_queries`` the rows of all
    compensated events except their POV walks (summed over the
    ``compensated`` events); ``queries_by_stage`` / ``calls_by_stage``
    stage -> count (stages of ``STAGES``); ``pose_rank``, ``pov_dim``,
    ``rank_gap``, ``sensory_gain``, ``fd_noise_floor``, ``rank_votes``,
    ``rank_probes``, ``noise_estimate``, ``fd_step`` and ``noise_quantum``
    the agent's measure of its body (``STRUCTURE_FIELDS``; ``pose_rank`` -1
    before ``start``); ``ends_between_loops`` and ``ends_off_manifold`` the
    search ends it refused under noise, all and those off its loops'
    manifold (``SEARCH_FIELDS``, ``core.naive.known_loops``); ``povs_relaxed``
    the POVs it moved at the end (``core.naive.pov_relaxation``).
    """

    povs: np.ndarray
    pov_events: np.ndarray
    pov_queries: np.ndarray
    compensation_event: np.ndarray
    compensation_anchor_event: np.ndarray
    compensation_motor_state: np.ndarray
    compensation_anchor_motor_state: np.ndarray
    compensation_searched: np.ndarray
    pairs: np.ndarray
    set_ids: np.ndarray
    compensated: int
    compensation_queries: int
    queries_total: int
    calls_total: int
    queries_by_stage: dict
    calls_by_stage: dict
    pose_rank: int = -1
    pov_dim: int = -1
    rank_gap: float = 0.0
    sensory_gain: float = 0.0
    fd_noise_floor: float = 0.0
    rank_votes: int = 0
    rank_probes: int = 0
    noise_estimate: float = 0.0
    fd_step: float = 0.0
    noise_quantum: float = 0.0
    ends_between_loops: int = 0
    ends_off_manifold: int = 0
    povs_relaxed: int = 0

    @classmethod
    def from_agent(cls, agent) -> "NaiveAgentRecords":
        """The records of ``agent`` (a ``core.naive.agent.NaiveAgent``)."""
        records = agent.compensations
        n_motors = agent.n_motors
        pairs, set_ids = agent.equality_sets()
        return cls(
            povs=agent.points_of_view,
            pov_events=np.asarray(agent.pov_events, dtype=np.int64),
            pov_queries=np.asarray(agent.pov_queries, dtype=np.int64),
            compensation_event=np.asarray([r.event for r in records], dtype=np.int64),
            compensation_anchor_event=np.asarray([r.anchor_event for r in records], dtype=np.int64),
            compensation_motor_state=np.asarray([r.motor_state for r in records],
                                                dtype=float).reshape(-1, n_motors),
            compensation_anchor_motor_state=np.asarray(
                [r.anchor_motor_state for r in records], dtype=float).reshape(-1, n_motors),
            compensation_searched=np.asarray([r.searched for r in records], dtype=bool),
            pairs=np.asarray(pairs, dtype=np.int64).reshape(-1, 2),
            set_ids=np.asarray(set_ids, dtype=np.int64),
            compensated=int(agent.compensated),
            compensation_queries=int(sum(agent.compensation_queries)),
            queries_total=int(agent.queries_total), calls_total=int(agent.calls_total),
            queries_by_stage=agent.queries_by_stage, calls_by_stage=agent.calls_by_stage,
            povs_relaxed=int(getattr(agent, "povs_relaxed", 0)),
            **structure_fields(agent), **search_fields(agent))

    def to_arrays(self) -> dict:
        """Flat ``{name: array}`` (``np.savez``); stage counts as
        ``queries_by_stage.<stage>``, ``calls_by_stage.<stage>``."""
        arrays = {}
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, dict):
                arrays.update({f"{item.name}.{stage}": np.int64(count)
                               for stage, count in value.items()})
            else:
                arrays[item.name] = np.asarray(value)
        return arrays

    @classmethod
    def from_arrays(cls, arrays) -> "NaiveAgentRecords":
        """Inverse of ``to_arrays``."""
        values = {}
        for item in fields(cls):        # item.type: the annotation's text (postponed)
            if item.type == "dict":
                prefix = f"{item.name}."
                values[item.name] = {key[len(prefix):]: int(arrays[key]) for key in arrays
                                     if key.startswith(prefix)}
            elif item.name not in arrays and item.default is not MISSING:
                continue                # written before the field existed: its default
            elif item.type == "int":
                values[item.name] = int(arrays[item.name])
            elif item.type == "float":
                values[item.name] = float(arrays[item.name])
            else:
                values[item.name] = np.asarray(arrays[item.name])
        return cls(**values)


# The agent's measure of its body, as its records and metrics (naive.<field>) name it.
STRUCTURE_FIELDS = ("pose_rank", "pov_dim", "rank_gap", "sensory_gain", "fd_noise_floor",
                    "rank_votes", "rank_probes", "noise_estimate", "fd_step", "noise_quantum")


# The search ends the agent refused (``core.naive.known_loops``), as its
# records and metrics (naive.<field>) name them.
SEARCH_FIELDS = ("ends_between_loops", "ends_off_manifold")


def search_fields(agent) -> dict:
    """``SEARCH_FIELDS`` of an agent (0 for an agent that has none)."""
    return {name: int(getattr(agent, name, 0)) for name in SEARCH_FIELDS}


def structure_fields(agent) -> dict:
    """``STRUCTURE_FIELDS`` of a started agent (else none: the records' defaults)."""
    structure = agent.structure
    if structure is None:
        return {}
    measured = structure.metrics()
    return {name: measured[f"naive.{name}"] for name in STRUCTURE_FIELDS}
