"""bench/clock_study.py: the smallest interval it reports and the table it writes
(the explorations themselves are tests/core/test_clocked_agent.py's)."""
import sys

from shared import REPO
sys.path.insert(0, str(REPO))

from bench import clock_study  # noqa: E402


def _rows(coverages):
    return [{"interval": i, "coverage": c, "naive.distinct_positions": int(100 * c),
             "naive.clock.reactions": 5, "naive.clock.undone_reactions": 1,
             "naive.clock.false_detection_rate": 0.004}
            for i, c in coverages.items()]


def test_smallest_interval_is_where_coverage_stays_above_the_target():
    # 1,000 reaches 0.9 but 2,000 does not: coverage holds from 5,000 on only.
    rows = _rows({500: 0.2, 1000: 0.92, 2000: 0.85, 5000: 0.95, 10000: 0.97})
    assert clock_study.smallest(rows, 0.9) == 5000
    assert clock_study.smallest(_rows({500: 0.95, 1000: 0.96}), 0.9) == 500
    assert clock_study.smallest(_rows({500: 0.5, 1000: 0.8}), 0.9) is None


def test_table_has_a_column_per_interval():
    text = clock_study.table(_rows({250: 0.1, 2000: 0.9}))
    lines = text.splitlines()
    assert lines[0] == "| mean interval (rows) | 250 | 2000 |"
    assert "| reactions kept / undone | 5 / 1 | 5 / 1 |" in lines
    assert "| false detections | 0.4 % | 0.4 % |" in lines
    assert all(line.count("|") == 4 for line in lines)


def test_a_coverage_without_a_lockstep_to_compare_reaches_nothing():
    rows = [{"interval": i, "coverage": float("nan")} for i in (1000, 2000)]
    assert clock_study.smallest(rows, 0.9) is None
