"""``sensorispace analyze BAG --out DIR``: a run's representation and numbers from its bag alone.

What the bag gives (see bags.py, nodes/recorder.py):

- configuration and seed: the first ``/session/config`` message (the ROS
  params file every node of the run was started with);
- the agent's data: ``/agent/points_of_view`` and ``/agent/compensations``,
  assembled exactly as the representation node assembles them (same
  function; a message re-sent with the same frame id counts once);
- ground truth, joined here as the evaluator: the sensor position of each
  point of view is looked up in the recorded ``/body/sensor_pose`` rows (the
  row answering the motor command equal to the POV's first sample); a POV
  whose first sample was never commanded (resampled) gets ``core.arm.forward``
  of it, the same model the body uses. ``analysis.true_positions`` says how
  many came from which. The object position of each change comes from
  ``/environment/event``.

Then ``pipeline.build_representation`` + ``pipeline.evaluate`` and the same
``metrics.json`` / figures as ``pipeline.reproduce``.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from . import bags

POVS, ROWS, DONE = "/agent/points_of_view", "/agent/compensations", "/agent/done"
EVENT, COMMAND, POSE = "/environment/event", "/body/motor_command", "/body/sensor_pose"


def config_from_bag(bag_dir) -> dict:
    """The run's validated configuration, from its /session/config message."""
    from . import config

    text = bags.read_session_config(bag_dir)
    with tempfile.NamedTemporaryFile("w", suffix=".yaml") as handle:
        handle.write(text)
        handle.flush()
        try:
            return config.load_config(handle.name)
        except config.ConfigError as exc:
            raise bags.BagError(f"bag {bag_dir}: its {bags.SESSION_CONFIG_TOPIC} is not a valid "
                                f"configuration: {' '.join(str(exc).split())}") from None


def _tables(bag_dir, topic: str, kinds=("change",)) -> dict[str, np.ndarray]:
    """frame id -> decoded table for every message of ``topic`` (last copy of a re-send)."""
    from . import contracts, messages
    from .nodes import parse_frame

    columns = contracts.contract(topic).columns
    tables = {}
    for _, _, _, msg in bags.read_bag_messages(bag_dir, [topic]):
        parsed = parse_frame(msg.header.frame_id)
        if parsed is None or parsed[0] not in kinds:
            continue
        try:
            tables[msg.header.frame_id] = messages.cloud_to_table(msg, columns).copy()
        except messages.MessageError as exc:
            raise bags.BagError(f"bag {bag_dir}: a {topic} message does not decode: {exc}") from None
    return tables


def agent_data(bag_dir) -> dict:
    """POV ids, POV motor samples, equality pairs (POV positions) and set ids, as the
    representation node builds them, plus the change each POV was published for."""
    from . import contracts, messages
    from .nodes.representation import assemble_points_of_view

    pov_tables = _tables(bag_dir, POVS)
    row_tables = _tables(bag_dir, ROWS)
    if not pov_tables:
        raise bags.BagError(f"bag {bag_dir} holds no {POVS} message: nothing to analyse")
    ids, povs = assemble_points_of_view(list(pov_tables.values()))
    rows = (np.concatenate(list(row_tables.values())) if row_tables
            else np.zeros(0, dtype=messages.record_dtype(contracts.contract(ROWS).columns)))
    pairs = np.stack([np.searchsorted(ids, rows["pov_from"]),
                      np.searchsorted(ids, rows["pov_to"])], axis=-1).astype(np.int64)
    change_of_pov = {}
    for frame_id, table in pov_tables.items():
        for pov in np.unique(table["pov"]):
            change_of_pov.setdefault(int(pov), frame_id)
    return {"ids": ids, "povs": povs, "pairs": pairs.reshape(-1, 2),
            "set_ids": rows["set"].astype(np.int64),
            "pov_frames": [change_of_pov[int(i)] for i in ids]}


def agent_totals(bag_dir) -> dict | None:
    done = _tables(bag_dir, DONE, kinds=("end",))
    if not done:
        return None
    table = next(iter(done.values()))
    return {name: int(table[name][0]) for name in table.dtype.names}


