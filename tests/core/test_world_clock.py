"""A world on its own clock (core.world_clock) and the agent's change test
(core.naive.change_detection)."""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.core.naive import change_detection
from sensorispace_ros.core.world_clock import ClockedBody, change_rows

RECEPTORS = np.linspace(-0.5, 0.5, 4)
LIGHTS = [np.array([[4.0, 1.0], [-3.5, 2.0]]), np.array([[4.5, 1.0], [-3.0, 2.0]]),
          np.array([[4.5, -1.0], [-3.0, 3.0]])]


def _states(n=7, seed=3):
    return np.random.default_rng(seed).uniform(-np.pi, np.pi, size=(n, 4))


def test_change_rows_are_seeded_exponential_gaps():
    rows = change_rows(20000, 500.0, seed=1)
    assert np.array_equal(rows, change_rows(20000, 500.0, seed=1))
    assert not np.array_equal(rows, change_rows(20000, 500.0, seed=2))
    gaps = np.diff(np.concatenate([[0], rows]))
    assert gaps.min() >= 1
    assert abs(gaps.mean() / 500.0 - 1.0) < 0.03
    # Exponential: the median gap is the mean times ln 2.
    assert abs(np.median(gaps) / (500.0 * np.log(2)) - 1.0) < 0.05


def test_a_change_inside_a_batch_splits_it():
    rows = np.array([3, 5])
    clocked = ClockedBody(SimulatedBody(RECEPTORS), LIGHTS, rows)
    states = _states()
    sensed = clocked.sense(states)
    assert np.ptp(sensed, axis=0).max() > 0
    for state in range(3):
        alone = SimulatedBody(RECEPTORS, LIGHTS[state])
        expected = alone.sense(states)
        which = clocked.state_at(np.arange(7)) == state
        assert which.any()
        assert np.array_equal(sensed[which], expected[which])
    assert clocked.row == 7 and clocked.ended
    assert list(clocked.state_at([0, 2, 3, 4, 5, 100])) == [0, 0, 1, 1, 2, 2]


def test_hold_returns_the_first_sensation_out_of_band():
    body = SimulatedBody(RECEPTORS)
    clocked = ClockedBody(body, LIGHTS, np.array([1000, 1000000]))
    candidates = _states(200)
    before = SimulatedBody(RECEPTORS, LIGHTS[0]).sense(candidates)
    after = SimulatedBody(RECEPTORS, LIGHTS[1]).sense(candidates)
    rest = candidates[np.argmax(np.abs(after - before).max(axis=1))]
    reference = clocked.sense(rest[None])[0]
    low, high = change_detection.band(0.0, reference)
    sensed = clocked.hold(rest, low, high)
    assert np.array_equal(sensed, SimulatedBody(RECEPTORS, LIGHTS[1]).sense(rest[None])[0])
    assert clocked.row == 1001 and clocked.held_rows == 1000
    # A band that takes everything in holds to the end of the world.
    assert clocked.hold(rest, np.full(4, -np.inf), np.full(4, np.inf)) is None
    assert clocked.ended


def test_a_clock_resumed_at_its_position_answers_as_it_did():
    clocked = ClockedBody(SimulatedBody(RECEPTORS), LIGHTS, np.array([3, 5]))
    states = _states()
    first = clocked.sense(states[:2])
    at = clocked.position()
    assert at[:3].tolist() == [2, 0, 1]
    np.testing.assert_array_equal(at[3:], states[1])
    then = clocked.sense(states[2:])
    clocked.resume(at)                      # back before the change at row 3
    assert (clocked.row, clocked.state) == (2, 0)
    np.testing.assert_array_equal(clocked.sense(states[2:]), then)
    assert clocked.ended and clocked.row == 7
    np.testing.assert_array_equal(first, SimulatedBody(RECEPTORS, LIGHTS[0]).sense(states[:2]))
    with pytest.raises(ValueError, match="position: need row, held rows, calls, 4 joints and 0 physics values"):
        clocked.resume(at[:3])
    with pytest.raises(ValueError, match="held rows 9 outside"):
        clocked.resume(np.concatenate([[2, 9, 1], states[1]]))


def test_the_change_test_is_the_noise_band():
    reference = np.array([1.0, 2.0, np.nan])
    sd = 1e-3
    half = change_detection.Z_BAND * np.sqrt(2) * sd
    assert not change_detection.differs(sd, reference, reference + 0.9 * half)
    assert change_detection.differs(sd, reference, reference + np.array([0, 1.1 * half, 0]))
    # A lost receptor is no evidence.
    assert not change_detection.differs(sd, reference, np.array([1.0, np.nan, 5.0]))
    # Noiseless: any change beyond round-off.
    assert change_detection.differs(0.0, reference, reference + np.array([0, 1e-12, 0]))
    assert not change_detection.differs(0.0, reference, reference.copy())


def test_config_names_the_clock():
    assert config.defaults()["world"]["clock"] == "agent"
    for key, value in (("world.clock", "sometimes"), ("world.change_interval", 0.0),
                       ("world.change_period_s", -1.0)):
        with pytest.raises(config.ConfigError, match=key.replace(".", r"\.")):
            config.load_config(None, {key: value})


def test_sentinels_watch_the_rows_sent_since_they_were_last_sensed():
    # With ``every`` rows, small calls go unwatched until the call that makes
    # that many; a change in an unwatched call is flagged by the next
    # sentinels (a later call or ``flush``), before anything after it passes.
    from sensorispace_ros.core.naive.change_detection import Tripwire, WorldChanged

    states = _states(12)
    for every, first_flagged in [(0, 1), (7, 2)]:
        clocked = ClockedBody(SimulatedBody(RECEPTORS), LIGHTS[:2], np.array([4]))
        tripwire = Tripwire(clocked)
        sentinel = states[-1:]
        tripwire.arm(sentinel, SimulatedBody(RECEPTORS, LIGHTS[0]).sense(sentinel), 0.0)
        tripwire.every = every
        tripwire.sense(states[:3])                  # 3 rows (+ the sentinel when every = 0)
        flagged = None
        for call in range(1, 4):
            try:
                tripwire.sense(states[3 + 2 * call:5 + 2 * call])    # 2 rows a call
            except WorldChanged:
                flagged = call
                break
        assert flagged == first_flagged
    clocked = ClockedBody(SimulatedBody(RECEPTORS), LIGHTS[:2], np.array([2]))
    tripwire = Tripwire(clocked)
    tripwire.arm(sentinel, SimulatedBody(RECEPTORS, LIGHTS[0]).sense(sentinel), 0.0)
    tripwire.every = 100
    tripwire.sense(states[:3])                      # unwatched: the change falls inside
    assert tripwire.rows == 0
    with pytest.raises(WorldChanged):
        tripwire.flush()
