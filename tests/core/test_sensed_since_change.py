"""The naive agent answers a call from what it sensed since the last change
(``remember_sensations``): same results, fewer calls and rows, the arm still rests."""
import contextlib
import types

import numpy as np
import pytest

from sensorispace_ros.core.body import SensingOnly, SimulatedBody
from sensorispace_ros.core.paper.exploration import build_world
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.run import run_naive
from sensorispace_ros.core.naive.sense_memory import CountingBody, SensedSinceChange

from naive_flag_runs import assert_same_results, runs_on_and_off


class CountingFake:
    """A deterministic body (row -> its own function) recording each call."""

    n_motors, n_sensors = 4, 6

    def __init__(self, with_move: bool):
        self.sent: list[np.ndarray] = []
        self.moved: list[np.ndarray] = []
        if with_move:
            self.move = lambda rows: self.moved.append(np.array(rows))

    def sense(self, motor_states):
        motor_states = np.asarray(motor_states, dtype=float)
        self.sent.append(motor_states.copy())
        return np.sin(motor_states @ np.arange(1.0, 25.0).reshape(4, 6))


def test_recall_gives_the_stored_bits_only_for_rows_all_stored():
    rng = np.random.default_rng(0)
    memory = SensedSinceChange(4, 6)
    rows, sensations = rng.normal(size=(7, 4)), rng.normal(size=(7, 6))
    assert memory.recall(rows[:1]) is None                         # empty
    memory.store(rows, sensations)
    picked = [5, 0, 5, 3]
    got = memory.recall(rows[picked])
    assert got is not None and np.array_equal(got.view(np.uint64),
                                              sensations[picked].view(np.uint64))
    got[:] = 0.0                                                    # a copy, not the memory
    np.testing.assert_array_equal(memory.recall(rows[picked]), sensations[picked])
    assert memory.recall(np.vstack([rows[2], rng.normal(size=4)])) is None   # one unknown row
    assert memory.recall(rng.normal(size=(1, 4))) is None
    nudged = rows[4:5].copy()
    nudged[0, 2] = np.nextafter(nudged[0, 2], np.inf)               # one ulp away
    assert memory.recall(nudged) is None
    memory.clear()
    assert memory.recall(rows[:1]) is None


def test_rows_are_matched_by_their_bits():
    memory = SensedSinceChange(4, 6)
    memory.store(np.array([[0.0, 1.0, 2.0, 3.0]]), np.ones((1, 6)))
    assert memory.recall(np.array([[-0.0, 1.0, 2.0, 3.0]])) is None   # == 0.0, other bits
    assert memory.recall(np.array([[0.0, 1.0, 2.0, 3.0]])) is not None
    assert memory.recall(np.array([[1.0, 0.0, 2.0, 3.0]])) is None     # same values, swapped


def test_a_row_has_the_same_key_alone_and_in_any_batch():
    rng = np.random.default_rng(2)
    memory = SensedSinceChange(4, 6)
    rows = rng.normal(size=(600, 4))
    memory.store(rows, rng.normal(size=(600, 6)))
    for i in range(0, 600, 37):                       # one row, then the batch reversed
        assert memory.recall(np.ascontiguousarray(rows[i:i + 1])) is not None
    assert memory.recall(np.ascontiguousarray(rows[::-1])) is not None


def test_keys_that_collide_are_not_taken_for_the_row():
    memory = SensedSinceChange(4, 6)
    stored = np.array([[1.0, 2.0, 3.0, 4.0]])
    memory.store(stored, np.ones((1, 6)))
    other = np.array([[5.0, 6.0, 7.0, 8.0]])
    memory._index[memory._keys(other)[0]] = 0                       # force a collision
    assert memory.recall(other) is None
    assert not memory.lookup(other)[1].any()


def test_lookup_tells_row_by_row_which_were_sensed():
    rng = np.random.default_rng(3)
    memory = SensedSinceChange(4, 6)
    rows, sensations = rng.normal(size=(5, 4)), rng.normal(size=(5, 6))
    memory.store(rows, sensations)
    memory.store(rows[:1], sensations[:1] + 1.0)        # sensed again: the first is kept
    nudged = rows[2].copy()
    nudged[1] = np.nextafter(nudged[1], -np.inf)
    asked = np.vstack([rows[3], rng.normal(size=4), rows[0], nudged])
    got, found = memory.lookup(asked)
    np.testing.assert_array_equal(found, [True, False, True, False])
    np.testing.assert_array_equal(got[found], sensations[[3, 0]])
    assert np.isnan(got[~found]).all()
    memory.clear()
    assert not memory.lookup(rows)[1].any()


