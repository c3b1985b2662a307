"""2-D points of view: a front that grows over the sensory level set.

Where the sensory Jacobian has rank ``M - 2`` a point of view is a surface in
the motor torus, its tangent plane the null space of ``J_s``. The cover
starts from the POV's own motor state and grows a front: every front knot
proposes ``DIRECTIONS`` states ``step`` away in its tangent plane, those not
already within ``SPACING * step`` of a knot are sensed with
their finite-difference stencils (one ``sense`` call for every front of the
batch), each is taken one Gauss-Newton step back onto the level set, and the
corrected ones that are still uncovered become the next front. A closed
surface is covered when the front is empty. Only the start is rank-tested:
the sensation is the same all over the POV, and how well the Jacobian is
conditioned changes along it with the body's configuration. A proposal
whose correction is larger than ``CORRECTION`` times its step (or infinite:
a blank) is retried at half that step, down to ``2**-HALVINGS`` of it
(where the surface curves hard, near a singular fibre); a direction that
fails then is an edge of what the front can reach, and a POV with an edge is
rejected (``NOT_CLOSED``), as is one that needs more than ``max_queries``
rows.

The knots then get ``polish_iterations`` more Gauss-Newton steps together
(one call each: the first with a fresh stencil, the others with that
Jacobian), and farthest-point sampling, from the POV's own state,
keeps ``n_samples`` of them spread evenly; a nearest-neighbour tour orders
them so that consecutive samples are close. Steps are in phases (a joint's
period is 2 pi); distances between knots are chord lengths of the torus.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.naive.jacobians import (NOT_CLOSED, RANK_DEFICIENT, VALID,
    SensoryPointsOfView, has_full_pose_rank, jacobian_stencil, minimum_norm_correction,
    repair_rows, sensory_jacobian, stencil_jacobian, stencil_rows)

TWO_PI = 2.0 * np.pi
DIRECTIONS = 6          # proposals per front knot, evenly round its tangent plane
SPACING = 0.7           # a proposal within SPACING * its step of a knot is covered
CORRECTION = 0.25       # largest accepted correction, relative to the step
HALVINGS = 3            # a failed direction is retried at 1/2, 1/4, 1/8 of the step


def cover_surfaces(body, start, *, rank, n_samples, fd_step, step, predictor_tol,
                   rank_ratio, min_singular, pattern_ratio, max_queries, polish_iterations,
                   sample_tol=np.inf):
    """``SensoryPointsOfView`` of 2-D POVs (see the module docstring);
    ``predictor_tol`` is unused (the correction bound is relative to ``step``)."""
    del predictor_tol
    cover = _Cover(body, start, rank=rank, fd_step=fd_step, step=step,
                   max_queries=max_queries,
                   rank_test=dict(rank_ratio=rank_ratio, min_singular=min_singular,
                                  pattern_ratio=pattern_ratio))
    cover.begin()
    while cover.active:
        cover.grow()
    max_residual = cover.polish(polish_iterations, sample_tol)
    samples = cover.samples(n_samples)
    reason = cover.reason
    return SensoryPointsOfView(samples=samples, valid=np.array([r == VALID for r in reason]),
                               reason=reason, queries=cover.queries, steps=cover.steps,
                               calls=cover.calls, max_residual=max_residual,
                               target_sensations=cover.target)


class _Cover:
    """One batch of surface covers: per POV its knots (unwrapped motor
    states, the first its own state) and their tangent planes, its front
    (knots still to expand, and half steps to retry), rows probed and
    outcome."""

    def __init__(self, body, start, *, rank, fd_step, step, max_queries, rank_test):
        self.body, self.start, self.rank = body, np.asarray(start, dtype=float), int(rank)
        self.fd_step, self.step, self.max_queries = fd_step, float(step), max_queries
        self.rank_test = rank_test
        n_pov = len(self.start)
        self.queries = np.zeros(n_pov, dtype=int)
        self.steps = np.zeros(n_pov, dtype=int)
        self.reason = [VALID] * n_pov
        self.knots = [s[None].copy() for s in self.start]
        self.embedded = [_embed(s[None]) for s in self.start]    # knots on the unit circles
        self._trees: dict[int, cKDTree] = {}                     # this generation's, per POV
        self.tangent: list[np.ndarray] = []          # per POV (knots, 2, M)
        self.front = [np.zeros(0, dtype=int) for _ in range(n_pov)]
        self.retry: list[list] = [[] for _ in range(n_pov)]   # (knot, failed state, halvings)
        self.calls = 0

    @property
    def active(self) -> list[int]:
        return [p for p in range(len(self.start))
                if self.reason[p] == VALID and (len(self.front[p]) or self.retry[p])]

    def begin(self) -> None:
        self.target, jac, _ = sensory_jacobian(self.body, self.start, self.fd_step)
        self.calls += 1
        self.queries += self.start.shape[1] + 1
        full = has_full_pose_rank(jac, self.rank, sensations=self.target, **self.rank_test)
        _, basis = _correction_and_plane(jac, np.zeros(self.target.shape), self.rank)
        self.tangent = [basis[p][None].copy() for p in range(len(self.start))]
        for p in range(len(self.start)):
            if full[p]:
                self.front[p] = np.zeros(1, dtype=int)
            else:
                self.reason[p] = RANK_DEFICIENT

    def grow(self) -> None:
        """One call: every front knot's proposals, sensed, corrected, kept
        where still uncovered."""
        self._trees = {p: cKDTree(self.embedded[p]) for p in self.active}
        owner, parent, level, proposal = self._proposals()
        self.front = [np.zeros(0, dtype=int) for _ in self.front]
        self.retry = [[] for _ in self.retry]
        if not len(proposal):
            return
        n_motors = proposal.shape[1]
        sensed = np.asarray(self.body.sense(jacobian_stencil(proposal, self.fd_step)), dtype=float)
        self.calls += 1
        rows = stencil_rows(n_motors, self.fd_step)
        sensation, jac = stencil_jacobian(sensed.reshape(len(proposal), rows, -1), self.fd_step)
        correction, plane = _correction_and_plane(jac, sensation - self.target[owner], self.rank)
        with np.errstate(over="ignore", invalid="ignore"):
            size = np.linalg.norm(correction, axis=1)
        reach = self.step * 0.5 ** level
        good = np.isfinite(size) & (size <= CORRECTION * reach)
        np.add.at(self.queries, owner, rows)
        for p in np.unique(owner):
            mine = owner == p
            if self.queries[p] > self.max_queries or np.any(mine & ~good & (level >= HALVINGS)):
                self.reason[p] = NOT_CLOSED      # out of budget, or an edge it cannot pass
                continue
            failed = np.flatnonzero(mine & ~good)
            self.retry[p] = [(parent[k], proposal[k], level[k]) for k in failed]
            self._keep(p, np.flatnonzero(mine & good), proposal, correction, plane, reach)

    def _keep(self, p, rows, proposal, correction, plane, reach) -> None:
        """Add the corrected proposals ``rows`` of POV ``p`` that no knot
        (nor one added before them) covers within ``SPACING`` times their
        step ``reach``; they are its next front."""
        knots = proposal[rows] + correction[rows]
        embedded = _embed(knots)
        radius = SPACING * reach[rows]
        free = np.flatnonzero(_uncovered(embedded, self._trees[p], radius))
        kept = free[_greedy_apart(embedded[free], radius[free])]
        if not len(kept):
            return
        first = len(self.knots[p])
        self.knots[p] = np.vstack([self.knots[p], knots[kept]])
        self.embedded[p] = np.vstack([self.embedded[p], embedded[kept]])
        self.tangent[p] = np.concatenate([self.tangent[p], plane[rows[kept]]])
        self.front[p] = np.arange(first, first + len(kept))
        self.steps[p] += len(kept)

    def _proposals(self):
        """``(owner POV, parent knot, halvings of the step, state)`` of every
        proposal not already covered: ``DIRECTIONS`` round each front knot in
        its tangent plane, and half steps toward the proposals that failed."""
        owner, parent, level, proposal = [], [], [], []
        angle = TWO_PI * np.arange(DIRECTIONS) / DIRECTIONS
        for p in self.active:
            knots, front = self.knots[p], self.front[p]
            if len(front):
                basis = self.tangent[p][front]
                ring = (np.cos(angle)[None, :, None] * basis[:, None, 0]
                        + np.sin(angle)[None, :, None] * basis[:, None, 1])
                states = (knots[front][:, None] + self.step * ring).reshape(-1, knots.shape[1])
                free = _uncovered(_embed(states), self._trees[p], SPACING * self.step)
                owner += [p] * int(free.sum())
                parent += list(np.repeat(front, DIRECTIONS)[free])
                level += [0] * int(free.sum())
                proposal += list(states[free])
            for k, failed, halvings in self.retry[p]:
                owner.append(p)
                parent.append(k)
                level.append(halvings + 1)
                proposal.append(0.5 * (knots[k] + failed))
        n_motors = self.start.shape[1]
        return (np.asarray(owner, dtype=int), np.asarray(parent, dtype=int),
                np.asarray(level, dtype=int),
                np.asarray(proposal, dtype=float).reshape(-1, n_motors))

    def polish(self, iterations: int, sample_tol: float = np.inf) -> float:
        """Gauss-Newton steps on every knot of the covered POVs (the first
        knot, the POV's own state, stays): the first with a fresh Jacobian
        (its stencil in the same call), the others with that one; knots whose
        last step is above ``sample_tol`` get fresh ones
        (``jacobians.repair_rows``), and a POV whose knots do not come back
        is not kept. Returns the largest sensory error before the last step."""
        good = [p for p in range(len(self.start)) if self.reason[p] == VALID]
        max_residual = 0.0
        counts = [len(self.knots[p]) - 1 for p in good]
        if not good or iterations == 0 or not sum(counts):
            return max_residual
        flat = np.concatenate([self.knots[p][1:] for p in good])
        target = np.repeat(self.target[good], counts, axis=0)
        jac = None
        for _ in range(iterations):
            if jac is None:
                sensation, jac, rows = sensory_jacobian(self.body, flat, self.fd_step)
            else:
                sensation, rows = np.asarray(self.body.sense(flat), dtype=float), len(flat)
            self.calls += 1
            for p, c in zip(good, counts):
                self.queries[p] += rows // len(flat) * c
            residual = sensation - target
            max_residual = float(np.max(np.linalg.norm(residual, axis=1)))
            step = minimum_norm_correction(jac, residual, self.rank)
            flat = flat + step
        with np.errstate(invalid="ignore"):
            stray = np.flatnonzero(~(np.linalg.norm(step, axis=1) <= sample_tol))
        self._repair(flat, target, stray, np.repeat(good, counts), sample_tol)
        for p, chunk in zip(good, np.split(flat, np.cumsum(counts)[:-1])):
            self.knots[p] = np.vstack([self.knots[p][:1], chunk])
        return max_residual

    def _repair(self, flat, target, stray, owner, sample_tol) -> None:
        calls, sensed, failed = repair_rows(self.body, flat, target, stray, rank=self.rank,
                                            fd_step=self.fd_step, tol=sample_tol)
        self.calls += calls
        for rows in sensed:
            np.add.at(self.queries, owner[rows], self.start.shape[1] + 1)
        for p in np.unique(owner[failed]):
            self.reason[p] = NOT_CLOSED

    def samples(self, n_samples: int) -> np.ndarray:
        """``(P, n_samples, M)``: every covered POV's knots thinned to
        ``n_samples`` by farthest-point sampling from its own state and
        ordered by a nearest-neighbour tour (the start first); the others
        repeat their start."""
        out = np.repeat(self.start[:, None, :], n_samples, axis=1)
        for p in range(len(self.start)):
            if self.reason[p] == VALID:
                chosen = self.knots[p][farthest_points(self.knots[p], n_samples)]
                out[p] = chosen[nearest_tour(chosen)]
        return out


def _correction_and_plane(jacobians: np.ndarray, residuals: np.ndarray, rank: int):
    """``minimum_norm_correction`` and the tangent plane (two unit null
    vectors, ``(B, 2, M)``) of each Jacobian, from one SVD."""
    u, singular, right = np.linalg.svd(jacobians)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        coeff = np.einsum("bsk,bs->bk", u[:, :, :rank], residuals) / singular[:, :rank]
    return -np.einsum("bk,bkm->bm", coeff, right[:, :rank, :]), right[:, rank:rank + 2, :]


def farthest_points(points: np.ndarray, count: int) -> np.ndarray:
    """Indices of ``count`` of ``points`` ``(n, M)`` chosen greedily, each the
    farthest (chord metric of the torus) from those chosen before, the first
    first; with fewer points than ``count`` they repeat in turn."""
    n = len(points)
    if n <= count:
        return np.arange(count) % n
    embedded = _embed(points)
    chosen = np.zeros(count, dtype=int)
    # |e_a - e_b|^2 = 2 M - 2 e_a . e_b: the largest distance is the smallest product.
    closeness = embedded @ embedded[0]
    for k in range(1, count):
        chosen[k] = int(np.argmin(closeness))
        np.maximum(closeness, embedded @ embedded[chosen[k]], out=closeness)
    return chosen


def nearest_tour(points: np.ndarray) -> np.ndarray:
    """An order of ``points`` from the first, each next the nearest unvisited
    (chord metric of the torus)."""
    embedded = _embed(points)
    order = np.zeros(len(points), dtype=int)
    visited = np.zeros(len(points), dtype=bool)
    visited[0] = True
    for k in range(1, len(points)):
        closeness = embedded @ embedded[order[k - 1]]
        closeness[visited] = -np.inf
        order[k] = int(np.argmax(closeness))
        visited[order[k]] = True
    return order


def _embed(states: np.ndarray) -> np.ndarray:
    """Each coordinate on its unit circle: ``(..., 2M)``. Euclidean distances
    there are chord lengths of the torus (the torus distance, to within
    ``d^3 / 24``)."""
    return np.concatenate([np.cos(states), np.sin(states)], axis=-1)


def _uncovered(embedded: np.ndarray, tree: cKDTree, radius) -> np.ndarray:
    """Which states (``embedded`` by ``_embed``) have no knot of ``tree``
    within ``radius`` (one, or one per state)."""
    radius = np.broadcast_to(np.asarray(radius, dtype=float), (len(embedded),))
    if not len(embedded):
        return np.zeros(0, dtype=bool)
    distance, _ = tree.query(embedded, k=1, distance_upper_bound=float(np.max(radius)))
    return ~(distance < radius)


def _greedy_apart(embedded: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Indices of ``embedded`` kept in order, each farther than its
    ``radius`` from every one kept before it."""
    if not len(embedded):
        return np.zeros(0, dtype=int)
    neighbours: dict[int, list[int]] = {}
    for i, j in cKDTree(embedded).query_pairs(float(np.max(radius)), output_type="ndarray"):
        neighbours.setdefault(int(max(i, j)), []).append(int(min(i, j)))
    kept = np.zeros(len(embedded), dtype=bool)
    for i in range(len(embedded)):
        earlier = neighbours.get(i, ())
        kept[i] = not any(kept[j] and np.linalg.norm(embedded[i] - embedded[j]) < radius[i]
                          for j in earlier)
    return np.flatnonzero(kept)
