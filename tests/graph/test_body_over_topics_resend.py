"""BodyOverTopics re-sends a command only when it is late for its size: after
``command_timeout_s``, or after RESEND_AFTER_ROW_TIMES times the body's time
per row so far times the command's rows (a camera rendering a large cloud is
slow, not lost). Without ROS, on a clock the fake body advances."""
import types

import numpy as np
import pytest

from sensorispace_ros.graph import body_over_topics
from sensorispace_ros.graph.body_over_topics import RESEND_AFTER_ROW_TIMES, BodyOverTopics

ROW_S = 0.01          # the fake body's time to answer one row
TIMEOUT_S = 0.05      # command_timeout_s: shorter than a 100-row answer


class SlowBody:
    """Answers a command ROW_S per row after its publication; drops the
    publications listed in ``lose`` (by their count, from 1)."""

    def __init__(self, lose=()):
        self.now, self.sent, self.lose = 0.0, [], set(lose)
        self.due = None
        self.proxy = None

    def perf_counter(self):
        return self.now

    def publish_command(self, motor_states, frame_id):
        self.sent.append(frame_id)
        if len(self.sent) not in self.lose:
            self.due = (self.now + ROW_S * len(motor_states), frame_id, len(motor_states))

    def spin_once(self, timeout_s):
        self.now += timeout_s
        if self.due is not None and self.now >= self.due[0]:
            _, frame_id, rows = self.due
            self.due = None
            self.proxy.deliver(frame_id, np.zeros((rows, 3)))


@pytest.fixture
def body(monkeypatch):
    body = SlowBody()
    monkeypatch.setattr(body_over_topics, "time", types.SimpleNamespace(
        perf_counter=body.perf_counter))
    body.proxy = BodyOverTopics(body.publish_command, body.spin_once, n_motors=2, n_sensors=3,
                                command_timeout_s=TIMEOUT_S)
    return body


def test_a_large_slow_command_is_waited_for_not_sent_again(body):
    body.proxy.sense(np.zeros((2, 2)))                  # answered within the timeout
    assert 0 < body.proxy.row_s <= TIMEOUT_S / 2 + 1e-12
    big = 100                                           # 1 s to answer, 20 timeouts
    assert RESEND_AFTER_ROW_TIMES * body.proxy.row_s * big > ROW_S * big
    sensed = body.proxy.sense(np.zeros((big, 2)))
    assert sensed.shape == (big, 3)
    assert body.proxy.retransmits == 0 and body.sent == ["cmd/1", "cmd/2"]


def test_a_lost_command_is_still_sent_again(body):
    body.proxy.sense(np.zeros((2, 2)))
    body.lose = {2}                                     # the next publication is lost
    sensed = body.proxy.sense(np.zeros((2, 2)))
    assert sensed.shape == (2, 3)
    assert body.proxy.retransmits == 1 and body.sent == ["cmd/1", "cmd/2", "cmd/2"]
    assert body.now < 1.0                               # re-sent after about the timeout


def test_the_first_command_waits_command_timeout_s(body):
    body.lose = {1}
    body.proxy.sense(np.zeros((4, 2)))
    assert body.proxy.retransmits == 1 and body.sent == ["cmd/1", "cmd/1"]
