"""``sensorispace analyze BAG --out DIR``: a run's representation and numbers from its bag alone.

What the bag gives (see recording.bag_format, nodes/recorder.py):

- configuration and seed: the first ``/session/config`` message (the ROS
  params file every node of the run was started with);
- the body description: the first well-formed ``/body/description``
  message, which sizes the motor columns and gives their unit (the
  Hausdorff metric takes angles, ``BodyDescription.to_radians``); a bag
  recorded before bodies described themselves has none, and the configured
  arm and retina stand in for it;
- the agent's data: ``/agent/points_of_view`` and ``/agent/compensations``,
  assembled exactly as the representation node assembles them (same
  functions; a message re-sent with the same frame id counts once; POVs
  moved at the end of the run, ``end/<k>``, replace their samples; rows
  ``withdrawn/<k>`` names leave);
- ground truth, joined here as the evaluator: the sensor position of each
  point of view is looked up in the recorded ``/body/sensor_pose`` rows (the
  row answering the motor command equal to the POV's first sample); a POV
  whose first sample was never commanded (resampled) gets the configured
  arm's forward model of it (``core.arm.Arm``), the same model the body uses. ``analysis.true_positions`` says how
  many came from which. The object position of each change comes from
  ``/environment/event``;
- the naive run's ground-truth metrics (``exploration.*``, ``naive.*``):
  the agent's own records (``/agent/pov_records``,
  ``/agent/compensation_records``, ``/agent/stage_counters``, ``/agent/done``)
  joined with the recorded changes (centre, kind, grid position; light
  layout version = redistributions so far) and the world rebuilt from the
  bag's configuration (initial centre, the paper strategy's compensated
  positions for the coverage denominator) by the offline evaluator itself,
  ``evaluation.naive.evaluate_naive_records``.

Duplicates: a restarted node re-sends (the environment its current
change, the agent a reaction, the body passive sensations of re-delivered
lights, a restarted recorder receives every TRANSIENT_LOCAL history again), so
every topic is read with "the first message of a frame id wins". A change
whose volatile ``/environment/event`` was sent while the recorder was down is
taken from the world rebuilt from the bag's configuration (the environment
plays the same seeded schedule); ``analysis.events`` says how many.

Then ``offline.representation.build_representation`` and the offline
evaluator (``evaluation.runs.evaluate_graph_run``): the same
``metrics.json`` / figures as ``reproduce``.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from sensorispace_ros import config, contracts, messages
from sensorispace_ros.core.arm import Arm
from sensorispace_ros.core.naive.records import (SEARCH_FIELDS, STAGES, STRUCTURE_FIELDS,
                                                 NaiveAgentRecords)
from sensorispace_ros.core.world import REDISTRIBUTION
from sensorispace_ros.evaluation.graph_clock import clocked_numbers
from sensorispace_ros.evaluation.ground_truth import RunTruth, ground_truth_from_motor
from sensorispace_ros.evaluation.naive import naive_metrics
from sensorispace_ros.evaluation.run_files import run_arrays
from sensorispace_ros.evaluation.runs import evaluate_graph_run
from sensorispace_ros.offline.pov_assembly import (MIN_POVS, assemble_points_of_view,
                                                   equality_pairs, net_equality_rows)
from sensorispace_ros.offline.representation import build_representation
from sensorispace_ros.offline.strategies import StrategyOutput, pose_drift
from sensorispace_ros.protocol import CHECKPOINTS, EQUALITY_ROW_KINDS, KIND_OF_CODE, parse_frame
from sensorispace_ros.recording.bag_format import SESSION_CONFIG_TOPIC, BagError
from sensorispace_ros.recording.bag_reader import (
    bag_info,
    check_contract,
    infos_kept,
    read_bag_messages,
    read_session_config,
)
from sensorispace_ros.recording.completeness import DONE, POVS, ROWS
POV_RECORDS, COMPENSATION_RECORDS = "/agent/pov_records", "/agent/compensation_records"
STAGE_COUNTERS = "/agent/stage_counters"
EVENT, COMMAND, POSE = "/environment/event", "/body/motor_command", "/body/sensor_pose"
DESCRIPTION = "/body/description"


def config_from_bag(bag_dir) -> dict:
    """The run's validated configuration, from its /session/config message."""
    text = read_session_config(bag_dir)
    with tempfile.NamedTemporaryFile("w", suffix=".yaml") as handle:
        handle.write(text)
        handle.flush()
        try:
            return config.load_config(handle.name)
        except config.ConfigError as exc:
            raise BagError(f"bag {bag_dir}: its {SESSION_CONFIG_TOPIC} is not a valid "
                           f"configuration: {' '.join(str(exc).split())}") from None