def test_memory_grows_and_keeps_the_first_rows():
    rng = np.random.default_rng(1)
    memory = SensedSinceChange(4, 6)
    rows, sensations = rng.normal(size=(3000, 4)), rng.normal(size=(3000, 6))
    for chunk in range(0, 3000, 700):
        memory.store(rows[chunk:chunk + 700], sensations[chunk:chunk + 700])
    assert memory.count == 3000
    picked = [0, 699, 700, 2999]
    np.testing.assert_array_equal(memory.recall(rows[picked]), sensations[picked])


def test_counting_body_sends_a_call_once_per_change():
    fake = CountingFake(with_move=False)
    body = CountingBody(fake)
    body.stage = "rank"
    rows = np.arange(8.0).reshape(2, 4)
    first = body.sense(rows)
    second = body.sense(rows[::-1])
    assert len(fake.sent) == 1 and body.calls == {"rank": 1} and body.remembered == {"rank": 1}
    np.testing.assert_array_equal(second, first[::-1])
    body.sense(np.vstack([rows[0], rows[0] + 1.0]))               # half new: sent whole
    assert len(fake.sent) == 2
    body.forget()                                                   # the environment moved
    body.sense(rows)
    assert len(fake.sent) == 3 and body.calls == {"rank": 3}


def test_partial_recall_sends_only_the_rows_not_sensed_since_the_change():
    fake = CountingFake(with_move=False)
    body = CountingBody(fake, partial=True)
    body.stage = "rank"
    rows = np.arange(8.0).reshape(2, 4)
    body.sense(rows)
    asked = np.vstack([rows[1], rows[0] + 1.0, rows[0], rows[0] + 2.0])
    got = body.sense(asked)
    np.testing.assert_array_equal(fake.sent[-1], asked[[1, 3]])     # the new rows alone
    np.testing.assert_array_equal(got, fake.sense(asked))
    assert body.rows == {"rank": 4} and body.calls == {"rank": 2}
    assert body.recalled == {"rank": 2} and body.remembered == {}
    body.sense(asked[[2, 0]])                                       # all known: not sent
    assert body.calls == {"rank": 2} and body.remembered == {"rank": 1}
    with body.fresh():                                              # averaging: all sent
        body.sense(asked)
    assert len(fake.sent[-2]) == 4 and body.rows == {"rank": 8}
    body.forget()
    body.sense(asked)
    assert len(fake.sent[-2]) == 4 and body.rows == {"rank": 12}


def test_partial_recall_retries_lost_rows_and_carries_the_lookahead():
    truth = CountingFake(with_move=False)
    sent, lost_once = [], [True]

    def sense(rows):
        rows = np.asarray(rows, dtype=float)
        sent.append(rows.copy())
        out = np.sin(rows @ np.arange(1.0, 25.0).reshape(4, 6))
        if lost_once[0] and len(rows) > 1:
            lost_once[0] = False
            out[0] = np.nan                                         # a lost frame
        return out

    truth.sense = sense
    body = CountingBody(truth, partial=True, retries=1)
    body.stage = "compensation"
    known = np.full((1, 4), 0.5)
    body.sense(known)
    ahead = np.full((1, 4), 0.9)
    new = np.array([[0.1, 0.2, 0.3, 0.4], [0.2, 0.3, 0.4, 0.5]])
    with body.lookahead(ahead):
        got = body.sense(np.vstack([known, new]))
    expected = np.sin(np.vstack([known, new]) @ np.arange(1.0, 25.0).reshape(4, 6))
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(sent[1], np.vstack([new, ahead]))   # the known row left out
    np.testing.assert_array_equal(sent[2], new[:1])                   # the lost row again
    assert body.recalled == {"compensation": 1} and body.rows == {"compensation": 5}


@pytest.mark.parametrize("with_move", [True, False])
def test_rest_always_commands_the_arm_and_waits_only_without_move(with_move):
    fake = CountingFake(with_move)
    body = CountingBody(fake)
    body.stage = "rest"
    state = np.array([0.1, -1.5, 2.2, -3.0])
    sensed = body.sense(state[None])[0]
    rested = body.rest(state)
    np.testing.assert_array_equal(rested, sensed)
    assert body.calls == {"rest": 2} and body.rows == {"rest": 2}
    if with_move:                       # remembered: moved there without waiting for it
        assert len(fake.sent) == 1 and len(fake.moved) == 1
        np.testing.assert_array_equal(fake.moved[0], state[None])
    else:                               # no move: the command is a sense, the arm ends there
        assert len(fake.sent) == 2
        np.testing.assert_array_equal(fake.sent[-1], state[None])
    fresh = np.array([0.3, 0.2, 0.1, 0.0])
    body.rest(fresh)                    # never sensed: a sense, whatever the body
    np.testing.assert_array_equal(fake.sent[-1], fresh[None])


