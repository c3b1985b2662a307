"""The graph's protocol facts, without ROS: what nodes, the recorder, the
analysis of a bag and the evaluator agree on.

Frame ids (msg_schemas/topics.yaml): ``change/<k>``, ``end/<k>``,
``cmd/<n>``, ``next/<k>``, ``hold/<n>``, ``equality/<k>``, ``withdrawn/<k>``,
and their parser; the code of each change kind on
``/environment/event``; the files nodes write into the run's results
directory. Plain Python: ``recording`` and ``evaluation`` read it without
rclpy.
"""
from __future__ import annotations

import time
from pathlib import Path

from sensorispace_ros.core.world import REDISTRIBUTION, TRANSLATION

FRAME_KINDS = ("change", "end", "cmd", "next", "hold", "equality", "withdrawn")
# /agent/compensations: a reaction's rows (change/<k>), then, once the run is
# over, the sets the agent's lattice implies (end/<k>) and the rows published
# earlier that the lattice's trimming withdraws (withdrawn/<k>).
EQUALITY_ROW_KINDS = ("change", "end", "withdrawn")
WITHDRAWN = "withdrawn"
# Numbers count changes and commands and travel as int64/uint64 elsewhere.
MAX_FRAME_NUMBER = 2 ** 63 - 1

# /environment/event's ``kind`` column.
KIND_CODES = {TRANSLATION: 0, REDISTRIBUTION: 1}
KIND_OF_CODE = {code: kind for kind, code in KIND_CODES.items()}

# Files in graph.results_dir: the representation node's arrays, the agent's records.
RESULT_FILE = "representation.npz"
AGENT_RECORDS_FILE = "agent_records.npz"
# In graph.results_dir: the run's own directory, named by the time the agent
# ended the run (the stamp of /agent/done, which the agent and the
# representation both have), so that a second run does not overwrite a first.
RUN_PLACEHOLDER = "{run}"
# Files in graph.checkpoint_dir (state/): the agent's snapshot and journal, the
# environment's progress record (the launcher polls it), the body's row clock
# (the launcher polls it on that clock) and its ground truth of time, appended
# as it answers (a restarted body reads it back) and written whole when a run
# on its own clock is over (the evaluator reads it). The launcher's
# checkpoint directory is CHECKPOINTS in the run's directory.
SNAPSHOT_FILE = "agent.snapshot"
JOURNAL_FILE = "agent.journal"
PROGRESS_FILE = "environment.json"
BODY_CLOCK_FILE = "body.clock"
BODY_TRUTH_FILE = "body.truth.npz"
BODY_TRUTH_LOG_FILE = "body.truth.log"
CHECKPOINTS = "checkpoints"


def frame(kind: str, number: int) -> str:
    """Protocol frame id: ``change/<k>``, ``end/<k>``, ``cmd/<n>``, ``next/<k>`` (topics.yaml)."""
    return f"{kind}/{int(number)}"


def parse_frame(frame_id: str) -> tuple[str, int] | None:
    """``(kind, number)`` of a protocol frame id, None for anything else."""
    kind, _, number = frame_id.partition("/")
    # ASCII digits only: str.isdigit() is also true for "²" (int() raises) and
    # for "٣" (int() reads 3).
    if kind not in FRAME_KINDS or not (number.isascii() and number.isdigit()):
        return None
    # A longer number is no frame id (a fuzzed "cmd/" + 400 nines); the length
    # goes first: int() raises on a string of more than 4,300 digits.
    if len(number) > 19 or int(number) > MAX_FRAME_NUMBER:
        return None
    return kind, int(number)


def run_directory(results_dir: str, end_stamp_ns: int) -> Path:
    """``graph.results_dir`` with ``{run}`` replaced by the run's name:
    ``run-<UTC date>-<time>-<ms>`` of the end's stamp; a path without
    ``{run}`` is the run directory itself."""
    seconds, ns = divmod(int(end_stamp_ns), 1_000_000_000)
    name = time.strftime("run-%Y%m%d-%H%M%S", time.gmtime(seconds)) + f"-{ns // 1_000_000:03d}"
    return Path(results_dir.replace(RUN_PLACEHOLDER, name))