def body_description(bag_dir, cfg: dict | None = None):
    """The body description of the run: the bag's first well-formed
    /body/description; without one (a bag recorded before it existed), the
    configured arm and retina (``cfg``, or the bag's configuration)."""
    if DESCRIPTION in bag_info(bag_dir).topics:
        for _, _, _, msg in read_bag_messages(bag_dir, [DESCRIPTION]):
            try:
                return messages.description_from_msg(msg)
            except messages.MessageError:
                continue
    cfg = config_from_bag(bag_dir) if cfg is None else cfg
    return Arm.from_config(cfg["arm"]).description(int(cfg["world"]["retina"]["receptors"]))


def _tables(bag_dir, topic: str, kinds=("change",), description=None, later=()
            ) -> dict[str, np.ndarray]:
    """frame id -> decoded table of the first message of ``topic`` with that frame id
    (a re-send after a restart is a duplicate, see the module docstring);
    ``description`` sizes a topic sized by the body; ``later``: trailing
    columns a bag recorded before they existed lacks (``decoded_table``)."""
    columns = contracts.contract(topic).columns_for(description)
    tables = {}
    for _, _, _, msg in read_bag_messages(bag_dir, [topic]):
        parsed = parse_frame(msg.header.frame_id)
        if parsed is None or parsed[0] not in kinds or msg.header.frame_id in tables:
            continue
        try:
            tables[msg.header.frame_id] = decoded_table(msg, columns, later)
        except messages.MessageError as exc:
            raise BagError(f"bag {bag_dir}: a {topic} message does not decode: {exc}") from None
    return tables


def decoded_table(msg, columns: dict, later=()) -> np.ndarray:
    """``msg`` as a table of ``columns``, or, where it has none of the
    columns ``later`` (an older recording), of the others."""
    try:
        return messages.cloud_to_table(msg, columns).copy()
    except messages.MessageError:
        if not later or {field.name for field in msg.fields} & set(later):
            raise
    earlier = {name: kind for name, kind in columns.items() if name not in later}
    return messages.cloud_to_table(msg, earlier).copy()


def agent_data(bag_dir, description=None) -> dict:
    """POV ids, POV motor samples, equality pairs (POV positions) and set ids, as the
    representation node builds them, plus the change each POV was published for
    and the equality rows recorded (``rows_held``, withdrawn ones too, as
    ``/agent/done`` counts them).
    ``description``: the body's (``body_description`` by default)."""
    description = body_description(bag_dir) if description is None else description
    pov_tables = _tables(bag_dir, POVS, kinds=("change", "end"), description=description)
    moved = {frame_id: pov_tables.pop(frame_id) for frame_id in list(pov_tables)
             if parse_frame(frame_id)[0] == "end"}
    row_tables = _tables(bag_dir, ROWS, kinds=EQUALITY_ROW_KINDS)
    ids, povs = assemble_points_of_view(list(pov_tables.values()), description.n_motors,
                                        moved=list(moved.values()))
    rows = net_equality_rows(row_tables, messages.record_dtype(contracts.contract(ROWS).columns))
    pairs, set_ids = equality_pairs(ids, rows)
    change_of_pov = {}
    for frame_id, table in pov_tables.items():
        for pov in np.unique(table["pov"]):
            change_of_pov.setdefault(int(pov), frame_id)
    return {"ids": ids, "povs": povs, "pairs": pairs, "set_ids": set_ids,
            "pov_frames": [change_of_pov[int(i)] for i in ids],
            "rows_held": sum(len(table) for table in row_tables.values())}


def agent_totals(bag_dir) -> dict | None:
    done = _tables(bag_dir, DONE, kinds=("end",), later=("moved_povs",))
    if not done:
        return None
    table = next(iter(done.values()))
    return {name: int(table[name][0]) for name in table.dtype.names}


