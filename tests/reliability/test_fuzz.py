"""Hostile input: ~15 s of malformed messages on every subscribed
topic of a running smoke graph (5 per second per topic, huge batches every 2 s,
exact duplicates of real messages). No node may die, RSS stays below
2 x start + 200 MB, and the run's result equals the undisturbed run.
The full 60 s acceptance run: ``python tests/reliability/fuzz_graph.py --seconds 60``."""
from __future__ import annotations

import pytest

from .fuzz_graph import _subscribed_topics, rss_bounded, run_fuzz
from .node_processes import assert_same_result

pytestmark = [pytest.mark.graph, pytest.mark.slow]


@pytest.mark.timeout(400)
def test_fifteen_seconds_of_hostile_input_change_nothing(tmp_path, single_host_result):
    report = run_fuzz(seconds=15, rate_hz=5.0, work_dir=tmp_path)
    assert not report["died"], report
    every = set(_subscribed_topics())
    assert set(report["sent_per_topic"]) == every, report["sent_per_topic"]
    assert min(report["sent_per_topic"].values()) >= 50, report["sent_per_topic"]
    for kind in ("random_bytes", "wrong_width", "bad_fields", "bad_frame", "nonfinite",
                 "duplicate", "settled_unknown", "bad_description"):
        assert report["sent_by_kind"].get(kind, 0) > 0, (kind, report["sent_by_kind"])
    assert report["sent_by_kind"].get("huge_nonfinite", 0) + \
        report["sent_by_kind"].get("huge_wrong_width", 0) >= 6
    assert not rss_bounded(report), report
    from .fuzz_graph import DUPLICATED
    for topic in DUPLICATED:
        assert report["duplicates_per_topic"].get(topic, 0) > 0, (topic, report)
    assert report["result"] is not None, "the fuzzed run did not finish"
    assert_same_result(report["result"], single_host_result)
