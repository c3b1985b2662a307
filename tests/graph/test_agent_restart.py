"""The agent node survives its death: snapshot + journal replay,
command retransmit, settled re-send; the representation ignores the
duplicates a restarted agent re-publishes.

The graph test runs every node in this process on one executor (a private
Context and domain id, as tests/graph/test_graph_in_process.py) and "kills" the
agent twice: the node is dropped at that instant without writing anything
more, and a fresh AgentNode is started on the same checkpoint directory. The
run must end with the offline run's POVs, equality sets, records and totals.
"""
import time

import numpy as np
import pytest

from sensorispace_ros import config, contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.graph import in_process
from sensorispace_ros.state.agent_journal import JOURNAL_FILE, SNAPSHOT_FILE, read_journal
from sensorispace_ros.graph.framework import frame
from sensorispace_ros.graph.body_over_topics import BodyOverTopics, RunAborted
from sensorispace_ros.graph.nodes.agent import AgentNode
from sensorispace_ros.graph.nodes.representation import RepresentationNode

from shared import SMOKE

PAPER_BODY = BodyDescription.revolute(4, 6)
SENSATION = contracts.contract("/body/sensation").columns_for(PAPER_BODY)


# ------------------------------------------------------------- retransmit

class SilentOnce:
    """A body that ignores the first copy of every command (a restarted body
    that lost it); answers later copies after ``delay_s``."""

    def __init__(self, delay_s=0.0):
        self.published: list[str] = []
        self.delay_s = delay_s
        self.body = None

    def publish(self, motor_states, frame_id):
        self.published.append(frame_id)
        self.motor = np.asarray(motor_states)

    def spin_once(self, timeout_s):
        if self.published.count(self.published[-1]) >= 2:
            time.sleep(self.delay_s)
            self.body.deliver(self.published[-1], np.tile(self.motor[:, :1], (1, 6)))
        else:
            time.sleep(timeout_s)


def test_an_unanswered_command_is_sent_again_with_the_same_frame_id():
    fake = SilentOnce()
    body = BodyOverTopics(fake.publish, fake.spin_once, n_motors=4, n_sensors=6,
                          command_timeout_s=0.05, on_retransmit=lambda *a: None)
    fake.body = body
    started = time.monotonic()
    answer = body.sense(np.full((2, 4), 0.25))
    assert time.monotonic() - started >= 0.05
    np.testing.assert_array_equal(answer, np.full((2, 6), 0.25))
    assert fake.published == ["cmd/1", "cmd/1"] and body.retransmits == 1
    body.sense(np.zeros((1, 4)))
    assert fake.published[2:] == ["cmd/2", "cmd/2"] and body.retransmits == 2
    # The late answer to the first copy of cmd/2 is not taken for anything.
    assert not body.deliver("cmd/2", np.zeros((1, 6)))


def test_a_prompt_answer_is_never_sent_twice():
    published = []
    body = BodyOverTopics(lambda m, f: published.append(f), lambda t: None,
                          n_motors=4, n_sensors=6, command_timeout_s=0.05)
    body._spin_once = lambda t: body.deliver(published[-1], np.zeros((1, 6)))
    for _ in range(3):
        body.sense(np.zeros((1, 4)))
    assert published == ["cmd/1", "cmd/2", "cmd/3"] and body.retransmits == 0


def test_command_timeout_must_be_positive():
    with pytest.raises(ValueError, match="command_timeout_s"):
        BodyOverTopics(None, None, 4, 6, command_timeout_s=0)


def test_the_body_over_topics_is_the_body_its_description_states():
    with pytest.raises(ValueError, match="description"):
        BodyOverTopics(None, None, 4, 6, description=BodyDescription.revolute(4, 7))
    assert BodyOverTopics(None, None, 4, 6, description=PAPER_BODY).description == PAPER_BODY


# ------------------------------------------- nodes fed by hand (no graph)