def true_poses(bag_dir, povs: np.ndarray, description=None, body_arm=None
               ) -> tuple[np.ndarray, int]:
    """Sensor pose (x, y, alpha) of each POV's first sample: recorded where that motor
    state was commanded, ``body_arm``'s forward model otherwise (the arm of the bag's
    configuration by default). Returns (poses, number recorded)."""
    description = body_description(bag_dir) if description is None else description
    if body_arm is None:
        body_arm = Arm.from_config(config_from_bag(bag_dir)["arm"])
    first = np.ascontiguousarray(povs[:, 0], dtype="<f8")
    wanted = {row.tobytes(): k for k, row in enumerate(first)}
    poses = np.asarray(body_arm.forward(first), dtype=float).reshape(-1, 3)
    found = np.zeros(len(first), dtype=bool)
    info = bag_info(bag_dir)
    if info.counts.get(COMMAND) and info.counts.get(POSE):
        command_columns = contracts.contract(COMMAND).columns_for(description)
        pose_columns = contracts.contract(POSE).columns
        commands = {}
        # The recorder writes messages of different topics in the order its
        # callbacks ran, not in causal order: a pose may come before its command.
        early_poses = {}
        for topic, _, _, msg in read_bag_messages(bag_dir, [COMMAND, POSE]):
            frame_id = msg.header.frame_id
            if topic == COMMAND:
                if frame_id in commands:
                    continue                   # a re-sent command: the first copy counts
                motor = commands[frame_id] = messages.cloud_to_matrix(msg, command_columns)
                pose = early_poses.pop(frame_id, None)
            else:
                pose = messages.cloud_to_matrix(msg, pose_columns)
                motor = commands.get(frame_id)
                if motor is None:
                    early_poses.setdefault(frame_id, pose)
                    continue
            if pose is None or len(pose) != len(motor):
                continue
            for row, p in zip(np.ascontiguousarray(motor, dtype="<f8"), pose):
                k = wanted.get(row.tobytes())
                if k is not None and not found[k]:
                    poses[k], found[k] = p, True
    return poses, int(found.sum())


def events(bag_dir) -> dict[str, np.ndarray]:
    """frame id ("change/<k>") -> the /environment/event row of that change."""
    return {frame: table[0] for frame, table in _tables(bag_dir, EVENT).items() if len(table)}


def _concatenated(bag_dir, topic: str, description=None) -> np.ndarray:
    present = topic in bag_info(bag_dir).topics
    tables = list(_tables(bag_dir, topic, description=description).values()) if present else []
    columns = contracts.contract(topic).columns_for(description)
    return np.concatenate(tables) if tables else np.zeros(0, dtype=messages.record_dtype(columns))


def naive_records(bag_dir, data: dict, totals: dict | None, description=None):
    """The agent's records of the run (``core.naive.records.NaiveAgentRecords``),
    or None when the bag lacks them (recorded before they were published, or the
    run did not end). ``description``: the body's (``body_description`` by default)."""
    info = bag_info(bag_dir)
    if totals is None or STAGE_COUNTERS not in info.topics or POV_RECORDS not in info.topics:
        return None
    counters = _tables(bag_dir, STAGE_COUNTERS, kinds=("end",), later=SEARCH_FIELDS)
    if not counters:
        return None
    counters = next(iter(counters.values()))
    ids = data["ids"]
    pov_rows = _concatenated(bag_dir, POV_RECORDS)
    _, first = np.unique(pov_rows["pov"], return_index=True)     # a re-send counts once
    pov_rows = pov_rows[first]
    if not np.array_equal(pov_rows["pov"], ids):
        raise BagError(f"bag {bag_dir}: {POV_RECORDS} names POVs {pov_rows['pov'].tolist()}, "
                       f"{POVS} holds {ids.tolist()}")
    description = body_description(bag_dir) if description is None else description
    # one copy of each change's rows
    comp = _concatenated(bag_dir, COMPENSATION_RECORDS, description)
    joints = range(description.n_motors)
    motor = np.stack([comp[f"m{j}"] for j in joints], axis=-1).astype(float)
    anchor = np.stack([comp[f"a{j}"] for j in joints], axis=-1).astype(float)
    return NaiveAgentRecords(
        povs=data["povs"], pov_events=pov_rows["event"].astype(np.int64),
        pov_queries=pov_rows["queries"].astype(np.int64),
        compensation_event=comp["event"].astype(np.int64),
        compensation_anchor_event=comp["anchor_event"].astype(np.int64),
        compensation_motor_state=motor, compensation_anchor_motor_state=anchor,
        compensation_searched=comp["searched"].astype(bool),
        pairs=data["pairs"], set_ids=data["set_ids"], compensated=int(totals["compensated"]),
        compensation_queries=int(counters["compensation_queries"][0]),
        queries_total=int(totals["queries"]), calls_total=int(totals["calls"]),
        povs_relaxed=int(totals.get("moved_povs", 0)),
        queries_by_stage={stage: int(counters[f"queries_{stage}"][0]) for stage in STAGES},
        calls_by_stage={stage: int(counters[f"calls_{stage}"][0]) for stage in STAGES},
        **{name: counters[name][0].item() for name in STRUCTURE_FIELDS + SEARCH_FIELDS
           if name in counters.dtype.names})


