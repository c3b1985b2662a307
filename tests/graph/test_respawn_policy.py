"""The launcher's respawn policy: which dead node is started again, how often."""
from __future__ import annotations

import pytest

from sensorispace_ros.graph.launcher import ASKED_RESTARTS, RespawnPolicy

RESTART = 75


def test_a_node_killed_by_a_signal_is_respawned_up_to_its_limit_per_node():
    policy = RespawnPolicy(2, RESTART)
    first = policy.restart("body", -9)
    assert first.log_name == "body.respawn-1"
    assert first.line(123) == "[launch] body was killed by signal 9; respawned (1/2, pid 123)"
    assert policy.restart("body", -15).log_name == "body.respawn-2"
    assert policy.restart("body", -9) is None                  # past the limit: the run fails
    assert policy.restart("agent", -9).log_name == "agent.respawn-1"   # its own count


def test_a_node_that_asks_is_started_again_even_without_respawn():
    policy = RespawnPolicy(0, RESTART)
    assert policy.restart("body", -9) is None
    for k in range(1, ASKED_RESTARTS + 1):
        restart = policy.restart("body", RESTART)
        assert restart.log_name == f"body.restart-{k}"
        assert restart.line(1).startswith("[launch] body asked to be restarted (exit code 75); "
                                          f"started again ({k}/{ASKED_RESTARTS}")
    assert policy.restart("body", RESTART) is None


@pytest.mark.parametrize("code", [1, 2, 0])
def test_a_node_that_exits_with_another_code_is_never_started_again(code):
    assert RespawnPolicy(3, RESTART).restart("agent", code) is None


def test_a_negative_respawn_count_is_refused():
    with pytest.raises(ValueError, match="respawn must be >= 0, got -1"):
        RespawnPolicy(-1, RESTART)
