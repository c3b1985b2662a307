"""Whether a recording holds the agent's whole run, and the marker that says so.

A recorder started again mid-run gets the agent's POVs and equality rows
from their TRANSIENT_LOCAL history, once its readers have matched the
agent's writers; a recorder restarted late could otherwise close its bag
without some of them. The recorder counts what it holds against
``/agent/done`` (the agent's own totals), as the representation does, and
when both agree writes
``<bag>.complete`` beside the bag directory; the launcher and the test
harness wait for that file (``wait_for_complete_recording``) before they stop
the nodes. The recorder removes the file when it starts and when it closes
the bag.

No ROS imports at module level: the launcher (imported by every
``sensorispace`` command) only needs the marker and the wait.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

POVS, ROWS, DONE = "/agent/points_of_view", "/agent/compensations", "/agent/done"
TOPICS = (POVS, ROWS, DONE)
MARKER_SUFFIX = ".complete"


def marker_path(bag_dir: str | Path) -> Path:
    bag_dir = Path(bag_dir)
    return bag_dir.with_name(bag_dir.name + MARKER_SUFFIX)


class RunCompleteness:
    """POV ids, POVs moved at the end and equality rows held (the first
    message of each frame id, as the representation and the analysis count
    them) against ``/agent/done``."""

    def __init__(self):
        self.totals: dict | None = None
        self.pov_ids: set[int] = set()
        self.moved_ids: set[int] = set()
        self.rows_by_frame: dict[str, int] = {}
        self.complete = False
        self.undecodable = 0

    @property
    def held(self) -> dict:
        return {"points_of_view": len(self.pov_ids),
                "compensation_rows": sum(self.rows_by_frame.values()),
                "moved_povs": len(self.moved_ids)}

    def add(self, topic: str, cdr: bytes) -> bool:
        """Count one recorded message; True when the run has just become complete."""
        if topic not in TOPICS or self.complete:
            return False
        from sensorispace_ros import contracts, messages  # the recorder's process has them loaded
        from sensorispace_ros.protocol import parse_frame
        try:
            cloud = messages.cloud_from_cdr(cdr)
            if topic == POVS:
                # The POV ids only: the motor columns are the body's (any number).
                pov_ids = messages.cloud_column(cloud, "pov", contracts.contract(POVS)
                                                .column_spec["pov"])
            else:
                table = messages.cloud_to_table(cloud, contracts.contract(topic).columns)
        except messages.MessageError:
            self.undecodable += 1        # recorded all the same; it just counts for nothing
            return False
        if topic == POVS:
            moved = (parse_frame(cloud.header.frame_id) or ("",))[0] == "end"
            (self.moved_ids if moved else self.pov_ids).update(int(pov) for pov in pov_ids)
        elif topic == ROWS:
            self.rows_by_frame.setdefault(cloud.header.frame_id, len(table))
        elif len(table) == 1:
            self.totals = {name: int(table[name][0])
                           for name in ("points_of_view", "compensation_rows", "moved_povs")}
        self.complete = self.totals is not None and self.held == self.totals
        return self.complete


def write_marker(bag_dir: str | Path, content: dict) -> Path:
    path = marker_path(bag_dir)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(content))
    tmp.replace(path)
    return path


def remove_marker(bag_dir: str | Path) -> None:
    marker_path(bag_dir).unlink(missing_ok=True)


def wait_for_complete_recording(bag_dir: str | Path, timeout_s: float,
                                alive=lambda: True, poll_s: float = 0.05) -> float | None:
    """Seconds waited until ``<bag>.complete`` exists; None after ``timeout_s``
    or once ``alive()`` (the recorder's process) is false without it."""
    started = time.monotonic()
    path = marker_path(bag_dir)
    while not path.exists():
        if time.monotonic() - started >= timeout_s or not alive():
            return None
        time.sleep(poll_s)
    return time.monotonic() - started