def recorded_changes(change_events: dict) -> dict[int, tuple]:
    """change number -> (centre, kind, grid index) of each recorded ``/environment/event``
    (``ground_truth.naive_truth_of_changes``)."""
    changes = {}
    for frame_id, event in change_events.items():
        changes[int(parse_frame(frame_id)[1])] = (
            np.array([event["center_x"], event["center_y"]], dtype=float),
            KIND_OF_CODE[int(event["kind"])], int(event["grid_index"]))
    return changes


def analyze_bag(bag_dir, out_dir, cfg: dict | None = None, progress=None) -> dict:
    """Rebuild and evaluate the run recorded in ``bag_dir``; write ``out_dir/metrics.json``,
    ``arrays.npz`` and figures (``runs.evaluate_graph_run``, as for a live graph run).
    ``cfg`` replaces the configuration stored in the bag. Returns the nested metrics.
    The run's ground truth (``RunTruth``: its world) is built once and handed down."""
    with infos_kept():          # the bag is closed: its topics and counts are read once
        return _analyze_bag(Path(bag_dir), Path(out_dir), cfg, progress, time.perf_counter())


def _analyze_bag(bag_dir: Path, out_dir: Path, cfg: dict | None, progress, started: float
                 ) -> dict:
    check_contract(bag_dir, {n: c.type_name for n, c in contracts.load_contracts().items()})
    cfg = config_from_bag(bag_dir) if cfg is None else config.validate_config(cfg)
    seed = int(cfg["seed"])
    description, body_arm = body_description(bag_dir, cfg), Arm.from_config(cfg["arm"])
    data, totals = agent_data(bag_dir, description), agent_totals(bag_dir)
    if len(data["ids"]) == 0 and totals is None:
        raise BagError(f"bag {bag_dir} holds no {POVS} and no {DONE} message: nothing to analyse")
    if len(data["ids"]) < MIN_POVS:
        return _analyze_too_few(bag_dir, out_dir, cfg, data, totals, description)
    povs, pairs, set_ids = data["povs"], data["pairs"], data["set_ids"]
    poses, recorded = true_poses(bag_dir, povs, description, body_arm)
    change_events = events(bag_dir)
    # The Hausdorff metric's wrap is 2 pi: the POVs as angles (the same bits for rad).
    representation = build_representation(description.to_radians(povs), pairs, set_ids, cfg,
                                           seed, progress)
    produced = StrategyOutput(povs=povs, pairs=pairs, set_ids=set_ids,
                              true_positions=poses[:, :2].copy(), metrics={}, arrays={},
                              timings_s={})
    arrays = run_arrays(produced, representation, cfg, seed)
    arrays.update({"true_poses": poses, "motor_states": povs[:, 0], "pov_ids": data["ids"]})
    from_motor = ground_truth_from_motor(povs, cfg)
    arrays["grid_index"] = _grid_index(data["pov_frames"], change_events, from_motor)
    for key, value in from_motor.items():
        arrays.setdefault(key, value)
    counters = {
        "pov.max_pose_drift": pose_drift(povs, poses, body_arm),
        "analysis.bag": str(bag_dir),
        "analysis.true_positions": f"{recorded} of {len(povs)} from recorded /body/sensor_pose, "
                                   f"{len(povs) - recorded} from core.arm.forward",
        "analysis.complete": totals is not None
        and ((totals["points_of_view"], totals["compensation_rows"])
             == (len(povs), data["rows_held"])),
        **{f"timings_s.{key}": value for key, value in representation.timings_s.items()},
        **{f"agent.{name}": value for name, value in (totals or {}).items()},
    }
    truth = RunTruth(cfg)
    counters.update(_naive_numbers(bag_dir, data, totals, description, truth, poses,
                                   change_events, arrays))
    if cfg["world"]["clock"] != "agent":
        counters.update(clocked_numbers(cfg, out_dir / CHECKPOINTS))
    counters["timings_s.total"] = time.perf_counter() - started
    return evaluate_graph_run(arrays, cfg, out_dir, metrics=counters, strategy="naive",
                              progress=progress, truth=truth)


