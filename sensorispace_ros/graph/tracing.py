"""Opt-in time stamps of the graph's round trips and hand-overs (``bench/graph_hops.py``).

With ``SENSORISPACE_TRACE_DIR`` set in a node's environment, the node process
records ``(tag, perf_counter_ns, number)`` at the points below and writes them
to ``<dir>/<node>-<pid>.json`` when it exits. ``time.perf_counter`` is
CLOCK_MONOTONIC on Linux, so stamps of different processes on one machine are
comparable. Unset (the default), ``stamp`` only tests a module global.

Why: the graph's extra wall time over the offline run is spread over many
steps of 40-140 us each (docs/benchmarks.md), and a machine's
numbers differ; this lets anyone see where a run's time goes on theirs.

Tags (see ``ROUND_TRIP`` and ``HAND_OVER``): the agent's command publication
(``agent.publish``, ``agent.published``), the body's callback, its answer's
publication (``body.command``, ``body.publish``, ``body.published``), the
agent's callback and return to its computation (``agent.answer``,
``agent.resume``); per change: the agent waiting for its rest command's answer
(``agent.await_rest``), publishing the settle (``agent.settle``,
``agent.settled``), done with its own work of the hand-over (the next sweep sent
ahead: ``agent.idle``, a branch beside the chain, see ``idle_waits``), the environment receiving it and about to publish the
next lights (``environment.settled``, ``environment.lights``, numbered by the
new change), the body receiving them and having published the passive
sensation (``body.lights``, ``body.passive``), the agent receiving it and
reacting (``agent.passive``, ``agent.react``). A step that starts when a
publication returns can be negative: on two cores the woken reader may run
before the writer gets its CPU back.

No rclpy here.
"""
from __future__ import annotations

import atexit
import json
import os
import statistics
import time
from pathlib import Path

TRACE_DIR_ENV = "SENSORISPACE_TRACE_DIR"

ROUND_TRIP = ("agent.publish", "agent.published", "body.command", "body.publish",
              "body.published", "agent.answer", "agent.resume")
# Numbered by change; environment.lights and what follows carry the next change's number.
HAND_OVER = ("agent.await_rest", "agent.settle", "agent.settled", "environment.settled",
             "environment.lights", "body.lights", "body.passive", "agent.passive",
             "agent.react")
_NEXT_CHANGE = HAND_OVER.index("environment.lights")
# The agent's own work after its settle (the next sweep, sent ahead) runs beside the
# chain environment -> body -> passive sensation, not in it.
AGENT_IDLE = "agent.idle"

_events: list | None = None
_node = ""


def enable(node: str, directory: str | Path | None = None) -> bool:
    """Start recording for ``node`` if ``directory`` (default: the
    ``SENSORISPACE_TRACE_DIR`` variable) is set; True if recording."""
    global _events, _node
    directory = directory if directory is not None else os.environ.get(TRACE_DIR_ENV)
    if not directory or _events is not None:
        return _events is not None
    _events, _node = [], node
    atexit.register(dump, Path(directory))
    return True


def stamp(tag: str, number: int = -1) -> None:
    if _events is not None:
        _events.append((tag, time.perf_counter_ns(), number))


def dump(directory: str | Path) -> Path | None:
    """Write the stamps recorded so far to ``<directory>/<node>-<pid>.json``."""
    if _events is None:
        return None
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{_node}-{os.getpid()}.json"
    path.write_text(json.dumps({"node": _node, "pid": os.getpid(), "events": _events}))
    return path


def load(directory: str | Path) -> list[tuple[str, int, int]]:
    """Every stamp of every process traced into ``directory``, in time order."""
    events = []
    for path in sorted(Path(directory).glob("*.json")):
        events.extend(tuple(e) for e in json.loads(path.read_text())["events"])
    return sorted(events, key=lambda e: e[1])


def round_trips(events) -> list[dict]:
    """The ``ROUND_TRIP`` stamps of each command, in order: a round trip starts
    at ``agent.publish`` and takes the first of each later tag in sequence
    (an answer taken from memory or a presend's, which skip some, are left out)."""
    trips, current = [], None
    for tag, t, _ in events:
        if tag == ROUND_TRIP[0]:
            current = {tag: t}
        elif current is not None and tag in ROUND_TRIP and tag not in current:
            position = ROUND_TRIP.index(tag)
            if all(previous in current for previous in ROUND_TRIP[:position]):
                current[tag] = t
                if tag == ROUND_TRIP[-1]:
                    trips.append(current)
                    current = None
    return trips


def hand_overs(events) -> list[dict]:
    """The ``HAND_OVER`` stamps of each change k (the first of each tag; the
    steps from ``environment.lights`` on carry k + 1), complete ones only."""
    first = _first_stamps(events, HAND_OVER)
    changes = sorted({n for tag, n in first if tag == HAND_OVER[0]})
    complete = []
    for k in changes:
        stamps = {tag: first.get((tag, k if i < _NEXT_CHANGE else k + 1))
                  for i, tag in enumerate(HAND_OVER)}
        if all(v is not None for v in stamps.values()):
            complete.append(stamps)
    return complete


def _first_stamps(events, tags) -> dict[tuple[str, int], int]:
    """The time of the first stamp of each ``(tag, number)`` of ``tags`` (a re-sent
    copy of a message stamps again)."""
    first: dict[tuple[str, int], int] = {}
    for tag, t, number in events:
        if tag in tags:
            first.setdefault((tag, number), t)
    return first


def _summary(us) -> dict:
    """Count, mean, median and p90 of durations in us (``{"n": 0}`` for none)."""
    us = sorted(us)
    if not us:
        return {"n": 0}
    return {"n": len(us), "mean_us": statistics.fmean(us), "median_us": statistics.median(us),
            "p90_us": us[min(len(us) - 1, int(0.9 * len(us)))]}


def step_table(records: list[dict], tags) -> list[dict]:
    """Per step between consecutive ``tags``: count, mean, median, p90 (us) and
    the total (s) over ``records``."""
    rows = []
    for a, b in zip(tags, tags[1:]):
        us = [(r[b] - r[a]) / 1e3 for r in records]
        if not us:
            continue
        rows.append({"from": a, "to": b, **_summary(us), "total_s": sum(us) / 1e6})
    return rows


def idle_waits(events) -> dict:
    """Per change k: how long the agent sat idle, done with its own work
    (``agent.idle`` k), before the passive sensation of change k + 1 was
    published (``body.passive``; <= 0 when it was published first), and the
    hop of that sensation to the agent's callback (``agent.passive``) when the
    agent was already idle, i.e. a hop no work of the agent's delays. Count,
    mean, median and p90 (us) of each; the share of changes where the agent
    was idle first."""
    first = _first_stamps(events, (AGENT_IDLE, "body.passive", "agent.passive"))
    idle, hops = [], []
    for (tag, k), t_idle in first.items():
        if tag != AGENT_IDLE:
            continue
        passive, taken = first.get(("body.passive", k + 1)), first.get(("agent.passive", k + 1))
        if passive is None or taken is None:
            continue
        idle.append((passive - t_idle) / 1e3)
        if t_idle <= passive:
            hops.append((taken - passive) / 1e3)
    return {"idle_before_passive": _summary(idle), "passive_hop_when_idle": _summary(hops),
            "idle_first_share": len(hops) / len(idle) if idle else 0.0}
