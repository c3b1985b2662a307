"""The lattice points next to the agent's POVs that no POV holds yet.

``HoleMap`` keeps the agent's POVs on their lattice (``lattice``): which
point each known POV holds, which empty points its searches failed to
reach and how often. Given a snapshot's rows and the displacement one of
its matches shows now (a matched pair's lattice difference), every row's
target lies at a lattice point: a known POV's (no search needed), or an
empty one. The empty points with the most known neighbours come first:
a hole inside what the agent knows is reachable, a point past its edge
may not be (``candidates``). A point whose searches failed
``max_fails`` times is given up.

The lattice is measured again from the equality sets when POVs the map
does not place have piled up; the failures are carried over through the
integer affine map between the two coordinate systems (``_regauge``).
"""
from __future__ import annotations

import itertools

import numpy as np

from sensorispace_ros.core.naive.lattice import Lattice, consecutive_pairs

__all__ = ["Candidate", "HoleMap"]


class Candidate(tuple):
    """``(point, row, snapshot, neighbour)``: the empty lattice ``point`` (a
    tuple) the target of ``row`` of snapshot ``snapshot`` lies at, and the
    known POV ``neighbour`` a search toward it starts from: of those next to
    it along an axis (else diagonally), the one known first; whatever basis the
    lattice was measured in, the same POV."""

    point = property(lambda self: self[0])
    row = property(lambda self: self[1])
    snapshot = property(lambda self: self[2])
    neighbour = property(lambda self: self[3])