def _analyze_too_few(bag_dir: Path, out_dir: Path, cfg: dict, data: dict, totals: dict | None,
                     description) -> dict:
    """The run directory of a bag whose agent found too few POVs for a
    representation: its counts and a one-line outcome (``runs.evaluate_graph_run``)."""
    counters = {"analysis.bag": str(bag_dir),
                **{f"agent.{name}": value for name, value in (totals or {}).items()}}
    if totals is not None:
        counters.update({"exploration.compensated": totals["compensated"],
                         "naive.queries_total": totals["queries"]})
    counters["exploration.events"] = int(len(events(bag_dir)))
    arrays = {"povs": data["povs"], "pairs": data["pairs"], "set_ids": data["set_ids"], "pov_ids": data["ids"]}
    return evaluate_graph_run(arrays, cfg, out_dir, metrics=counters, strategy="naive")


def _grid_index(pov_frames: list, change_events: dict, from_motor: dict) -> np.ndarray:
    """Grid position of the object for the change each POV answered: recorded
    (/environment/event) where there is one, else inferred from the tip
    displacement (the initial POV answers no event)."""
    return np.array([int(change_events[f]["grid_index"]) if f in change_events else int(g)
                     for f, g in zip(pov_frames, from_motor["grid_index"])], dtype=int)


def _naive_numbers(bag_dir, data: dict, totals: dict | None, description, truth: RunTruth,
                   poses: np.ndarray, change_events: dict, arrays: dict) -> dict:
    """``naive.*`` and ``exploration.*`` of the run: its records joined with
    ground truth (``naive.naive_metrics``; sets ``arrays["grid_index"]``), or
    the recorded counts when the bag lacks the records."""
    records = naive_records(bag_dir, data, totals, description)
    if records is None:
        counters = {} if totals is None else {"exploration.compensated": totals["compensated"]}
        counters["exploration.events"] = int(len(change_events))
        counters["exploration.state_changes"] = int(sum(
            KIND_OF_CODE.get(int(e["kind"])) == REDISTRIBUTION for e in change_events.values()))
        counters["analysis.naive_records"] = (f"absent (no {STAGE_COUNTERS} / {POV_RECORDS}): "
                                              f"naive.* not evaluated")
        return counters
    if truth.cfg["world"]["clock"] != "agent":
        # Its events are its reactions, not the schedule's changes: ``clocked_numbers``.
        return {}
    try:
        evaluated = naive_metrics(records, truth, totals["changes"], poses,
                                  recorded_changes(change_events))
    except ValueError as exc:
        raise BagError(f"bag {bag_dir}: {exc}") from None
    arrays["grid_index"] = evaluated.grid_index
    n_changes = int(totals["changes"]) - 1
    recorded = sum(f"change/{k}" in change_events for k in range(1, n_changes + 1))
    return {**evaluated.metrics,
            "analysis.events": f"{recorded} of {n_changes} from recorded {EVENT}, "
                               f"{n_changes - recorded} from the seeded schedule",
            "analysis.naive_records": "evaluated by evaluation.naive"}
