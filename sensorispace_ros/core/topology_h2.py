"""Betti numbers up to H2, for spaces with a looped dimension.

``core.topology`` reads b0 and b1 (the paper's ring); a world whose object
turns gives points of view on the ring times a circle, a solid torus's
boundary-like product whose Betti numbers are (1, 2, 1) (annulus x circle:
one component, two independent loops, one enclosed cavity class). Same rule
as ``core.topology`` (a feature counts when its lifetime exceeds ``k``
times the landmarks' median nearest-neighbour distance), same landmarks
(ripser's greedy ``n_perm``), one more dimension: ripser ``maxdim=2``,
whose cost grows as the cube of the landmarks, hence ``MAX_POINTS_H2``.
"""
from __future__ import annotations

import numpy as np
from ripser import ripser

from sensorispace_ros.core.topology import K_SCALE, _lifetimes, _nearest_neighbour_scale, \
    check_distance_matrix

MAX_POINTS_H2 = 200        # greedy landmarks above this many points (H2 is costly)


def betti_up_to_h2(distance, max_points: int = MAX_POINTS_H2, k: float = K_SCALE) -> dict:
    """``betti0``, ``betti1``, ``betti2``, ``threshold``, ``margin`` (as in
    ``core.topology.betti_numbers``) and the longest lifetimes of H1 and H2
    of the distance matrix ``distance``."""
    D = check_distance_matrix(distance)
    if int(max_points) != max_points or max_points < 4:
        raise ValueError(f"max_points must be an integer >= 4, got {max_points!r}")
    if not k > 0:
        raise ValueError(f"k must be > 0, got {k}")
    n = D.shape[0]
    if n > max_points:
        result = ripser(D, distance_matrix=True, maxdim=2, n_perm=int(max_points))
        landmarks = np.asarray(result["idx_perm"], dtype=int)
    else:
        result = ripser(D, distance_matrix=True, maxdim=2)
        landmarks = np.arange(n)
    threshold = float(k * _nearest_neighbour_scale(D[np.ix_(landmarks, landmarks)]))
    h0, h1, h2 = (_lifetimes(np.asarray(d, dtype=float).reshape(-1, 2)) for d in result["dgms"])
    finite0 = h0[np.isfinite(h0)]
    bettis = [len(h0) - len(finite0) + int(np.sum(finite0 > threshold)),
              int(np.sum(h1 > threshold)), int(np.sum(h2 > threshold))]
    pooled = np.concatenate([finite0, h1[np.isfinite(h1)], h2[np.isfinite(h2)]])
    counted, uncounted = pooled[pooled > threshold], pooled[pooled <= threshold]
    up = counted.min() / threshold if len(counted) else np.inf
    down = threshold / uncounted.max() if len(uncounted) else np.inf
    return {"betti0": bettis[0], "betti1": bettis[1], "betti2": bettis[2],
            "threshold": threshold, "margin": float(min(up, down)),
            "h1_lifetimes_top3": [float(v) for v in h1[:3]],
            "h2_lifetimes_top3": [float(v) for v in h2[:3]]}
