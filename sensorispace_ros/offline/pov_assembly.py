"""Points of view and equality sets from the agent's tables, and a
representation as arrays: the one assembly the representation node, the
analysis of a bag and the run files share (no rclpy).

A POV table has the columns of ``/agent/points_of_view`` (pov, sample,
m0..m{M-1}); an equality table those of ``/agent/compensations`` (set,
pov_from, pov_to), POVs named by id. The representation indexes POVs by
position in the sorted ids.
"""
from __future__ import annotations

import numpy as np

# Fewest points of view a representation is built from (offline.representation).
MIN_POVS = 4


def assemble_points_of_view(tables: list[np.ndarray], n_motors: int
                            ) -> tuple[np.ndarray, np.ndarray]:
    """POV ids (sorted) and motor samples ``(n_povs, n_samples, n_motors)`` from
    row tables (columns pov, sample, m0..m{n_motors-1})."""
    if not tables:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 0, n_motors))
    rows = np.concatenate(tables)
    ids = np.unique(rows["pov"]).astype(np.int64)
    n_samples = int(rows["sample"].max()) + 1
    motor = np.full((len(ids), n_samples, n_motors), np.nan)
    where = np.searchsorted(ids, rows["pov"])
    for j in range(n_motors):
        motor[where, rows["sample"], j] = rows[f"m{j}"]
    if np.isnan(motor).any():
        raise ValueError("some point of view misses samples")
    return ids, motor


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
