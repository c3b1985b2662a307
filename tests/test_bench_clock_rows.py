"""bench/clock_rows.py's windows: what a trace of the clocked agent spent
between marks of the POVs it knew."""
import sys

from shared import REPO
sys.path.insert(0, str(REPO))

from bench import clock_rows  # noqa: E402

# (motor states, POVs, clock row, motor states by stage) after each kept reaction.
TRACE = [(100, 1, 150, {"sweep": 40, "pov": 60}),
         (250, 3, 400, {"sweep": 90, "pov": 160}),
         (300, 3, 700, {"sweep": 140, "pov": 160}),
         (420, 5, 900, {"sweep": 160, "pov": 260}),
         (500, 7, 1200, {"sweep": 200, "pov": 300}),
         (560, 7, 1500, {"sweep": 260, "pov": 300})]


def test_each_window_spends_what_its_last_reaction_added_to_the_one_before():
    rows = clock_rows.windows(TRACE, marks=(0, 4, 6))
    assert [(low, high, states, reactions) for low, high, states, reactions, _ in rows] == \
        [(0, 3, 300, 3), (4, 5, 120, 1), (6, 7, 140, 2)]
    assert [by_stage for *_, by_stage in rows] == \
        [{"sweep": 140, "pov": 160}, {"sweep": 20, "pov": 100}, {"sweep": 100, "pov": 40}]
    # The windows add up to the whole trace.
    assert sum(states for _, _, states, _, _ in rows) == TRACE[-1][0]


def test_a_mark_no_reaction_fell_in_gives_no_window():
    rows = clock_rows.windows(TRACE, marks=(0, 2, 3, 8))
    assert [(low, high) for low, high, *_ in rows] == [(0, 1), (3, 7)]
    assert rows[1][2] == 560 - 100