def true_poses(bag_dir, povs: np.ndarray) -> tuple[np.ndarray, int]:
    """Sensor pose (x, y, alpha) of each POV's first sample: recorded where that motor
    state was commanded, ``arm.forward`` otherwise. Returns (poses, number recorded)."""
    from . import contracts, messages
    from .core import arm

    first = np.ascontiguousarray(povs[:, 0], dtype="<f8")
    wanted = {row.tobytes(): k for k, row in enumerate(first)}
    poses = np.asarray(arm.forward(first), dtype=float).reshape(-1, 3)
    found = np.zeros(len(first), dtype=bool)
    info = bags.bag_info(bag_dir)
    if info.counts.get(COMMAND) and info.counts.get(POSE):
        command_columns = contracts.contract(COMMAND).columns
        pose_columns = contracts.contract(POSE).columns
        commands = {}
        for topic, _, _, msg in bags.read_bag_messages(bag_dir, [COMMAND, POSE]):
            if topic == COMMAND:
                commands[msg.header.frame_id] = messages.cloud_to_matrix(msg, command_columns)
                continue
            motor = commands.get(msg.header.frame_id)
            if motor is None:
                continue
            pose = messages.cloud_to_matrix(msg, pose_columns)
            if len(pose) != len(motor):
                continue
            for row, p in zip(np.ascontiguousarray(motor, dtype="<f8"), pose):
                k = wanted.get(row.tobytes())
                if k is not None and not found[k]:
                    poses[k], found[k] = p, True
    return poses, int(found.sum())


def events(bag_dir) -> dict[str, np.ndarray]:
    """frame id ("change/<k>") -> the /environment/event row of that change."""
    return {frame: table[0] for frame, table in _tables(bag_dir, EVENT).items() if len(table)}


def analyze_bag(bag_dir, out_dir, cfg: dict | None = None, progress=None) -> dict:
    """Rebuild and evaluate the run recorded in ``bag_dir``; write ``out_dir/metrics.json``,
    ``arrays.npz`` and figures (``pipeline.evaluate_graph_run``, as for a live graph run).
    ``cfg`` replaces the configuration stored in the bag. Returns the nested metrics."""
    from . import config, contracts, pipeline

    started = time.perf_counter()
    bag_dir, out_dir = Path(bag_dir), Path(out_dir)
    bags.check_contract(bag_dir, {n: c.type_name for n, c in contracts.load_contracts().items()})
    cfg = config_from_bag(bag_dir) if cfg is None else config.validate_config(cfg)
    seed = int(cfg["seed"])

    data = agent_data(bag_dir)
    povs, pairs, set_ids = data["povs"], data["pairs"], data["set_ids"]
    poses, recorded = true_poses(bag_dir, povs)
    change_events = events(bag_dir)
    totals = agent_totals(bag_dir)

    representation = pipeline.build_representation(povs, pairs, set_ids, cfg, seed, progress)
    produced = pipeline.StrategyOutput(povs=povs, pairs=pairs, set_ids=set_ids,
                                       true_positions=poses[:, :2].copy(), metrics={}, arrays={},
                                       timings_s={})
    arrays = pipeline.run_arrays(produced, representation, cfg, seed)
    arrays.update({"true_poses": poses, "motor_states": povs[:, 0], "pov_ids": data["ids"]})
    # grid position of the object for the change each POV answered: recorded
    # (/environment/event) where there is one, else inferred from the tip
    # displacement (the initial POV answers no event)
    inferred = pipeline.ground_truth_from_motor(povs, cfg)["grid_index"]
    arrays["grid_index"] = np.array(
        [int(change_events[f]["grid_index"]) if f in change_events else int(g)
         for f, g in zip(data["pov_frames"], inferred)], dtype=int)
    counters = {
        "pov.max_pose_drift": pipeline._pose_drift(povs, poses),
        "exploration.changes": int(len(change_events)),
        "exploration.redistributions": int(sum(int(e["kind"]) == 1
                                               for e in change_events.values())),
        "analysis.bag": str(bag_dir),
        "analysis.true_positions": f"{recorded} of {len(povs)} from recorded /body/sensor_pose, "
                                   f"{len(povs) - recorded} from core.arm.forward",
        "analysis.complete": totals is not None
        and (totals["points_of_view"], totals["compensation_rows"]) == (len(povs), len(pairs)),
        **{f"timings_s.{key}": value for key, value in representation.timings_s.items()},
    }
    for name, value in (totals or {}).items():
        # the agent's own counters (/agent/done); "compensated" is the offline key too
        counters["exploration.compensated" if name == "compensated" else f"agent.{name}"] = value
    counters["timings_s.total"] = time.perf_counter() - started
    return pipeline.evaluate_graph_run(arrays, cfg, out_dir, metrics=counters, strategy="naive",
                                       progress=progress)