class RecordingPublisher:
    def __init__(self):
        self.sent = []

    def publish(self, msg):
        self.sent.append(msg)


def _passive(kind, number, value=0.5):
    return messages.matrix_to_cloud(np.full((1, 6), value), SENSATION,
                                    messages.make_header(frame(kind, number)))


def _agent(context, description=PAPER_BODY, **graph):
    """An agent node told what its body is (as the body's /body/description does)."""
    node = AgentNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, graph))
    node.on_description(messages.description_to_msg(description))
    return node


def test_the_agent_waits_for_its_body_description_and_sizes_itself_from_it(context, tmp_path):
    node = AgentNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, {"graph.results_dir": str(tmp_path)}))
    try:
        assert node.body is None and node.agent is None
        node.step()                                      # nothing to react with yet
        small = BodyDescription(("a", "b"), "deg", (360.0, 360.0), 3)
        node.on_description(messages.description_to_msg(small))
        assert (node.body.n_motors, node.body.n_sensors) == (2, 3)
        assert node.body.description == small           # the periods, for the naive agent
        assert node.agent.n_motors == 2 and node.initial_motor_state.tolist() == [0.0, 0.0]
        assert list(node.columns["/body/motor_command"]) == ["m0", "m1"]
        assert list(node.columns["/agent/points_of_view"])[2:] == ["m0", "m1"]
        # A sensation of another size is dropped, not handed to the agent.
        node.on_sensation(_passive("change", 0))
        assert node.dropped["/body/sensation"] == 1 and not node.passive
        node.on_sensation(messages.matrix_to_cloud(
            np.full((1, 3), 0.5), contracts.contract("/body/sensation").columns_for(small),
            messages.make_header("change/0")))
        assert [(k, n) for k, n, _ in node.passive] == [("change", 0)]
    finally:
        node.destroy_node()


def test_the_paper_body_keeps_the_configured_posture(context, tmp_path):
    node = _agent(context, **{"graph.results_dir": str(tmp_path)})
    try:
        assert (node.body.n_motors, node.body.n_sensors) == (4, 6)
        np.testing.assert_array_equal(node.initial_motor_state,
                                      config.load_config(SMOKE)["arm"]["initial_motor_state"])
    finally:
        node.destroy_node()


def test_a_passive_of_the_settled_change_is_settled_again(context, tmp_path):
    node = _agent(context, **{"graph.results_dir": str(tmp_path)})
    try:
        node.settled_pub = RecordingPublisher()
        node.last_passive = node.last_settled = 3
        node.on_sensation(_passive("change", 3))        # the settle of 3 may have been lost
        assert [m.data for m in node.settled_pub.sent] == [3]
        node.on_sensation(_passive("change", 2))        # older: nothing to say
        assert [m.data for m in node.settled_pub.sent] == [3] and not node.passive
        node.on_sensation(_passive("change", 4))        # new: queued, not settled yet
        assert [m.data for m in node.settled_pub.sent] == [3]
        assert [(k, n) for k, n, _ in node.passive] == [("change", 4)]
        node.on_sensation(_passive("change", 4))        # duplicate while reacting: ignored
        assert [m.data for m in node.settled_pub.sent] == [3] and len(node.passive) == 1
    finally:
        node.destroy_node()


def test_a_second_answer_to_an_answered_command_is_no_drop(context, tmp_path):
    node = _agent(context, **{"graph.results_dir": str(tmp_path)})

    def answer(n):
        return messages.matrix_to_cloud(np.zeros((1, 6)), SENSATION,
                                        messages.make_header(frame("cmd", n)))
    try:
        node.body.requests = 5                  # cmd/5 answered, nothing pending
        node.on_sensation(answer(5))            # the answer to its re-sent copy
        node.on_sensation(answer(4))
        assert node.late_answers == 2 and not node.dropped
        node.on_sensation(answer(6))            # a command never sent
        assert node.late_answers == 2 and node.dropped["/body/sensation"] == 1
    finally:
        node.destroy_node()


