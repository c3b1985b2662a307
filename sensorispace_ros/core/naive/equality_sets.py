"""Equality sets from sensation matching (naive simulation 2).

The paper's second simulation (Sec. 4.4) finds, for one object displacement
e_i -> e_i+1, the POV changes M_ij -> M_i+1,j that compensate it from many
starting POVs; those changes have equal external length, and the metric is
regularised to make their internal lengths equal. The paper finds the
compensating POV from the known sensor displacement. The naive agent does
not know it. It senses one sample of every known POV before and after the
change (one ``sense`` call each): POV j' after the change generating the
sensation POV j generated before it means the eye at j' sees the moved
object as it saw the unmoved one from j, i.e. pose(j') - pose(j) is the
object's displacement, the same for every matched pair of that change.

A match is trusted only if it is unique (no other POV's sensation near
either side) and the sensation pins the sensor's configuration: the sensory
Jacobian at j' has the body's pose rank as the agent measured it
(``structure``; a blank or one-light sensation matches many poses). The
tolerances are in the units of the sensations: the agent passes
motor-equivalent amounts times its measured gain (``structure.Tolerances``). The rank
at j' after the change equals the rank at j before it (same relative pose,
same light layout), so a rank found once is carried along the matches
instead of being measured again.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2, norm

from sensorispace_ros.core.naive.jacobians import has_full_pose_rank, sensory_jacobian

RANK_UNKNOWN = -1
RANK_DEFICIENT = 0
RANK_FULL = 1


# Where a lost (non-finite) sensation is put so it matches nothing: far from
# every sensation and from the other side's lost rows; its squares stay finite.
LOST_ROW = 1e150


def finite_rows(rows: np.ndarray, side: float = 1.0) -> np.ndarray:
    """``rows`` with every row holding a non-finite value moved to
    ``side * LOST_ROW`` (a copy when any is), for trees and matches."""
    rows = np.asarray(rows, dtype=float)
    lost = ~np.all(np.isfinite(rows), axis=-1)
    if not lost.any():
        return rows
    rows = rows.copy()
    rows[lost] = side * LOST_ROW
    return rows


def match_sensations(reference: np.ndarray, current: np.ndarray, *, match_tol: float = 1e-6,
                     separation: float = 1e-4, tree: cKDTree | None = None,
                     ratio: float = 0.0):
    """Unique one-to-one matches between two sets of sensations.

    Returns ``(reference_index, current_index)``: row ``i`` of ``reference``
    matches row ``j`` of ``current`` when ``|reference[i] - current[j]| <=
    match_tol``, no other current row lies within ``separation`` of
    ``reference[i]`` (with ``ratio > 0``: nor within ``ratio`` times the
    matched distance; a tolerance wide enough for noisy chains of poses
    then still tells a match from its neighbours), and no other reference
    row matches ``current[j]``.
    ``tree``: a ``cKDTree`` of ``finite_rows(current, -1)`` to reuse across
    calls. A lost (non-finite) row matches nothing.
    """
    if not 0 < match_tol or not (match_tol < separation or ratio > 0):
        raise ValueError(f"match_tol must be > 0 and < separation ({separation}), "
                         f"got {match_tol}")
    reference = np.asarray(reference, dtype=float)
    empty = np.zeros(0, dtype=int)
    if len(reference) == 0 or len(current) == 0:
        return empty, empty
    # A bounded sweep leaves most rows lost: only the others are queried.
    kept = np.flatnonzero(np.all(np.isfinite(reference), axis=-1))
    if len(kept) < len(reference):
        ref_idx, cur_idx = match_sensations(reference[kept], current, match_tol=match_tol,
                                            separation=separation, tree=tree, ratio=ratio)
        return kept[ref_idx], cur_idx
    tree = cKDTree(finite_rows(current, -1.0)) if tree is None else tree
    # Most rows match nothing: a bounded nearest-neighbour query prunes them
    # fast; only the candidates get the (k = 2) uniqueness query.
    distance, index = tree.query(reference, k=1, distance_upper_bound=match_tol)
    candidate = np.flatnonzero(np.isfinite(distance))
    near = np.zeros(len(reference), dtype=bool)
    index = np.where(np.isfinite(distance), index, 0)
    if len(candidate):
        if len(current) == 1:
            near[candidate] = True
        else:
            reach = max(separation, ratio * match_tol)
            second, _ = tree.query(reference[candidate], k=2, distance_upper_bound=reach)
            clear = np.maximum(separation, ratio * distance[candidate])
            near[candidate] = ~(second[:, 1] <= clear)
    ref_idx = np.flatnonzero(near)
    cur_idx = index[near]
    # Two reference rows on one current row: neither is a trustworthy match.
    counts = np.bincount(cur_idx, minlength=len(current))
    single = counts[cur_idx] == 1
    return ref_idx[single], cur_idx[single]


def noisy_matches(reference: np.ndarray, current: np.ndarray, *, reference_var: np.ndarray,
                  current_var: np.ndarray, confidence: float, tree: cKDTree | None = None):
    """Unique one-to-one matches between two sets of noisy sensations, by a
    statistical test against their measured noise instead of a tolerance.

    Row ``i`` of ``reference`` (per-receptor noise variance ``reference_var[i]``,
    the measured ``sd^2`` over the sensings averaged in it) matches row ``j``
    of ``current`` (``current_var[j]``) when

    * their difference is what the noise of the two explains: ``|r - c|^2 /
      (var_r + var_c)`` within the ``confidence`` quantile of chi-square with
      ``S`` degrees of freedom;
    * it stands out from the next nearest row on either side by more than
      the noise: the margin of ``r`` past the hyperplane halfway between
      ``c`` and the next nearest current row ``c'``, ``(|r - c'|^2 - |r -
      c|^2) / (2 |c' - c|)``, exceeds the ``confidence`` quantile of its
      normal noise (sd ``sqrt(var_r + (var_c + var_c') / 4)``), and so does
      the margin of ``c`` between ``r`` and the next nearest reference row;
    * no other reference row matches ``current[j]``.

    Where two candidates lie within what the noise lets one sensing tell
    apart, no match is made: refusing costs a match, a wrong one costs a
    wrong pose. ``tree``: a ``cKDTree`` of ``finite_rows(current, -1)``. A
    lost (non-finite) row matches nothing."""
    reference = finite_rows(reference, 1.0)
    current = finite_rows(current, -1.0)
    empty = np.zeros(0, dtype=int)
    if len(reference) == 0 or len(current) == 0:
        return empty, empty
    reference_var = np.broadcast_to(np.asarray(reference_var, dtype=float), len(reference))
    current_var = np.broadcast_to(np.asarray(current_var, dtype=float), len(current))
    n_sensors = reference.shape[1]
    limit = chi2.ppf(confidence, n_sensors)
    z = norm.ppf(confidence)
    tree = cKDTree(current) if tree is None else tree
    k = min(2, len(current))
    distance, index = tree.query(reference, k=k)
    distance, index = distance.reshape(len(reference), k), index.reshape(len(reference), k)
    best = index[:, 0]
    close = distance[:, 0] ** 2 <= limit * (reference_var + current_var[best])
    if k == 2:
        close &= _stands_out(reference, current[best], current[index[:, 1]], reference_var,
                             current_var[best], current_var[index[:, 1]], z)
    if len(reference) > 1 and close.any():
        rows = np.flatnonzero(close)
        _, other = cKDTree(reference).query(current[best[rows]], k=2)
        # The nearest reference row to c is r itself when r is the closest.
        second = np.where(other[:, 0] == rows, other[:, 1], other[:, 0])
        close[rows] &= (other[:, 0] == rows) & _stands_out(
            current[best[rows]], reference[rows], reference[second], current_var[best[rows]],
            reference_var[rows], reference_var[second], z)
    ref_idx = np.flatnonzero(close)
    cur_idx = best[close]
    counts = np.bincount(cur_idx, minlength=len(current))
    single = counts[cur_idx] == 1
    return ref_idx[single], cur_idx[single]


def match_counted(reference: np.ndarray, current: np.ndarray, *, counts=None,
                  noise_sd: float = 0.0, confidence: float = 0.999, tree=None,
                  discrepancy: float = 0.0, **tolerances):
    """``noisy_matches`` where the agent measured noise (``noise_sd > 0``;
    ``reference`` rows averaged ``counts`` sensings each, None: one, ``current``
    rows one each; ``discrepancy`` the per-receptor variance matched POVs
    differ by beyond it, ``match_discrepancy``), else ``match_sensations``
    with ``tolerances``."""
    if noise_sd <= 0:
        return match_sensations(reference, current, tree=tree, **tolerances)
    sd2 = float(noise_sd) ** 2
    counts = np.ones(len(reference)) if counts is None else np.asarray(counts, dtype=float)
    return noisy_matches(reference, current, reference_var=sd2 / counts + discrepancy,
                         current_var=sd2, confidence=confidence, tree=tree)


def match_noise(noise: float, repeat_noise: float, quantum: float) -> float:
    """The per-receptor noise sd ``match_counted`` tests matches against, 0
    for its tolerances. Two matched sensings differ by their noise and by
    the pose errors of the compensations that placed their POVs, which add
    up along chains of anchors. Where the noise is random (repeats spread:
    ``repeat_noise`` at least half of ``noise``) the agent averages it out
    of its compensations, and where the outputs lie on a lattice
    (``quantum``) a pose error finer than its step senses alike: the noise
    covers the difference. Where the error repeats exactly and lies on no
    lattice (rounding to a float's relative precision), nothing averages
    the pose errors down and they exceed the rounding many times over: the
    chain tolerance and the ratio test tell the match instead."""
    if noise <= 0 or (repeat_noise < 0.5 * noise and quantum <= 0):
        return 0.0
    return float(noise)


def _stands_out(point, nearest, second, var_point, var_nearest, var_second, z):
    """Whether each ``point`` lies nearer ``nearest`` than ``second`` by more
    than ``z`` standard deviations of the noise of its margin past the
    hyperplane halfway between them (rows; variances per receptor)."""
    gap = np.linalg.norm(second - nearest, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        margin = (np.sum((point - second) ** 2, axis=1)
                  - np.sum((point - nearest) ** 2, axis=1)) / (2.0 * gap)
    spread = np.sqrt(var_point + 0.25 * (var_nearest + var_second))
    return (gap > 0) & (margin > z * spread)


def check_pose_rank(body, motor_states: np.ndarray, *, rank: int, fd_step: float = 1e-6,
                    rank_ratio: float = 1e-3, min_singular: float = 0.0,
                    pattern_ratio: float = 1e-6, sensed: np.ndarray | None = None):
    """Rank test of the sensory Jacobian at ``motor_states`` against the pose
    rank ``rank`` (one ``sense`` call, ``M + 1`` rows each; ``M`` where the
    states' own sensations are given, ``sensed``: ``sensory_jacobian``).
    Returns ``(full_rank (B,) bool, rows)``."""
    motor_states = np.asarray(motor_states, dtype=float)
    if len(motor_states) == 0:
        return np.zeros(0, dtype=bool), 0
    sensations, jac, rows = sensory_jacobian(body, motor_states, fd_step, sensed)
    return has_full_pose_rank(jac, rank, rank_ratio, min_singular, sensations,
                              pattern_ratio), rows


class EqualitySetCollection:
    """Equality sets as ``core.regularize`` takes them: ``pairs`` ``(K, 2)``
    POV index changes i -> j, ``set_ids`` ``(K,)``, pairs of one set
    compensating one displacement."""

    def __init__(self, min_pairs: int = 2):
        if int(min_pairs) != min_pairs or min_pairs < 1:
            raise ValueError(f"min_pairs must be an integer >= 1, got {min_pairs}")
        self.min_pairs = int(min_pairs)
        self._pairs: list[np.ndarray] = []
        self._ids: list[np.ndarray] = []
        self.n_sets = 0
        self.n_pairs = 0

    def add(self, before: np.ndarray, after: np.ndarray) -> int:
        """Record the changes ``before[k] -> after[k]`` of one displacement.
        Changes to the same POV (zero displacement) are left out. Returns the
        set id, or -1 when fewer than ``min_pairs`` changes remain (a set of
        one constrains nothing)."""
        pairs = np.stack([np.asarray(before, int), np.asarray(after, int)], axis=1)
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        if len(pairs) < self.min_pairs:
            return -1
        set_id = self.n_sets
        self._pairs.append(pairs)
        self._ids.append(np.full(len(pairs), set_id))
        self.n_sets += 1
        self.n_pairs += len(pairs)
        return set_id

    def truncate(self, n_sets: int) -> None:
        """Forget the sets added after the first ``n_sets`` (an undone reaction's)."""
        if not 0 <= n_sets <= self.n_sets:
            raise ValueError(f"n_sets: must lie in [0, {self.n_sets}], got {n_sets}")
        self.n_pairs -= sum(len(pairs) for pairs in self._pairs[n_sets:])
        del self._pairs[n_sets:], self._ids[n_sets:]
        self.n_sets = n_sets

    @property
    def pairs(self) -> np.ndarray:
        return np.concatenate(self._pairs) if self._pairs else np.zeros((0, 2), dtype=int)

    def rows_since(self, n_sets: int) -> np.ndarray:
        """Rows ``(set id, from, to)`` of the sets added after the first ``n_sets``."""
        if n_sets >= self.n_sets:
            return np.zeros((0, 3), dtype=int)
        return np.column_stack([np.concatenate(self._ids[n_sets:]),
                                np.concatenate(self._pairs[n_sets:])]).astype(int)

    @property
    def set_ids(self) -> np.ndarray:
        return np.concatenate(self._ids) if self._ids else np.zeros(0, dtype=int)


def merge_equality_sets(pairs: np.ndarray, set_ids: np.ndarray):
    """Merge equality sets that share a POV change; keep each change once.

    POV j is a fixed displacement away from POV i, so two sets that both
    contain i -> j (or j -> i) compensate the same displacement (or its
    opposite, of the same length): they are one set. This is the agent's own
    inference, no ground truth. Returns ``(pairs, set_ids)`` with each
    unordered pair once and set ids 0.. in order of first appearance.
    """
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    set_ids = np.asarray(set_ids, dtype=int).reshape(-1)
    if len(pairs) != len(set_ids):
        raise ValueError(f"set_ids must have one entry per pair ({len(pairs)}), "
                         f"got {len(set_ids)}")
    if len(pairs) == 0:
        return pairs, set_ids
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    _, pair_key = np.unique(np.stack([lo, hi], axis=1), axis=0, return_inverse=True)
    pair_key = pair_key.reshape(-1)
    _, set_key = np.unique(set_ids, return_inverse=True)
    set_key = set_key.reshape(-1)
    n_sets, n_keys = set_key.max() + 1, pair_key.max() + 1
    # Bipartite graph sets <-> unordered pairs; its components are the merged sets.
    graph = coo_matrix((np.ones(len(pairs)), (set_key, n_sets + pair_key)),
                       shape=(n_sets + n_keys, n_sets + n_keys))
    _, component = connected_components(graph, directed=False)
    first = np.unique(pair_key, return_index=True)[1]
    merged = component[set_key[first]]
    order = np.argsort(first, kind="stable")
    first, merged = first[order], merged[order]
    # Number merged sets by first appearance.
    labels, first_seen, inverse = np.unique(merged, return_index=True, return_inverse=True)
    rank = np.empty(len(labels), dtype=int)
    rank[np.argsort(first_seen, kind="stable")] = np.arange(len(labels))
    return np.stack([lo[first], hi[first]], axis=1), rank[inverse.reshape(-1)]


class EqualitySetSweep:
    """Simulation 2 over known POVs: call ``observe()`` after every change of
    the environment (the body answers in the changed environment); each call
    senses one sample of every POV and matches it with the previous sweep.

    ``points_of_view`` ``(P, N, M)`` (any sample of a POV will do: all share
    the eye's pose). ``rows`` counts motor states probed, ``calls`` the
    ``sense`` calls; ``ratio`` as ``match_sensations``'s (0: none).
    """

    ratio = 0.0

    def __init__(self, body, points_of_view: np.ndarray, *, rank: int, fd_step: float = 1e-6,
                 rank_ratio: float = 1e-3, min_singular: float = 0.0,
                 pattern_ratio: float = 1e-6, match_tol: float = 1e-6,
                 separation: float = 1e-4, min_pairs: int = 2):
        povs = np.asarray(points_of_view, dtype=float)
        if povs.ndim != 3 or povs.shape[2] != int(body.n_motors):
            raise ValueError(f"points_of_view must have shape (P, N, {body.n_motors}), "
                             f"got {povs.shape}")
        self.body = body
        self.rank = int(rank)
        self.probe_states = povs[:, 0, :].copy()
        self.fd_step, self.rank_ratio, self.min_singular = fd_step, rank_ratio, min_singular
        self.pattern_ratio = pattern_ratio
        self.match_tol, self.separation = match_tol, separation
        self.sets = EqualitySetCollection(min_pairs)
        self.rows = 0
        self.calls = 0
        self._previous: np.ndarray | None = None
        self._previous_rank: np.ndarray | None = None

    def observe(self) -> np.ndarray:
        """Sweep, match with the previous sweep, record one set; returns this
        change's pairs ``(k, 2)`` (empty when nothing matched)."""
        current = np.asarray(self.body.sense(self.probe_states), dtype=float)
        self.rows += len(current)
        self.calls += 1
        rank = np.full(len(current), RANK_UNKNOWN)
        pairs = np.zeros((0, 2), dtype=int)
        if self._previous is not None:
            before, after = match_sensations(self._previous, current, match_tol=self.match_tol,
                                             separation=self.separation, ratio=self.ratio)
            before, after, rank = carry_rank(self, before, after, self._previous_rank, rank)
            if self.sets.add(before, after) >= 0:
                pairs = np.stack([before, after], axis=1)
                pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        self._previous, self._previous_rank = current, rank
        return pairs

    @property
    def pairs(self) -> np.ndarray:
        return self.sets.pairs

    @property
    def set_ids(self) -> np.ndarray:
        return self.sets.set_ids


def carry_rank(sweep, before, after, rank_before, rank_after):
    """Keep the matches whose sensation has full pose rank.

    The rank is carried from the matched row of the earlier sweep when it is
    known there, otherwise measured at the later row's probe state (one
    ``sense`` call for all of them); ``rank_after`` is filled in place.
    ``sweep`` supplies ``body``, ``probe_states``, the rank and its thresholds and
    the ``rows``/``calls`` counters.
    """
    known = rank_before[before]
    rank_after[after] = known
    unknown = after[known == RANK_UNKNOWN]
    if len(unknown):
        full, rows = check_pose_rank(sweep.body, sweep.probe_states[unknown], rank=sweep.rank,
                                     fd_step=sweep.fd_step, rank_ratio=sweep.rank_ratio,
                                     min_singular=sweep.min_singular,
                                     pattern_ratio=sweep.pattern_ratio)
        sweep.rows += rows
        sweep.calls += 1
        rank_after[unknown] = np.where(full, RANK_FULL, RANK_DEFICIENT)
    good = rank_after[after] == RANK_FULL
    return before[good], after[good], rank_after
