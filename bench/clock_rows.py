"""Where an agent on the row clock spends its search and rank rows.

Runs ``sensorispace reproduce --strategy naive`` (any of its arguments; the
configuration must set ``world.clock: rows``) with counters around the
clocked agent's methods, which change nothing it does, and writes
``clock_rows.json`` beside the run's ``metrics.json``:

* ``req.<kind>`` / ``found.<kind>`` / ``newpov.<kind>``: the anchors asked,
  found and found as a new POV, by kind: ``confirmed`` (the anchor of a
  snapshot some POV matched), ``unconfirmed`` (of one none matched),
  ``frontier`` (a row of the latest confirmed snapshot no POV matched);
* ``search_rows.<kinds>`` / ``search_calls.<kinds>``: the rows of the
  searches (with the nearest known POVs they sense) of reactions asking
  those kinds;
* ``rank_rows.test_ranks`` (the matches' rank tests), ``rank_rows.rest_after``
  (the new resting state's), ``sweep_rows.known`` (the bounded sweeps);
* ``rank_rows.equality_pass`` / ``rank_tests.equality_pass``: simulation 2's
  rank tests of its matches (rows, states tested; undone reactions' too);
* ``search_cost.<kind>.<outcome>`` / ``search_count.<kind>.<outcome>``: the
  rows of the LM searches toward each target (its starts together; the
  nearest known POVs sensed after it not included) by kind and outcome:
  ``new`` (a new POV), ``known`` (a known POV), ``fail``;
* ``search_turns.<kind>.<outcome>.<n>``: searches by the starts that took
  a step (searched in turn: the turns taken);
* ``known_comp``: anchors a known POV matched (no search);
* ``reaction_rows.<outcome>`` / ``reactions.<outcome>``: the rows of the
  exploring reactions (their final checks not included) by outcome:
  ``new`` (kept, added a POV), ``compensated`` (kept, compensated toward
  known POVs only), ``nothing`` (kept, neither), ``undone`` (a change cut
  it; the POVs it salvaged not told apart);
* ``clock_trace.json``: (motor states, POVs, clock row, motor states by
  stage) after each kept reaction::

    nice -n 10 .venv/bin/python bench/clock_rows.py reproduce --strategy naive \\
        --config config/paper-clock.yaml --no-figures --quiet --out /tmp/clock_rows

``bench/clock_rows.py windows DIR [POVS ...]`` prints from DIR's trace the
motor states, kept reactions and rows by stage spent while the POVs known
went from one mark to the next (default marks 0, 100, ..., 500, 550, 584, 600, 620).
"""
from __future__ import annotations

import collections
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from bench.instrumented import run_instrumented  # noqa: E402

COUNTS: collections.Counter = collections.Counter()
TRACE: list = []        # (motor states, POVs, clock row, by stage) after each kept reaction


def _kinds(agent, requests, matches) -> list:
    return ["frontier" if r.row >= 0 else
            "confirmed" if len(matches[r.snapshot][0]) else "unconfirmed" for r in requests]


