"""BodyOverTopics' hold and end (a world on its own clock, docs/clock.md),
without ROS: a hold is one message with the band (open sides at the largest
float64), answered once; ``end/<n>`` answers it when the world has no change
left; a non-finite motor state is never sent."""
import numpy as np
import pytest

from sensorispace_ros.graph.body_over_topics import BAND_LIMIT, BodyOverTopics


class FakeBody:
    """Answers each publication when the proxy spins, as ``answer`` says."""

    def __init__(self, answer):
        self.sent, self.holds, self.answer = [], [], answer
        self.proxy = None

    def publish_command(self, motor_states, frame_id):
        self.sent.append((frame_id, motor_states.copy()))

    def publish_hold(self, motor_state, low, high, frame_id):
        self.holds.append((frame_id, motor_state.copy(), low.copy(), high.copy()))

    def spin_once(self, timeout_s):
        frame_id = (self.holds or self.sent)[-1][0]
        self.proxy.deliver(*self.answer(frame_id))


def _proxy(answer):
    body = FakeBody(answer)
    body.proxy = BodyOverTopics(body.publish_command, body.spin_once, n_motors=2, n_sensors=3,
                                publish_hold=body.publish_hold)
    return body, body.proxy


def test_a_hold_is_one_message_and_its_answer_the_sensation_that_left_the_band():
    left = np.array([[0.5, 0.2, 0.1]])
    body, proxy = _proxy(lambda frame_id: (frame_id, left))
    sensed = proxy.hold(np.array([1.0, 2.0]), np.array([-np.inf, 0.0, 0.0]),
                        np.array([1.0, np.inf, 1.0]))
    np.testing.assert_array_equal(sensed, left[0])
    [(frame_id, motor, low, high)] = body.holds
    assert frame_id == "hold/1" and not body.sent
    np.testing.assert_array_equal(motor, [[1.0, 2.0]])
    assert low[0] == -BAND_LIMIT and high[1] == BAND_LIMIT and np.isfinite([low, high]).all()


def test_a_hold_answered_with_end_says_the_run_is_over():
    body, proxy = _proxy(lambda frame_id: ("end/" + frame_id.split("/")[1], np.zeros((1, 3))))
    assert proxy.hold(np.zeros(2), np.zeros(3), np.ones(3)) is None
    assert proxy.reply_frame == "end/1"


def test_a_non_finite_motor_state_is_never_sent():
    body, proxy = _proxy(lambda frame_id: (frame_id, np.zeros((2, 3))))
    with pytest.raises(ValueError, match=r"non-finite motor values in rows \[1\]"):
        proxy.sense(np.array([[0.0, 0.0], [np.nan, 0.0]]))
    assert not body.sent


class SlowBody(FakeBody):
    """Answers a hold only at its ``answer_at``-th spin (a body node that died
    with the first one), each spin taking ``spin_s``."""

    def __init__(self, answer, answer_at: int, spin_s: float):
        super().__init__(answer)
        self.spins, self.answer_at, self.spin_s = 0, answer_at, spin_s

    def spin_once(self, timeout_s):
        import time
        time.sleep(self.spin_s)
        self.spins += 1
        if self.spins >= self.answer_at:
            super().spin_once(timeout_s)


@pytest.mark.parametrize("resend", [True, False])
def test_an_unanswered_hold_is_sent_again_only_on_the_row_clock(resend):
    left = np.array([[0.5, 0.2, 0.1]])
    body = SlowBody(lambda frame_id: (frame_id, left), answer_at=12, spin_s=0.005)
    body.proxy = BodyOverTopics(body.publish_command, body.spin_once, n_motors=2, n_sensors=3,
                                command_timeout_s=0.02, publish_hold=body.publish_hold,
                                resend_holds=resend)
    low, high = np.zeros(3), np.ones(3)
    sensed = body.proxy.hold(np.array([1.0, 2.0]), low, high)
    np.testing.assert_array_equal(sensed, left[0])
    # 12 spins of 5 ms against a timeout of 20 ms: sent again at least once.
    assert len(body.holds) > 1 if resend else len(body.holds) == 1
    assert body.proxy.retransmits == len(body.holds) - 1 and not body.sent
    for frame_id, motor, sent_low, sent_high in body.holds:    # the same hold each time
        assert frame_id == "hold/1"
        np.testing.assert_array_equal(motor, [[1.0, 2.0]])
        np.testing.assert_array_equal(sent_low, low)
        np.testing.assert_array_equal(sent_high, high)


