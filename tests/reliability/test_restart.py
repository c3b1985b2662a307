"""kill -9 mid-run, then restart (issue #7): each of the five nodes once.

For each victim the smoke graph runs as five processes (localhost discovery,
a free domain id, every node with ``graph.checkpoint_dir``); once the agent has
settled change 60 (of 284) the victim gets SIGKILL by PID and is started again
with the same command line. Asserted:

- the run completes (the representation exits 0) and its result (POVs,
  equality rows, embeddings, the agent's counters) equals the undisturbed
  in-process run's (``single_host_result``);
- the bag, closed by SIGTERM at the end (a restarted recorder merges the part
  it recovered from its predecessor), loses nothing recorded before the kill.
  Precisely: when another node is the victim, the recorder lived through the
  run and the bag holds every /agent/settled value 0..285 and every
  /environment/event change 1..284. When the recorder is the victim, the bag
  holds every /agent/settled value the test's own subscriber received more
  than RECORDER_MARGIN_S (0.2 s) before it sent SIGKILL, and the event of each
  of those changes (messages sent while no recorder ran are not in it; the
  analysis takes those events from the seeded schedule).

How each node resumes is in the README ("Node restarts").
"""
from __future__ import annotations

import pytest

from .node_processes import NODES, assert_same_result, load_result
from .restart_nodes import restart_run

pytestmark = [pytest.mark.graph, pytest.mark.slow]


@pytest.mark.timeout(240)
@pytest.mark.parametrize("victim", NODES)
def test_node_killed_and_restarted_mid_run_gives_the_same_result(victim, tmp_path,
                                                                 single_host_result):
    outcome = restart_run(victim, tmp_path, kill_at=60, stall_s=150, reference=None)
    assert outcome.get("settled_at_kill", 10**6) < 200, str(outcome)     # killed mid-run
    assert outcome["state"] == "completed", str(outcome)
    assert_same_result(load_result(tmp_path / "results"), single_host_result)
    assert outcome["bag"] == {"settled_missing": [], "events_missing": [], "parts_left": []}, \
        str(outcome)
    assert outcome["bag_expected_settled"] >= (50 if victim == "recorder" else 285), str(outcome)
