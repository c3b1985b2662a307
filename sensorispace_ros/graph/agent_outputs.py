"""What the agent node publishes and logs, as plain tables and lines (no rclpy).

Each table is a dict of columns, ready for ``messages.table_to_cloud`` with
the contract's columns of its topic (msg_schemas/topics.yaml): the points of
view of a reaction, their records, the accepted compensations, the equality
rows, the stage counters and the totals of ``/agent/done``. The lines are
what the agent says of its body and of its run.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.records import STAGES as NAIVE_STAGES
from sensorispace_ros.core.naive.records import (STRUCTURE_FIELDS, NaiveAgentRecords,
                                                 search_fields, structure_fields)
from sensorispace_ros import messages
from sensorispace_ros.protocol import AGENT_RECORDS_FILE  # noqa: F401 (the file name nodes write)
from sensorispace_ros.protocol import WITHDRAWN, frame, parse_frame


def reaction_tables(agent, reaction) -> dict[str, dict]:
    """The tables of one ``start``/``react`` by topic; topics with no row are left out."""
    tables = {}
    povs = np.asarray(reaction.new_povs, dtype=float)
    if len(povs):
        ids = np.asarray(reaction.new_pov_ids, dtype=np.int64)
        tables["/agent/points_of_view"] = pov_table(ids, povs)
        tables["/agent/pov_records"] = {
            "pov": ids, "event": np.asarray(agent.pov_events)[ids],
            "queries": np.asarray(agent.pov_queries)[ids]}
    if reaction.compensations:
        records = reaction.compensations
        motor = np.asarray([r.motor_state for r in records], dtype=float)
        anchor = np.asarray([r.anchor_motor_state for r in records], dtype=float)
        tables["/agent/compensation_records"] = {
            "event": [r.event for r in records], "anchor_event": [r.anchor_event for r in records],
            "pov": [r.pov for r in records], "searched": [r.searched for r in records],
            **{f"m{j}": motor[:, j] for j in range(motor.shape[1])},
            **{f"a{j}": anchor[:, j] for j in range(anchor.shape[1])}}
    rows = np.asarray(reaction.equality_rows, dtype=np.int64).reshape(-1, 3)
    if len(rows):
        tables["/agent/compensations"] = equality_table(rows)
    return tables


def pov_table(ids, povs) -> dict:
    """``/agent/points_of_view``'s columns for POVs ``ids`` of samples ``povs`` ``(P, N, M)``."""
    povs = np.asarray(povs, dtype=float)
    n_samples, n_motors = povs.shape[1:]
    return {"pov": np.repeat(np.asarray(ids, dtype=np.int64), n_samples),
            "sample": np.tile(np.arange(n_samples), len(ids)),
            **{f"m{j}": povs[:, :, j].ravel() for j in range(n_motors)}}


def equality_table(rows) -> dict:
    """``/agent/compensations``' columns for rows ``(set id, from, to)`` ``(K, 3)``."""
    return {"set": rows[:, 0], "pov_from": rows[:, 1], "pov_to": rows[:, 2]}


def publish_end_of_run(agent, publish, header) -> int:
    """Once the run is over, publish (``publish(topic, table, header)``) under
    ``header`` (``end/<k>``) the POVs the agent moves onto its lattice
    (``RelaxedPOVs.relax_povs``, their samples now), then the
    ``/agent/compensations`` rows of the sets its lattice implies
    (``ImpliedSets.implied_rows``), then under ``withdrawn/<k>`` the rows
    published earlier that its trimming withdraws (``ImpliedSets.withdrawn_rows``);
    returns how many equality rows."""
    if agent.relax_povs():
        ids = agent.relaxed_ids
        publish("/agent/points_of_view", pov_table(ids, agent.points_of_view[ids]), header)
    _, number = parse_frame(header.frame_id)
    withdrawn_header = messages.make_header(frame(WITHDRAWN, number), messages.stamp_ns(header))
    published = 0
    for rows, rows_header in ((agent.implied_rows(), header),
                              (agent.withdrawn_rows(), withdrawn_header)):
        if len(rows):
            publish("/agent/compensations", equality_table(rows), rows_header)
        published += len(rows)
    return published