class RestartingBody(FakeBody):
    """A body that dies holding (its first spins answer nothing) and starts
    again at spin ``restart_at``, when the agent hears its description again
    (``hold_again``); it answers the hold it is sent after that."""

    def __init__(self, answer, restart_at: int):
        super().__init__(answer)
        self.spins, self.restart_at, self.holds_seen_at_restart = 0, restart_at, None

    def spin_once(self, timeout_s):
        self.spins += 1
        if self.spins == self.restart_at:
            self.holds_seen_at_restart = len(self.holds)
            assert self.proxy.hold_again()
        elif self.spins > self.restart_at and len(self.holds) > self.holds_seen_at_restart:
            super().spin_once(timeout_s)


def test_a_hold_is_sent_again_to_a_body_that_started_again_on_the_wall_clock():
    left = np.array([[0.5, 0.2, 0.1]])
    body = RestartingBody(lambda frame_id: (frame_id, left), restart_at=5)
    body.proxy = BodyOverTopics(body.publish_command, body.spin_once, n_motors=2, n_sensors=3,
                                command_timeout_s=60.0, publish_hold=body.publish_hold)
    assert not body.proxy.hold_again()                 # no hold waited for: nothing sent
    sensed = body.proxy.hold(np.array([1.0, 2.0]), np.zeros(3), np.ones(3))
    np.testing.assert_array_equal(sensed, left[0])
    assert [h[0] for h in body.holds] == ["hold/1", "hold/1"] and body.proxy.retransmits == 1
    assert not body.proxy.hold_again() and len(body.holds) == 2    # answered: not again


class LateSubscriber(FakeBody):
    """A restarted body whose hold subscription matches late: the hold sent on
    its description is lost; it answers the first hold that reaches it."""

    def __init__(self, answer):
        super().__init__(answer)
        self.spins = 0

    def spin_once(self, timeout_s):
        import time
        time.sleep(0.005)
        self.spins += 1
        assert self.spins < 400, "the hold was not sent again after the restart"
        if self.spins == 3:
            assert self.proxy.hold_again()          # lost: not subscribed yet
            self.lost = len(self.holds)
        elif self.spins > 3 and len(self.holds) > self.lost:
            super().spin_once(timeout_s)


def test_a_hold_sent_again_to_a_restarted_body_is_sent_by_time_until_answered():
    left = np.array([[0.5, 0.2, 0.1]])
    body = LateSubscriber(lambda frame_id: (frame_id, left))
    body.proxy = BodyOverTopics(body.publish_command, body.spin_once, n_motors=2, n_sensors=3,
                                command_timeout_s=0.02, publish_hold=body.publish_hold)
    sensed = body.proxy.hold(np.array([1.0, 2.0]), np.zeros(3), np.ones(3))
    np.testing.assert_array_equal(sensed, left[0])
    # Sent, sent again on the restart (lost), then by time until answered.
    assert len(body.holds) >= 3 and {h[0] for h in body.holds} == {"hold/1"}
    # Answered: the next hold on this (wall) clock is not re-sent by time.
    quiet = SlowBody(lambda frame_id: (frame_id, left), answer_at=12, spin_s=0.005)
    quiet.proxy = body.proxy
    body.proxy._publish_hold, body.proxy._spin_once = quiet.publish_hold, quiet.spin_once
    body.proxy.hold(np.array([1.0, 2.0]), np.zeros(3), np.ones(3))
    assert len(quiet.holds) == 1