def test_journal_records_older_than_the_snapshot_are_not_replayed(context, tmp_path):
    """A kill between the snapshot's os.replace and the journal's truncation
    leaves records the snapshot already holds: they must not be fed twice."""
    graph = {"graph.results_dir": str(tmp_path), "graph.checkpoint_dir": str(tmp_path / "cp")}
    first = _agent(context, **graph)
    first.last_passive = first.last_settled = 5
    first.body.requests = 10
    first.take_snapshot()
    for number in (4, 5, 6):                 # 4, 5 before the snapshot, 6 after
        first.journal.passive("change", number, np.full(6, float(number)))
    for number in (9, 10, 11, 12):           # 9, 10 before the snapshot
        first.journal.answer(number, 0, np.full((1, 6), float(number)))
    first.journal.settled(5)
    first.journal.settled(6)
    first.destroy_node()                     # dies: no close, nothing more written
    second = AgentNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, graph))
    try:
        assert second.agent is None and not second.passive   # resumed once it has its body
        second.on_description(messages.description_to_msg(PAPER_BODY))
        assert [(k, n) for k, n, _ in second.passive] == [("change", 6)]
        np.testing.assert_array_equal(second.passive[0][2], np.full(6, 6.0))
        assert sorted(second.body.replay) == [11, 12] and second.body.requests == 10
        assert second.published_before_restart == {6}
        assert (second.last_passive, second.last_settled) == (6, 5)
    finally:
        second.close()
        second.destroy_node()


@pytest.mark.parametrize("damage", ["snapshot", "journal", "config"])
def test_a_bad_checkpoint_stops_the_agent_naming_the_file(context, tmp_path, damage):
    from sensorispace_ros.state.agent_journal import AgentJournal, write_snapshot
    checkpoints = tmp_path / "checkpoints"
    checkpoints.mkdir()
    if damage == "snapshot":
        (checkpoints / SNAPSHOT_FILE).write_bytes(b"not a pickle")
        expected = r"graph\.checkpoint_dir: .*agent\.snapshot: corrupt"
    elif damage == "journal":
        journal = AgentJournal(checkpoints / JOURNAL_FILE)
        journal.settled(1)
        journal.settled(2)
        journal.close()
        data = bytearray((checkpoints / JOURNAL_FILE).read_bytes())
        data[3] ^= 0xFF
        (checkpoints / JOURNAL_FILE).write_bytes(bytes(data))
        expected = r"graph\.checkpoint_dir: .*agent\.journal: corrupt"
    else:
        write_snapshot(checkpoints / SNAPSHOT_FILE, {"config": {"seed": 12345}})
        expected = r"agent\.snapshot: written by a run with another configuration"
    with pytest.raises(config.ConfigError, match=expected):
        AgentNode(context=context, parameter_overrides=in_process.parameter_overrides(
            SMOKE, {"graph.results_dir": str(tmp_path),
                    "graph.checkpoint_dir": str(checkpoints)}))


def test_a_snapshot_of_another_body_stops_the_agent_naming_the_file(context, tmp_path):
    graph = {"graph.results_dir": str(tmp_path), "graph.checkpoint_dir": str(tmp_path / "cp")}
    first = _agent(context, **graph)
    first.take_snapshot()
    first.close()
    first.destroy_node()
    second = AgentNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, graph))
    try:
        errors = []
        second.get_logger().error = errors.append
        second.on_description(messages.description_to_msg(BodyDescription.revolute(4, 7)))
        assert second.finished and second.exit_code == 2
        assert len(errors) == 1 and "agent.snapshot: written for another body" in errors[0]
    finally:
        second.destroy_node()


def _table(topic, frame_id, **columns):
    return messages.table_to_cloud(columns, contracts.contract(topic).columns_for(PAPER_BODY),
                                   messages.make_header(frame_id))