def initial_posture(configured, n_motors: int) -> tuple[np.ndarray, str]:
    """The agent's first motor state (proprioception, nothing of the world) and
    what to say of it: ``arm.initial_motor_state`` when it has a value per
    joint of this body (the simulated body starts there), otherwise every
    joint at 0; a degenerate start is replaced by the agent itself
    (``core.naive.start``)."""
    posture = np.asarray(configured, float)
    if posture.shape == (n_motors,):
        return posture, ""
    return np.zeros(n_motors), (f"arm.initial_motor_state has {len(posture)} values for a "
                                f"body of {n_motors} joints: starting with every joint at 0")


def stage_counters(agent) -> tuple[dict, list[str]]:
    """``/agent/stage_counters``' row (0 for a stage never entered, the
    structure measured, else the records' defaults) and the stages the
    agent used that have no column."""
    queries, calls = agent.queries_by_stage, agent.calls_by_stage
    counters = {"compensation_queries": int(sum(agent.compensation_queries))}
    for stage in NAIVE_STAGES:
        counters[f"queries_{stage}"] = queries.get(stage, 0)
        counters[f"calls_{stage}"] = calls.get(stage, 0)
    defaults = {name: getattr(NaiveAgentRecords, name) for name in STRUCTURE_FIELDS}
    counters.update({**defaults, **structure_fields(agent), **search_fields(agent)})
    return counters, sorted((set(queries) | set(calls)) - set(NAIVE_STAGES))


def done_totals(agent, changes: int, n_povs: int, n_rows: int) -> dict:
    """``/agent/done``'s row."""
    return {"changes": changes, "points_of_view": n_povs, "compensation_rows": n_rows,
            "compensated": agent.compensated, "queries": agent.queries_total,
            "calls": agent.calls_total, "moved_povs": getattr(agent, "povs_relaxed", 0)}


def write_records(agent, path) -> None:
    """The agent's own records (``NaiveAgentRecords``: what ``/agent/pov_records``,
    ``/agent/compensation_records`` and ``/agent/stage_counters`` carry) to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **NaiveAgentRecords.from_agent(agent).to_arrays())


def body_measure(agent) -> str:
    """What the agent measured of its body at the start, in one line."""
    structure = agent.structure
    line = (f"measured body: pose rank {structure.pose_rank} of {structure.n_motors} joints "
            f"({structure.votes} of {structure.probes} probe states agree), points of view "
            f"of dimension {structure.pov_dim}, sensory noise {structure.noise:.2g} "
            f"(finite-difference step {structure.fd_step:.2g})")
    choice = getattr(agent, "start_choice", None)
    return line if choice is None else f"{line}; {choice.describe()}"


def account(agent, n_povs: int, n_rows: int, changes: int) -> str:
    """The one-line account of a run: what the agent found."""
    structure = agent.structure
    line = (f"found {n_povs} points of view (dimension {structure.pov_dim}, pose rank "
            f"{structure.pose_rank}), compensated {agent.compensated} of {changes} changes, "
            f"{n_rows} equality rows, {agent.calls_total} sense calls of "
            f"{agent.queries_total} motor states")
    if n_povs < 4:
        line += (": too few points of view for a representation (it needs 4); "
                 "a start that sees the world better, or a body whose sensation pins "
                 "its sensor's pose, may help")
    return line


def transport(body, late_answers: int, stats: dict, slow_reads: int) -> str:
    """How the run's commands and answers travelled (``BodyOverTopics``' counters,
    the checkpoint's), in one line."""
    return (f"transport: {body.requests} commands ({body.ahead_used} sent ahead with a "
            f"settle), {1e3 * body.round_trip_s / max(body.requests, 1):.3f} ms waited for each, "
            f"{body.retransmits} commands re-sent, {late_answers} late answers, "
            f"{body.replayed} answers and {stats['replayed_passives']} passive sensations "
            f"replayed, {stats['snapshots']} snapshots ({stats['snapshot_s']:.2f} s, last "
            f"{stats['snapshot_bytes'] / 1e6:.1f} MB, {stats['ack_timeouts']} acknowledgement "
            f"waits timed out), {slow_reads} sensations not read by the fast path")
