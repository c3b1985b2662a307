"""Metric regularisation from equality sets (paper Sec. "Modifying the
internal metric", Eqs. common_distance and distance_equalities).

An *equality set* is a group of POV changes i -> j that compensated one and
the same external displacement, so they should have one length. Sets are
given flat: ``pairs`` (K, 2) POV indices and ``set_ids`` (K,) labels; every
pair with the same label is in the same set.

One regularisation step replaces each constrained distance by its set's mean
(Eq. distance_equalities). The sets say nothing about how different sets
relate, so the paper iterates: regularise -> project with CCA (warm-started
from the previous projection) -> take the projected Euclidean distances as
the new metric, 10 times.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.distance import pdist, squareform

from sensorispace_ros.core.cca import CCA, check_distance_matrix


@dataclass
class RegularizationResult:
    """Outcome of ``iterate_regularization``.

    embeddings : one (P, n_components) projection per iteration.
    distances : the final metric (Euclidean distances of the last projection).
    set_spread : per iteration, how unequal the constrained distances were
        before that iteration's averaging (mean over sets of std / mean).
    timings_s : per iteration wall time (regularisation + CCA), seconds.
    """

    embeddings: list = field(default_factory=list)
    distances: np.ndarray | None = None
    set_spread: list = field(default_factory=list)
    timings_s: list = field(default_factory=list)


def _check_sets(pairs, set_ids, P: int):
    pairs = np.asarray(pairs)
    set_ids = np.asarray(set_ids)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"pairs must have shape (K, 2), got {pairs.shape}")
    if set_ids.shape != (pairs.shape[0],):
        raise ValueError(f"set_ids must have shape ({pairs.shape[0]},), got {set_ids.shape}")
    if pairs.size and not np.issubdtype(pairs.dtype, np.integer):
        raise ValueError(f"pairs must hold integer POV indices, got dtype {pairs.dtype}")
    if set_ids.size and not np.issubdtype(set_ids.dtype, np.integer):
        raise ValueError(f"set_ids must be integers, got dtype {set_ids.dtype}")
    if pairs.size and (pairs.min() < 0 or pairs.max() >= P):
        raise ValueError(f"pairs index POVs outside [0, {P})")
    if np.any(pairs[:, 0] == pairs[:, 1]):
        raise ValueError("pairs contains a POV paired with itself (a zero-length change)")
    _, compact = np.unique(set_ids, return_inverse=True)
    return pairs.astype(np.intp), compact.reshape(-1)


@dataclass
class _SetIndex:
    """Equality sets checked and indexed once (np.unique over millions of
    pairs is the costly part; the iterations reuse it).

    compact : (K,) set of each pair, 0..S-1.
    count : (S,) pairs per set.
    i, j : (U,) the distinct unordered POV pairs (i < j) that are constrained.
    slot : (K,) which of them each pair is.
    """

    pairs: np.ndarray
    compact: np.ndarray
    count: np.ndarray
    i: np.ndarray
    j: np.ndarray
    slot: np.ndarray
    slot_count: np.ndarray

    @classmethod
    def build(cls, pairs, set_ids, P: int) -> "_SetIndex":
        pairs, compact = _check_sets(pairs, set_ids, P)
        lo = np.minimum(pairs[:, 0], pairs[:, 1])
        hi = np.maximum(pairs[:, 0], pairs[:, 1])
        keys, slot = np.unique(lo * P + hi, return_inverse=True)
        i, j = np.divmod(keys, P)
        return cls(pairs=pairs, compact=compact, count=np.bincount(compact), i=i, j=j,
                   slot=slot.reshape(-1), slot_count=np.bincount(slot.reshape(-1)))

    def means(self, distance):
        values = distance[self.pairs[:, 0], self.pairs[:, 1]]
        return values, np.bincount(self.compact, weights=values) / self.count

    def spread(self, distance) -> float:
        if self.pairs.shape[0] == 0:
            return 0.0
        values, mean = self.means(distance)
        sq = np.bincount(self.compact, weights=(values - mean[self.compact]) ** 2)
        std = np.sqrt(sq / self.count)
        usable = (self.count >= 2) & (mean > 0)
        if not np.any(usable):
            return 0.0
        return float(np.mean(std[usable] / mean[usable]))

    def regularized(self, distance) -> np.ndarray:
        out = distance.copy()
        if self.pairs.shape[0] == 0:
            return out
        _, mean = self.means(distance)
        target = np.bincount(self.slot, weights=mean[self.compact]) / self.slot_count
        out[self.i, self.j] = target
        out[self.j, self.i] = target
        return out


def set_spread(distance, pairs, set_ids) -> float:
    """Mean over equality sets (of >= 2 pairs) of the coefficient of variation
    of their distances: 0 when every set is already equal."""
    D = np.asarray(distance, dtype=float)
    return _SetIndex.build(pairs, set_ids, D.shape[0]).spread(D)


def regularize_metric(distance, pairs, set_ids) -> np.ndarray:
    """One step of Eqs. common_distance / distance_equalities.

    Every constrained pair, in both orientations, takes the mean of its set's
    current distances; other pairs keep theirs. A pair listed in several sets
    (e.g. i -> j in the set of +delta and j -> i in the set of -delta) takes
    the mean of those sets' means.
    """
    D = check_distance_matrix(distance, "distance")
    return _SetIndex.build(pairs, set_ids, D.shape[0]).regularized(D)


def iterate_regularization(distance, pairs, set_ids, *, n_components, n_iterations=10,
                           cca_params=None, random_state=None, init=None,
                           callback=None) -> RegularizationResult:
    """Regularise -> CCA -> new metric, ``n_iterations`` times (paper: 10).

    ``init`` seeds the first projection (default: CCA's own, classical MDS of
    the first regularised metric); later ones warm-start from the previous
    projection. ``callback(iteration, embedding)`` runs after each iteration
    (1-based). ``random_state`` (int or Generator) drives every CCA in turn.
    """
    current = check_distance_matrix(distance, "distance")
    sets = _SetIndex.build(pairs, set_ids, current.shape[0])
    if not isinstance(n_iterations, (int, np.integer)) or n_iterations < 1:
        raise ValueError(f"n_iterations must be a positive integer, got {n_iterations!r}")
    cca_params = dict(cca_params or {})
    reserved = {"n_components", "random_state", "init", "metric"} & set(cca_params)
    if reserved:
        raise ValueError(f"cca_params must not set {sorted(reserved)}: "
                         "they are arguments of iterate_regularization")
    rng = random_state if isinstance(random_state, np.random.Generator) \
        else np.random.default_rng(random_state)
    result = RegularizationResult()
    start = init
    for iteration in range(1, n_iterations + 1):
        began = time.perf_counter()
        result.set_spread.append(sets.spread(current))
        target = sets.regularized(current)
        estimator = CCA(n_components, metric="precomputed", random_state=rng, **cca_params)
        embedding = estimator.fit_transform(target, init=start)
        current = squareform(pdist(embedding))
        start = embedding
        result.embeddings.append(embedding)
        result.timings_s.append(time.perf_counter() - began)
        if callback is not None:
            callback(iteration, embedding)
    result.distances = current
    return result