class HoleMap:
    """Known POVs on their lattice, and the empty points searched in vain."""

    def __init__(self, lattice: Lattice, n_sets: int):
        self.ij = lattice.ij.copy()
        self.placed = lattice.placed.copy()
        self.fails: dict[tuple, int] = {}
        self.found = 0              # POVs placed where a search toward an empty point found them
        self.n_sets = int(n_sets)
        self._offsets = np.array([o for o in itertools.product((-1, 0, 1), repeat=lattice.dim)
                                  if any(o)], dtype=int)

    @property
    def unplaced(self) -> int:
        """Known POVs the map does not place."""
        return int(len(self.placed) - np.count_nonzero(self.placed))

    def grow(self, n_povs: int) -> None:
        """Room for ``n_povs`` POVs, the new ones not placed."""
        extra = n_povs - len(self.placed)
        if extra > 0:
            self.ij = np.vstack([self.ij, np.zeros((extra, self.ij.shape[1]), dtype=int)])
            self.placed = np.concatenate([self.placed, np.zeros(extra, dtype=bool)])

    def place(self, pov: int, point) -> None:
        """POV ``pov`` holds lattice point ``point`` (a search toward it found it)."""
        self.grow(pov + 1)
        self.ij[pov] = point
        self.placed[pov] = True
        self.found += 1

    def failed(self, point) -> None:
        """A search toward ``point`` found no new POV there."""
        point = tuple(int(v) for v in point)
        self.fails[point] = self.fails.get(point, 0) + 1

    def remeasured(self, lattice: Lattice, n_sets: int) -> "HoleMap":
        """A map on ``lattice`` (measured again) with these failures carried over."""
        fresh = HoleMap(lattice, n_sets)
        fresh.fails, fresh.found = self._regauge(fresh), self.found
        return fresh

    def _regauge(self, fresh: "HoleMap") -> dict:
        """The failures in ``fresh``'s coordinates: the integer affine map
        between the two, fitted on the POVs both place (none if it is not one)."""
        n = min(len(self.placed), len(fresh.placed))
        both = np.flatnonzero(self.placed[:n] & fresh.placed[:n])
        if not self.fails or len(both) <= self.ij.shape[1] + 1:
            return {}
        old = np.c_[self.ij[both], np.ones(len(both))]
        coef = np.round(np.linalg.lstsq(old, fresh.ij[both].astype(float), rcond=None)[0])
        if np.any(old @ coef != fresh.ij[both]):
            return {}
        points = np.array(list(self.fails), dtype=float)
        moved = np.round(np.c_[points, np.ones(len(points))] @ coef).astype(int)
        return {tuple(int(v) for v in p): n for p, n in zip(moved, self.fails.values())}

    def contradicted(self, pairs: np.ndarray, set_ids: np.ndarray) -> bool:
        """Whether an equality set ``pairs`` ``(K, 2)`` / ``set_ids`` holds two
        pairs of POVs the map places that it moves by different lattice steps."""
        pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
        set_ids = np.asarray(set_ids, dtype=int).reshape(-1)
        known = np.all(pairs < len(self.placed), axis=1)
        known[known] = np.all(self.placed[pairs[known]], axis=1)
        first, second = consecutive_pairs(pairs[known], set_ids[known])
        steps = self.ij[first[:, 1]] - self.ij[first[:, 0]]
        return bool(np.any(steps != self.ij[second[:, 1]] - self.ij[second[:, 0]]))

    def displacement(self, before: np.ndarray, after: np.ndarray):
        """The lattice step of a snapshot's matches ``before -> after`` (POV
        indices), where every pair the map places agrees; else None."""
        both = self.placed[before] & self.placed[after]
        if not np.any(both):
            return None
        steps = self.ij[after[both]] - self.ij[before[both]]
        return steps[0] if np.all(steps == steps[0]) else None

    def row_targets(self, rows: np.ndarray, step):
        """The targets of POV ``rows`` ``(R,)`` moved by the lattice ``step``:
        ``(points (R, d), known (R,), neighbours (R,))``: each row's point,
        whether a known POV holds it, and how many known POVs lie next to it
        (-1 where the map does not place the row)."""
        rows = np.asarray(rows, dtype=int)
        known = self._known()
        points = self.ij[rows] + np.asarray(step, dtype=int)
        held = np.array([tuple(p) in known for p in points.tolist()], dtype=bool)
        near = np.array([len(self._known_next_to(p, known)) for p in points.tolist()],
                        dtype=int).reshape(-1)
        placed = self.placed[rows]
        return points, held & placed, np.where(placed, near, -1)

    def _known(self) -> dict:
        """``{point: POV}`` of the POVs the map places."""
        return {tuple(p): i for i, p in enumerate(self.ij.tolist()) if self.placed[i]}

    def _known_next_to(self, point, known: dict) -> list:
        """``[(lattice steps away, POV), ...]``: the POVs of ``known`` next
        to ``point`` (along an axis or diagonally)."""
        return [(sum(map(abs, o)), known[q]) for o, q in
                zip(self._offsets.tolist(), map(tuple, (np.array(point) + self._offsets).tolist()))
                if q in known]

    def candidates(self, rows_by_snapshot, max_fails: int) -> list[Candidate]:
        """``rows_by_snapshot`` ``[(snapshot, rows (POV indices), step), ...]``
        (most recent first): the empty points their targets lie at, each once,
        not given up, next to at least one known POV; the most known
        neighbours first, then the fewest failures."""
        known = self._known()
        found: dict[tuple, tuple] = {}
        for snapshot, rows, step in rows_by_snapshot:
            rows = np.asarray(rows, dtype=int)
            rows = rows[self.placed[rows]]
            for row, point in zip(rows, (self.ij[rows] + step).tolist()):
                point = tuple(point)
                if point in known or point in found or self.fails.get(point, 0) >= max_fails:
                    continue
                near = self._known_next_to(point, known)
                if near:
                    found[point] = (len(near), self.fails.get(point, 0), int(row), snapshot,
                                    min(near)[1])
        ranked = sorted(found.items(), key=lambda item: (-item[1][0], item[1][1]))
        return [Candidate((point, row, snapshot, neighbour))
                for point, (_, _, row, snapshot, neighbour) in ranked]