def test_simulated_body_move_puts_the_arm_there_and_counts_a_call():
    world = build_world(0, {"grid_count": 4})
    body = SimulatedBody(world.receptors, world.initial_lights, world.m0.copy())
    body.move(np.array([[0.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.5, 0.5]]))
    np.testing.assert_array_equal(body.motor_state, [0.5, 0.5, 0.5, 0.5])
    assert body.calls == 1 and body.queries == 2
    with pytest.raises(ValueError, match="shape"):
        body.move(np.zeros((1, 3)))
    sense_only = types.SimpleNamespace(n_motors=4, n_sensors=6, sensed=[],
                                       sense=lambda rows: sense_only.sensed.append(rows))
    SensingOnly(sense_only).move(np.ones((1, 4)))                  # no move: senses
    assert len(sense_only.sensed) == 1


def test_remembering_changes_no_result_only_the_calls():
    on, off = runs_on_and_off("remember_sensations", grid_count=12)
    assert assert_same_results(on, off) > 10
    remembered = sum(on.agent.remembered_by_stage.values())
    assert remembered > 0 and off.agent.remembered_by_stage == {}
    assert off.agent.calls_total - on.agent.calls_total == remembered
    # every rest is still a command: as many as changes (+ the start)
    assert on.agent.calls_by_stage["rest"] == off.agent.calls_by_stage["rest"]


def test_partial_recall_changes_no_result_only_the_rows(monkeypatch):
    world = build_world(0, {"grid_count": 12})
    partial = run_naive(world, NaiveParams())
    monkeypatch.setattr(NaiveAgent, "_partial_recall", False)      # whole calls only
    whole = run_naive(world, NaiveParams())
    assert assert_same_results(partial, whole) > 10
    recalled = sum(partial.agent.recalled_by_stage.values())
    assert recalled > 1000 and whole.agent.recalled_by_stage == {}
    assert whole.agent.queries_total - partial.agent.queries_total == recalled
    assert whole.agent.calls_by_stage == partial.agent.calls_by_stage


def test_lookahead_rows_ride_on_the_next_call_and_answer_a_later_one():
    fake = CountingFake(with_move=False)
    body = CountingBody(fake, remember=True)
    body.stage = "rank"
    asked, ahead = np.full((2, 4), 0.1), np.arange(12.0).reshape(3, 4) / 10
    with body.lookahead(ahead):
        got = body.sense(asked)
        assert got.shape == (2, 6)
        np.testing.assert_array_equal(got, fake.sense(asked))
        body.sense(asked[:1] + 1.0)                       # only the first call carries them
    assert [len(rows) for rows in fake.sent[:3]] == [5, 2, 1]
    np.testing.assert_array_equal(fake.sent[0][2:], ahead)
    assert body.rows == {"rank": 6} and body.calls == {"rank": 2}
    body.stage = "compensation"
    n_sent = len(fake.sent)
    np.testing.assert_array_equal(body.sense(ahead[[2, 0]]), fake.sense(ahead[[2, 0]]))
    assert len(fake.sent) == n_sent + 1                   # the check above, not the agent
    assert body.calls == {"rank": 2} and body.remembered == {"compensation": 1}
    with body.lookahead(ahead + 5.0):
        body.sense(asked)                                  # remembered: nothing is sent
    body.sense(asked + 2.0)                                # after the block: nothing rides
    assert len(fake.sent[-1]) == 2
    forgetful = CountingBody(CountingFake(with_move=False), remember=False)
    with forgetful.lookahead(ahead):
        forgetful.sense(asked)
    assert len(forgetful._body.sent[0]) == 2              # nothing to remember them in


def test_rank_call_carries_the_search_starts_same_results_fewer_calls(monkeypatch):
    world = build_world(0, {"grid_count": 12})
    with_lookahead = run_naive(world, NaiveParams())
    # The same run with the lookahead rows dropped.
    monkeypatch.setattr(CountingBody, "lookahead", _no_lookahead)
    without = run_naive(world, NaiveParams())
    np.testing.assert_array_equal(with_lookahead.povs, without.povs)
    np.testing.assert_array_equal(with_lookahead.pairs, without.pairs)
    assert len(with_lookahead.povs) > 10
    saved = without.agent.calls_total - with_lookahead.agent.calls_total
    remembered = with_lookahead.agent.remembered_by_stage
    assert saved > 20
    assert remembered.get("compensation", 0) - without.agent.remembered_by_stage.get(
        "compensation", 0) > 20
    assert with_lookahead.agent.queries_total > without.agent.queries_total


def _no_lookahead(self, motor_states):
    return contextlib.nullcontext()


def test_remember_sensations_must_be_a_bool():
    with pytest.raises(ValueError, match="naive.remember_sensations"):
        NaiveParams(remember_sensations="yes")