def instrument() -> None:
    """Wrap the clocked agent's methods with counters (``COUNTS``)."""
    from sensorispace_ros.core.naive.clocked_agent import ClockedAgent as Agent

    anchor_requests, search = Agent._anchor_requests, Agent._search
    test_ranks, rest_after, sweep_known = Agent._test_ranks, Agent._rest_after, Agent._sweep_known

    def counted_requests(self, matches, rest_hits, rank_now, current=None):
        known, requests = anchor_requests(self, matches, rest_hits, rank_now, current)
        if current is not None:
            self._bench_kinds = _kinds(self, requests, matches)
            COUNTS["known_comp"] += len(known)
        return known, requests

    search_plan, compensate = Agent._search_plan, Agent._compensate

    def planned(self, requests, current):
        plan = search_plan(self, requests, current)
        self._bench_plan = (list(requests), plan[0], plan[2])
        return plan

    def compensated(self, targets, starts, isolated):
        out = compensate(self, targets, starts, isolated)
        self._bench_queries = np.array(out.queries)
        return out

    def costs(self, requests, kinds, found, new):
        asked, group, owner = getattr(self, "_bench_plan", ([], [], []))
        queries = getattr(self, "_bench_queries", None)
        if queries is None or len(queries) != len(owner):
            return
        seen = set()
        for i, (request, kind) in enumerate(zip(requests, kinds)):
            at = next((j for j, r in enumerate(asked) if r is request), None)
            if at is None or group[at] in seen:
                continue
            seen.add(group[at])
            outcome = "fail" if i not in found else "new" if found[i][0] in new else "known"
            COUNTS[f"search_cost.{kind}.{outcome}"] += int(queries[owner == group[at]].sum())
            COUNTS[f"search_count.{kind}.{outcome}"] += 1
            mine = np.flatnonzero(owner == group[at])
            ran = int(np.count_nonzero(queries[mine] > queries.min()))
            COUNTS[f"search_turns.{kind}.{outcome}.{ran}"] += 1

    def counted_search(self, requests, current, tree, split_now):
        kinds = getattr(self, "_bench_kinds", ["?"] * len(requests))
        rows = self._body.rows
        before = rows.get("compensation", 0) + rows.get("sweep", 0)
        self._bench_plan, self._bench_queries = ([], [], []), None
        found, new, sensations = search(self, requests, current, tree, split_now)
        costs(self, requests, kinds, found, new)
        key = "+".join(sorted(set(kinds))) or "none"
        COUNTS["search_rows." + key] += rows.get("compensation", 0) + rows.get("sweep", 0) - before
        COUNTS["search_calls." + key] += 1
        for i, kind in enumerate(kinds):
            COUNTS["req." + kind] += 1
            if i in found:
                COUNTS["found." + kind] += 1
                COUNTS["newpov." + kind] += found[i][0] in new
        return found, new, sensations

    def rows_of(method, stage, key):
        def counted(self, *args, **kwargs):
            before = self._body.rows.get(stage, 0)
            out = method(self, *args, **kwargs)
            COUNTS[key] += self._body.rows.get(stage, 0) - before
            return out
        return counted

    from sensorispace_ros.core.naive.clock_equality import AllPairsSweep
    test_swept = AllPairsSweep._test

    def counted_test(self, *args):
        rows, tested = self.rows, self.tested
        test_swept(self, *args)
        COUNTS["rank_rows.equality_pass"] += self.rows - rows
        COUNTS["rank_tests.equality_pass"] += self.tested - tested

    from sensorispace_ros.core.clocked_run import ClockedRun
    react_agent, undo = Agent.react, ClockedRun._undo

    def counted_react(self, passive):
        before, stages = self.queries_total, self.queries_by_stage
        self._bench_outcome = None
        try:
            reaction = react_agent(self, passive)
        finally:
            self._bench_rows = self.queries_total - before
            self._bench_stages = {k: v - stages.get(k, 0) for k, v in self.queries_by_stage.items()}
        if self.phase == "exploring" or len(reaction.new_pov_ids) or reaction.compensations:
            self._bench_outcome = "new" if len(reaction.new_pov_ids) else \
                "compensated" if reaction.compensated else "nothing"
        return reaction

    def counted_undo(self, saved, rows_before, *args):
        if self.agent.phase == "exploring":
            COUNTS["reaction_rows.undone"] += self.agent.queries_total - rows_before
            COUNTS["reactions.undone"] += 1
            for stage, rows in self.agent.queries_by_stage.items():
                COUNTS[f"reaction_stage.undone.{stage}"] += rows - args[0].get(stage, 0)
        self.agent._bench_outcome = None
        undo(self, saved, rows_before, *args)

    react_run = ClockedRun.react

    def counted_run_react(self, sensed, reaction=None):
        agent = self.agent
        out = react_run(self, sensed, reaction)
        outcome = getattr(agent, "_bench_outcome", None)
        if outcome is not None:
            COUNTS["reaction_rows." + outcome] += getattr(agent, "_bench_rows", 0)
            COUNTS["reactions." + outcome] += 1
            for stage, rows in getattr(agent, "_bench_stages", {}).items():
                COUNTS[f"reaction_stage.{outcome}.{stage}"] += rows
        agent._bench_outcome = None
        TRACE.append((int(agent.queries_total), int(agent._store.count), int(self.body.row),
                      {k: int(v) for k, v in agent.queries_by_stage.items()}))
        return out

    AllPairsSweep._test = counted_test
    Agent.react, ClockedRun._undo, ClockedRun.react = counted_react, counted_undo, counted_run_react
    Agent._anchor_requests, Agent._search = counted_requests, counted_search
    Agent._search_plan, Agent._compensate = planned, compensated
    Agent._test_ranks = rows_of(test_ranks, "rank", "rank_rows.test_ranks")
    Agent._rest_after = rows_of(rest_after, "rank", "rank_rows.rest_after")
    Agent._sweep_known = rows_of(sweep_known, "sweep", "sweep_rows.known")


MARKS = (0, 100, 200, 300, 400, 500, 550, 584, 600, 620)


def windows(trace: list, marks=MARKS) -> list:
    """``[(first POVs, last POVs, motor states, kept reactions, {stage: rows})]``:
    what the agent spent while its POVs went from each mark to the next (the last
    window runs to the end of the trace)."""
    rows, previous = [], (0, 0, 0, {})
    for low, high in zip(marks, list(marks[1:]) + [float("inf")]):
        inside = [entry for entry in trace if low <= entry[1] < high]
        if not inside:
            continue
        last = inside[-1]
        stages = {k: v - previous[3].get(k, 0) for k, v in last[3].items()}
        rows.append((low, last[1], last[0] - previous[0], len(inside), stages))
        previous = last
    return rows


def print_windows(directory: str, marks=MARKS) -> None:
    trace = json.loads((Path(directory) / "clock_trace.json").read_text())
    stages = sorted({k for entry in trace for k in entry[3]})
    print("POVs       motor states  reactions  " + "  ".join(f"{k:>9}" for k in stages))
    for low, high, states, reactions, by_stage in windows(trace, marks):
        print(f"{low:>4}-{high:<4}  {states:>12,}  {reactions:>9}  " +
              "  ".join(f"{by_stage.get(k, 0):>{max(len(k), 9)},}" for k in stages))


def main() -> None:
    if sys.argv[1:2] == ["windows"]:
        marks = [int(m) for m in sys.argv[3:]] or MARKS
        print_windows(sys.argv[2], marks)
        return
    def write(out: Path):
        (out / "clock_rows.json").write_text(json.dumps(dict(COUNTS), indent=1, sort_keys=True))
        (out / "clock_trace.json").write_text(json.dumps(TRACE))
        print(json.dumps(dict(COUNTS), indent=1, sort_keys=True))

    run_instrumented(instrument, write)


if __name__ == "__main__":
    main()
