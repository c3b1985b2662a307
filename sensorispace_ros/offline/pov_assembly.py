"""Points of view and equality sets from the agent's tables, and a
representation as arrays: the one assembly the representation node, the
analysis of a bag and the run files share (no rclpy).

A POV table has the columns of ``/agent/points_of_view`` (pov, sample,
m0..m{M-1}); an equality table those of ``/agent/compensations`` (set,
pov_from, pov_to), POVs named by id; a ``withdrawn/<k>`` table withdraws
rows published before it. The representation indexes POVs by position in
the sorted ids.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.protocol import WITHDRAWN, parse_frame

# Fewest points of view a representation is built from (offline.representation).
MIN_POVS = 4


def assemble_points_of_view(tables: list[np.ndarray], n_motors: int, moved=()
                            ) -> tuple[np.ndarray, np.ndarray]:
    """POV ids (sorted) and motor samples ``(n_povs, n_samples, n_motors)`` from
    row tables (columns pov, sample, m0..m{n_motors-1}); the rows of the
    tables ``moved`` (POVs the agent moved at the end of its run) then
    replace those of the same POV and sample."""
    if not tables:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 0, n_motors))
    rows = np.concatenate(tables)
    ids = np.unique(rows["pov"]).astype(np.int64)
    n_samples = int(rows["sample"].max()) + 1
    motor = np.full((len(ids), n_samples, n_motors), np.nan)
    _fill(motor, ids, rows, n_motors)
    if np.isnan(motor).any():
        raise ValueError("some point of view misses samples")
    for table in moved:
        if not np.isin(table["pov"], ids).all() or table["sample"].max() >= n_samples:
            raise ValueError("a moved point of view was never published whole")
        _fill(motor, ids, table, n_motors)
    return ids, motor


def _fill(motor: np.ndarray, ids: np.ndarray, rows: np.ndarray, n_motors: int) -> None:
    """Write the samples of ``rows`` into ``motor`` (POVs by position in ``ids``)."""
    where = np.searchsorted(ids, rows["pov"])
    for j in range(n_motors):
        motor[where, rows["sample"], j] = rows[f"m{j}"]


def net_equality_rows(tables: dict, dtype) -> np.ndarray:
    """The rows of ``/agent/compensations`` tables (frame id -> table, in the
    order received) less every row a ``withdrawn/<k>`` table names (same
    set, pov_from and pov_to); ``dtype``: the rows' when there is none."""
    kinds = {frame_id: (parse_frame(frame_id) or ("",))[0] for frame_id in tables}
    kept = [table for frame_id, table in tables.items() if kinds[frame_id] != WITHDRAWN]
    gone = [table for frame_id, table in tables.items() if kinds[frame_id] == WITHDRAWN]
    rows = np.concatenate(kept) if kept else np.zeros(0, dtype=dtype)
    if not gone or not len(rows):
        return rows
    return rows[~np.isin(_row_keys(rows), _row_keys(np.concatenate(gone)))]


def _row_keys(rows: np.ndarray) -> np.ndarray:
    """One comparable key per equality row: its (set, pov_from, pov_to)."""
    triples = np.column_stack([rows["set"], rows["pov_from"], rows["pov_to"]]).astype(np.int64)
    return np.ascontiguousarray(triples).view(np.dtype((np.void, 24))).ravel()


def equality_pairs(ids: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(pairs (K, 2), set_ids (K,))`` of equality rows, POVs by position in ``ids``."""
    pairs = np.stack([np.searchsorted(ids, rows["pov_from"]),
                      np.searchsorted(ids, rows["pov_to"])], axis=-1).astype(np.int64)
    return pairs.reshape(-1, 2), np.asarray(rows["set"]).astype(np.int64)


def embedding_arrays(representation) -> dict:
    """A ``Representation``'s embeddings as the arrays a run keeps
    (``embedding_<dim>_before``, ``embedding_<dim>_iterations``, ``set_spread_<dim>``)."""
    arrays = {}
    for dim in representation.before:
        arrays[f"embedding_{dim}_before"] = representation.before[dim]
        arrays[f"embedding_{dim}_iterations"] = representation.iterations[dim]
        arrays[f"set_spread_{dim}"] = representation.set_spread[dim]
    return arrays
