"""The equality rows the representation node and a bag's analysis build
from the agent's tables (offline/pov_assembly.py)."""
import numpy as np

from sensorispace_ros.offline.pov_assembly import net_equality_rows

DTYPE = np.dtype([("set", "<u4"), ("pov_from", "<u4"), ("pov_to", "<u4")])


def _table(*rows):
    return np.array([tuple(r) for r in rows], dtype=DTYPE)


def test_withdrawn_rows_leave_and_the_rest_keep_their_order():
    tables = {"change/1": _table((0, 1, 2), (0, 3, 4), (1, 1, 3)),
              "change/2": _table((1, 2, 4), (2, 5, 6)),
              "end/3": _table((3, 1, 5), (3, 2, 6)),
              "withdrawn/3": _table((0, 3, 4), (2, 5, 6))}
    rows = net_equality_rows(tables, DTYPE)
    assert rows.tolist() == [(0, 1, 2), (1, 1, 3), (1, 2, 4), (3, 1, 5), (3, 2, 6)]


def test_a_withdrawn_row_names_set_and_both_povs():
    # The same two POVs in another set, or the other way round, stay.
    tables = {"change/1": _table((0, 1, 2), (1, 1, 2), (0, 2, 1)),
              "withdrawn/2": _table((0, 1, 2))}
    assert net_equality_rows(tables, DTYPE).tolist() == [(1, 1, 2), (0, 2, 1)]


def test_without_withdrawn_rows_every_row_stays_and_none_gives_an_empty_table():
    tables = {"change/1": _table((0, 1, 2)), "end/2": _table((1, 3, 4))}
    assert net_equality_rows(tables, DTYPE).tolist() == [(0, 1, 2), (1, 3, 4)]
    empty = net_equality_rows({}, DTYPE)
    assert empty.dtype == DTYPE and len(empty) == 0
    only_gone = net_equality_rows({"withdrawn/1": _table((0, 1, 2))}, DTYPE)
    assert len(only_gone) == 0