def test_representation_ignores_re_published_povs_and_rows(context, tmp_path):
    node = RepresentationNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, {"graph.results_dir": str(tmp_path)}))
    started = []
    node.build = lambda: started.append(True)
    try:
        node.on_description(messages.description_to_msg(PAPER_BODY))

        def povs(frame_id, ids, value):
            ids = np.asarray(ids)
            return _table("/agent/points_of_view", frame_id, pov=np.repeat(ids, 2),
                          sample=np.tile([0, 1], len(ids)),
                          **{f"m{j}": np.full(2 * len(ids), value) for j in range(4)})

        def rows(frame_id, set_id):
            return _table("/agent/compensations", frame_id, set=np.full(2, set_id),
                          pov_from=np.array([0, 1]), pov_to=np.array([1, 2]))

        sequence = [povs("change/0", [0], 1.0), povs("change/1", [1, 2], 2.0),
                    rows("change/1", 0),
                    # a restarted agent re-publishes change 1 (same ids, same rows)
                    povs("change/1", [1, 2], 2.0), rows("change/1", 0),
                    povs("change/2", [3], 3.0), rows("change/2", 1),
                    # and an impostor POV 3 under another frame: first copy wins
                    povs("change/3", [3], 9.0)]
        for msg in sequence:
            (node.on_compensations if "set" in [f.name for f in msg.fields]
             else node.on_points_of_view)(msg)
        node.on_done(_table("/agent/done", "end/3", changes=np.array([3]),
                            points_of_view=np.array([4]), compensation_rows=np.array([4]),
                            compensated=np.array([2]), queries=np.array([1]),
                            calls=np.array([1]), moved_povs=np.array([0])))
        assert node.worker is not None, "duplicates were counted: totals never matched"
        assert node.duplicates == 3
        from sensorispace_ros.graph.nodes.representation import assemble_points_of_view
        ids, motor = assemble_points_of_view(list(node.pov_tables.values()), 4)
        assert list(ids) == [0, 1, 2, 3] and np.all(motor[3] == 3.0)
        assert sum(len(t) for t in node.row_tables.values()) == 4
    finally:
        node.destroy_node()


# ------------------------------------------------- the graph, killed twice

class MortalAgent(AgentNode):
    """Dies at a chosen instant, as under kill -9: nothing more is written."""

    die_after_command: int | None = None       # right after publishing cmd/<n>
    die_before_marker_of: int | None = None    # reaction of change k out, journal marker not
    die_after_settle_of: int | None = None     # change k settled, its successor not yet seen

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.dead = False
        self.snapshot_at_death: dict | None = None
        self.resumed_at = None

    def start_body(self, description):
        super().start_body(description)        # resumes from the checkpoint
        self.resumed_at = (self.last_passive, self.last_settled, len(self.passive))

    def snapshot_due(self):
        return self.last_settled % 20 == 0      # deterministic, unlike the wall clock

    def die(self):
        self.dead = True
        self.body.aborted = True
        directory = self.journal.path.parent
        self.snapshot_at_death = {
            "snapshot": (directory / SNAPSHOT_FILE).is_file(),
            "journal": read_journal(directory / JOURNAL_FILE)}
        raise RunAborted("killed")

    def publish_command(self, motor_states, frame_id):
        super().publish_command(motor_states, frame_id)
        if frame_id == frame("cmd", self.die_after_command or -1):
            self.die()

    def settle(self, number, published):
        if number == self.die_before_marker_of and not published:
            self.die()
        super().settle(number, published)
        if number == self.die_after_settle_of and not published:
            self.die()

    def step(self):
        if not self.dead:
            super().step()


