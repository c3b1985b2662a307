"""The opt-in stamps of the graph's round trips and hand-overs (sensorispace_ros.graph.tracing):
recording only when enabled, one file per process, and the step tables of
bench/graph_hops.py on stamps whose steps are known."""
import json
import subprocess
import sys
import textwrap

import pytest

from sensorispace_ros.graph import tracing

from shared import REPO
sys.path.insert(0, str(REPO))

from bench import graph_hops  # noqa: E402


def _trip(start_ns: int, steps_us) -> list:
    """The ROUND_TRIP stamps of one command, each step ``steps_us`` after the last."""
    events, t = [(tracing.ROUND_TRIP[0], start_ns, -1)], start_ns
    for tag, step in zip(tracing.ROUND_TRIP[1:], steps_us):
        t += int(step * 1e3)
        events.append((tag, t, -1))
    return events


def test_round_trips_are_cut_at_each_publication_and_timed_step_by_step():
    steps = [(10, 20, 30, 40, 50, 60), (11, 21, 31, 41, 51, 61)]
    events = _trip(0, steps[0]) + _trip(10**6, steps[1])
    # A command answered without the agent waiting (a move's: no agent.resume),
    # then the next publication: that one is left out, the next one counted.
    events += _trip(2 * 10**6, steps[0])[:-1] + _trip(3 * 10**6, steps[1])
    events += [("agent.answer", 4 * 10**6, -1)]          # a stray callback: nothing starts
    trips = tracing.round_trips(sorted(events, key=lambda e: e[1]))
    assert len(trips) == 3
    table = tracing.step_table(trips, tracing.ROUND_TRIP)
    assert [(r["from"], r["to"]) for r in table] == list(zip(tracing.ROUND_TRIP,
                                                             tracing.ROUND_TRIP[1:]))
    for k, row in enumerate(table):
        durations = sorted([steps[0][k], steps[1][k], steps[1][k]])
        assert row["n"] == 3
        assert row["median_us"] == pytest.approx(durations[1])
        assert row["mean_us"] == pytest.approx(sum(durations) / 3)
        assert row["total_s"] == pytest.approx(sum(durations) / 1e6)


def test_a_tag_out_of_sequence_does_not_complete_a_round_trip():
    events = _trip(0, (10, 20, 30, 40, 50, 60))
    del events[2]                                          # the body never took it
    assert tracing.round_trips(events) == []


def test_hand_overs_pair_the_settle_of_k_with_the_lights_of_k_plus_one():
    events, t = [], 0
    for k in (3, 4):
        for i, tag in enumerate(tracing.HAND_OVER):
            t += 100_000 * (i + 1)                         # step i takes (i + 1) * 100 us
            number = k if tag in tracing.HAND_OVER[:4] else k + 1
            events.append((tag, t, number))
            if tag == "body.lights":                       # a re-sent copy: the first counts
                events.append((tag, t + 5_000_000, number))
    events.append(("agent.await_rest", t + 10**6, 5))      # change 5 never completed
    changes = tracing.hand_overs(sorted(events, key=lambda e: e[1]))
    assert len(changes) == 2
    table = tracing.step_table(changes, tracing.HAND_OVER)
    assert [r["median_us"] for r in table] == pytest.approx(
        [100.0 * (i + 1) for i in range(1, len(tracing.HAND_OVER))])


def test_idle_waits_time_the_agent_idle_before_the_passive_sensation_and_its_hop():
    us = 1_000
    events = []
    # change 3: idle at 100 us, passive published at 400, taken at 450 (idle 300, hop 50)
    events += [("agent.idle", 100 * us, 3), ("body.passive", 400 * us, 4),
               ("agent.passive", 450 * us, 4)]
    # change 4: idle at 1000, published at 1100, taken at 1300 (idle 100, hop 200)
    events += [("agent.idle", 1000 * us, 4), ("body.passive", 1100 * us, 5),
               ("agent.passive", 1300 * us, 5)]
    # change 5: still busy when the passive was published (idle -40): no hop counted
    events += [("body.passive", 2000 * us, 6), ("agent.idle", 2040 * us, 5),
               ("agent.passive", 2050 * us, 6)]
    # change 6 never got its passive sensation: left out
    events += [("agent.idle", 3000 * us, 6), ("body.passive", 3000 * us, 6)]
    waits = tracing.idle_waits(sorted(events, key=lambda e: e[1]))
    assert waits["idle_before_passive"]["n"] == 3
    assert waits["idle_before_passive"]["median_us"] == pytest.approx(100)
    assert waits["idle_before_passive"]["mean_us"] == pytest.approx((300 + 100 - 40) / 3)
    assert waits["passive_hop_when_idle"]["n"] == 2
    assert waits["passive_hop_when_idle"]["mean_us"] == pytest.approx(125)
    assert waits["idle_first_share"] == pytest.approx(2 / 3)
    assert tracing.idle_waits([])["idle_before_passive"] == {"n": 0}


def test_nothing_is_recorded_unless_enabled_and_each_process_writes_its_own_file(tmp_path):
    script = textwrap.dedent("""
        import os, sys
        sys.path.insert(0, sys.argv[1])
        from sensorispace_ros.graph import tracing
        tracing.stamp("agent.publish")              # before enable: not recorded
        on = tracing.enable("agent")
        tracing.stamp("agent.publish")
        tracing.stamp("agent.passive", 7)
        print(on)
    """)
    env_off = {"PATH": "/usr/bin:/bin"}
    off = subprocess.run([sys.executable, "-c", script, str(REPO)], env=env_off,
                         capture_output=True, text=True, check=True)
    assert off.stdout.strip() == "False"
    traces = tmp_path / "traces"
    on = subprocess.run([sys.executable, "-c", script, str(REPO)],
                        env={**env_off, tracing.TRACE_DIR_ENV: str(traces)},
                        capture_output=True, text=True, check=True)
    assert on.stdout.strip() == "True"
    files = list(traces.glob("agent-*.json"))
    assert len(files) == 1
    content = json.loads(files[0].read_text())
    assert content["node"] == "agent" and [e[0] for e in content["events"]] == [
        "agent.publish", "agent.passive"]
    assert content["events"][1][2] == 7
    events = tracing.load(traces)
    assert [e[0] for e in events] == ["agent.publish", "agent.passive"]
    assert events[0][1] <= events[1][1]


def test_the_bench_reports_both_tables_from_a_trace_directory(tmp_path, capsys):
    traces = tmp_path / "traces"
    traces.mkdir()
    events = _trip(0, (10, 20, 30, 40, 50, 60))
    changes = [(tag, 10**7 + 1000 * i, 0 if i < 4 else 1)
               for i, tag in enumerate(tracing.HAND_OVER)]
    (traces / "agent-1.json").write_text(json.dumps(
        {"node": "agent", "pid": 1, "events": events + changes}))
    out = tmp_path / "hops.json"
    assert graph_hops.main(["--traces", str(traces), "--json", str(out)]) == 0
    tables = json.loads(out.read_text())
    assert tables["round_trips"] == 1 and tables["changes"] == 1
    assert [r["median_us"] for r in tables["round_trip"]] == pytest.approx(
        [10, 20, 30, 40, 50, 60])
    assert [r["median_us"] for r in tables["hand_over"]] == pytest.approx(
        [1.0] * (len(tracing.HAND_OVER) - 1))
    printed = capsys.readouterr().out
    assert "mean 210 us in all" in printed and "1 complete" in printed
    assert graph_hops.main(["--traces", str(tmp_path / "empty")]) == 1