def _run_with_deaths(tmp_path, domain_id, deaths, timeout_s=300.0):
    """The smoke graph in this process; ``deaths`` are MortalAgent settings,
    one agent life each; the last agent is a plain AgentNode."""
    lives = list(deaths)
    dead = []

    def new_agent(**kwargs):
        if not lives:
            return AgentNode(**kwargs)
        agent = MortalAgent(**kwargs)
        for name, value in lives.pop(0).items():
            setattr(agent, name, value)
        return agent

    def bury_and_restart(nodes, replace):
        if getattr(nodes["agent"], "dead", False):
            corpse = replace("agent")
            corpse.journal.close()          # the fd only; a killed process writes nothing
            dead.append(corpse)

    result = in_process.run_graph_in_process(
        SMOKE, domain_id, tmp_path, timeout_s=timeout_s, on_spin=bury_and_restart,
        parameters={"graph.checkpoint_dir": str(tmp_path / "checkpoints")},
        node_factories={"agent": new_agent})
    return result["nodes"], dead


@pytest.mark.graph
@pytest.mark.slow
def test_agent_killed_twice_resumes_to_the_undisturbed_result(tmp_path, domain_id,
                                                           smoke_naive_run):
    offline = smoke_naive_run
    reference = offline.agent
    n_changes = reference._event
    # First death: waiting for the answer to a command a third into the run.
    # Second: right after settling the change half way (the passive sensation
    # of the next one goes to the dead agent: the restarted one, idle, settles
    # again until the environment re-sends it). Third: right after the
    # reaction of the last change that found a POV is published, before its
    # journal marker (it is settled again; every replayed reaction is
    # published again).
    deaths = [{"die_after_command": reference.calls_total // 3},
              {"die_after_settle_of": n_changes // 2},
              {"die_before_marker_of": max(reference.pov_events)}]
    assert deaths[2]["die_before_marker_of"] > n_changes // 2 + 1
    nodes, dead = _run_with_deaths(tmp_path, domain_id, deaths)

    first, second, third = dead
    assert first.snapshot_at_death["snapshot"], "no snapshot before the first death"
    assert first.snapshot_at_death["journal"].answers, "nothing journaled since the snapshot"
    assert second.body.replayed > 0 and second.checkpoint_stats["replayed_passives"] > 0
    # The third life's journal ended on the settled change: nothing of the next one.
    assert third.resumed_at[0] == max(third.published_before_restart) == n_changes // 2
    agent = nodes["agent"]
    for life in (second, third, agent):      # late answers are expected, drops are not
        assert not life.dropped, life.dropped
    killed_in = deaths[2]["die_before_marker_of"]
    assert agent.body.replayed > 0 and killed_in - 1 in agent.published_before_restart
    assert killed_in not in agent.published_before_restart   # so settled again

    arrays = nodes["representation"].result
    np.testing.assert_array_equal(arrays["povs"], offline.povs)
    np.testing.assert_array_equal(arrays["pairs"], offline.pairs)
    np.testing.assert_array_equal(arrays["set_ids"], offline.set_ids)
    assert nodes["representation"].duplicates > 0, "the re-published reaction never arrived"
    totals = {k[len("agent_"):]: int(v) for k, v in arrays.items() if k.startswith("agent_")}
    assert totals == {"changes": n_changes + 1, "points_of_view": len(offline.povs),
                      "compensation_rows": len(offline.pairs),
                      "compensated": reference.compensated,
                      "queries": reference.queries_total, "calls": reference.calls_total,
                      "moved_povs": 0}
    assert agent.agent.queries_by_stage == reference.queries_by_stage
    assert agent.agent.calls_by_stage == reference.calls_by_stage
    assert agent.agent.pov_queries == reference.pov_queries
    assert agent.agent.pov_events == reference.pov_events
    assert agent.agent.compensation_queries == reference.compensation_queries
    assert len(agent.agent.compensations) == len(reference.compensations)
    for got, want in zip(agent.agent.compensations, reference.compensations):
        assert (got.event, got.anchor_event, got.pov, got.searched) == \
            (want.event, want.anchor_event, want.pov, want.searched)
        np.testing.assert_array_equal(got.motor_state, want.motor_state)
        np.testing.assert_array_equal(got.anchor_motor_state, want.anchor_motor_state)


# ------------------------------------------------------------- move

def test_a_move_is_answered_before_the_next_command_and_before_await_move_returns():
    published, delivered = [], []
    body = BodyOverTopics(lambda m, f: published.append((f, np.array(m))), lambda t: None,
                          n_motors=4, n_sensors=6, command_timeout_s=0.05)

    def answer_last(timeout_s):
        frame_id, motor = published[-1]
        if body.deliver(frame_id, np.tile(motor[:, :1], (1, 6))):
            delivered.append(frame_id)
    body._spin_once = answer_last
    body.move(np.full((1, 4), 0.5))
    assert [f for f, _ in published] == ["cmd/1"] and delivered == []   # sent, not awaited
    answer = body.sense(np.full((2, 4), 0.25))
    # cmd/1's answer was taken before cmd/2 went out, and cmd/2's is the one returned
    assert [f for f, _ in published] == ["cmd/1", "cmd/2"] and delivered == ["cmd/1", "cmd/2"]
    np.testing.assert_array_equal(answer, np.full((2, 6), 0.25))
    body.move(np.zeros((1, 4)))
    body.await_move()
    assert delivered[-1] == "cmd/3"
    body.await_move()                                    # nothing pending: no spin, no send
    assert len(published) == 3 and body.retransmits == 0


def test_a_presend_answers_the_next_call_without_another_command():
    published = []
    body = BodyOverTopics(lambda m, f: published.append((f, np.array(m))), lambda t: None,
                          n_motors=4, n_sensors=6, command_timeout_s=0.05)

    def answer_last(timeout_s):
        frame_id, motor = published[-1]
        body.deliver(frame_id, np.tile(motor[:, :1], (1, 6)))
    body._spin_once = answer_last
    sweep = np.full((3, 4), 0.25)
    body.presend(sweep, 7)
    assert [f for f, _ in published] == ["next/7"]
    answer_last(0.0)            # the body answers right after change 7's passive sensation
    answer = body.sense(sweep.copy())
    assert [f for f, _ in published] == ["next/7"] and body.ahead_used == 1
    np.testing.assert_array_equal(answer, np.full((3, 6), 0.25))
    # Not answered yet when the agent asks: it waits for that answer, sends nothing.
    body.presend(sweep + 0.25, 8)
    np.testing.assert_array_equal(body.sense(sweep + 0.25), np.full((3, 6), 0.5))
    assert [f for f, _ in published] == ["next/7", "next/8"] and body.ahead_used == 2
    # A presend the agent does not ask for (other bits) is taken, dropped, then the call goes out.
    body.presend(np.zeros((1, 4)), 9)
    other = body.sense(np.full((1, 4), -0.0))
    assert [f for f, _ in published] == ["next/7", "next/8", "next/9", "cmd/4"]
    np.testing.assert_array_equal(other, np.full((1, 6), -0.0))
    assert body.ahead_used == 2 and body.requests == 4
    # ... and so is one still out when the agent moves the arm.
    body.presend(np.ones((2, 4)), 10)
    body.move(np.full((1, 4), 0.75))
    assert [f for f, _ in published][-2:] == ["next/10", "cmd/6"]
    assert body._pending == ("cmd/6", 1)


def test_an_unanswered_move_is_sent_again_by_await_move():
    fake = SilentOnce()
    body = BodyOverTopics(fake.publish, fake.spin_once, n_motors=4, n_sensors=6,
                          command_timeout_s=0.05, on_retransmit=lambda *a: None)
    fake.body = body
    body.move(np.full((1, 4), 0.25))
    assert fake.published == ["cmd/1"]
    body.await_move()
    assert fake.published == ["cmd/1", "cmd/1"] and body.retransmits == 1
