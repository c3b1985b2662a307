"""The topology of a space with a looped dimension, from its distance matrix alone.

Betti numbers up to H2 (``betti_up_to_h2``). ``core.topology`` reads b0 and b1 (the paper's ring); a world whose object
turns gives points of view on the ring times a circle, whose Betti numbers
are (1, 2, 1): one component, two independent loops, one 2-cycle. Same rule
as ``core.topology`` (a feature counts when its lifetime exceeds ``k``
times the landmarks' median nearest-neighbour distance), same landmarks
(ripser's greedy ``n_perm``), one more dimension: ripser ``maxdim=2``,
whose cost grows as the cube of the landmarks, hence ``MAX_POINTS_H2``.

An angle coordinate for the looped dimension (``circular_coordinates``,
``looped_coordinate``): circular coordinates from
persistent cohomology (de Silva, Morozov & Vejdemo-Johansson 2011).

A long H1 bar of the Rips filtration of a distance matrix is a loop of the
space. Its cocycle (ripser, coefficients mod a prime ``COEFF``), lifted to
integers, is an edge labelling of the Rips complex at a radius inside the
bar, ``r = birth + (death - birth) / 2``, that counts +-1 each time an edge
crosses a "cut" of the loop. The smoothest angle that crosses the same cut,
``theta = f mod 1`` with ``f`` minimising ``|| f_j - f_i - z_ij ||^2`` over
the edges (least squares), is a map to the circle that goes once around it
along the loop and stays nearly constant across it: the coordinate of the
looped dimension. Computed on greedy landmarks (ripser's ``n_perm``); every
other point takes the angle of its nearest landmark. Needs the distance
matrix only: it reads the agent's Hausdorff metric as it reads any other.
"""
from __future__ import annotations

import numpy as np
from ripser import ripser
from scipy.sparse import coo_matrix
from scipy.sparse.linalg import lsqr, spsolve

from sensorispace_ros.core.topology import K_SCALE, _lifetimes, _nearest_neighbour_scale, \
    check_distance_matrix

MAX_POINTS_H2 = 400        # greedy landmarks above this many points (H2 is costly)
COEFF = 47                 # a prime larger than any winding met in practice
MAX_LANDMARKS = 300
MAX_RESULTANT = 0.5        # a loop's coordinate goes round the circle: its mean resultant is small
GAP_MIN_LIFETIME = 0.5     # a feature of rule 'gap' outlives half a sampling step
GAP_MIN_RATIO = 1.5        # and stands out of the next by this factor
SYNC_ITERATIONS = 5        # rounds of synchronised_angle (steps of the sets, then the angles)
SYNC_ANCHOR_WEIGHT = 1e-6  # pull of the metric's coordinate against the sets' steps, per POV


def betti_up_to_h2(distance, max_points: int = MAX_POINTS_H2, k: float = K_SCALE,
                   rule: str = "scale") -> dict:
    """``betti0``, ``betti1``, ``betti2``, ``threshold``, ``margin`` (as in
    ``core.topology.betti_numbers``) and the longest lifetimes of H1 and H2
    of the distance matrix ``distance``.

    ``rule="scale"``: a feature counts when it outlives ``k`` times the
    landmarks' median neighbour distance (``core.topology``'s rule). ``rule=
    "gap"``: b0 by that rule; b1 and b2 by the largest gap of their own
    lifetimes (``gap_count``), the rule for a product with a coarsely sampled
    circle, whose loops outlive the sampling step by a factor 1-2 only, far
    below ``k`` steps, while the lattice's own cells die within half a step.
    ``threshold`` and ``margin`` then describe b0; ``h1_gap``, ``h2_gap``
    the ratio at each cut (0: nothing counted)."""
    if rule not in ("scale", "gap"):
        raise ValueError(f"rule must be 'scale' or 'gap', got {rule!r}")
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
    gaps = {}
    if rule == "gap":
        scale = threshold / k
        (bettis[1], gaps["h1_gap"]), (bettis[2], gaps["h2_gap"]) = \
            gap_count(h1, scale), gap_count(h2, scale)
        h1, h2 = h1[:0], h2[:0]          # the margin below is b0's
    pooled = np.concatenate([finite0, h1[np.isfinite(h1)], h2[np.isfinite(h2)]])
    counted, uncounted = pooled[pooled > threshold], pooled[pooled <= threshold]
    up = counted.min() / threshold if len(counted) else np.inf
    down = threshold / uncounted.max() if len(uncounted) else np.inf
    lifetimes = [_lifetimes(np.asarray(d, dtype=float).reshape(-1, 2)) for d in result["dgms"]]
    return {"betti0": bettis[0], "betti1": bettis[1], "betti2": bettis[2],
            "threshold": threshold, "margin": float(min(up, down)), **gaps,
            "h1_lifetimes_top3": [float(v) for v in lifetimes[1][:3]],
            "h2_lifetimes_top3": [float(v) for v in lifetimes[2][:3]]}


def gap_count(lifetimes, scale: float, min_lifetime: float = GAP_MIN_LIFETIME,
              min_gap: float = GAP_MIN_RATIO) -> tuple[int, float]:
    """How many of ``lifetimes`` (one dimension's) stand out: sorted longest
    first, the cut is the largest ratio of one lifetime to the next among
    those that outlive ``min_lifetime`` times ``scale`` (the sampling step;
    the shortest of all is compared with that floor); the features above it count when
    that ratio is at least ``min_gap``.
    Returns the count and the ratio at the cut (0.0 when none counts)."""
    life = np.sort(np.asarray(lifetimes, dtype=float).reshape(-1))[::-1]
    life = life[np.isfinite(life)]
    long = int(np.sum(life >= min_lifetime * scale))
    if long == 0:
        return 0, 0.0
    following = np.append(life[1:], min_lifetime * scale)[:long]    # the last: the floor
    ratio = life[:long] / following
    cut = int(np.argmax(ratio))
    if ratio[cut] < min_gap:
        return 0, 0.0
    return cut + 1, float(ratio[cut])



def circular_coordinates(distance, n_loops: int = 1, max_landmarks: int = MAX_LANDMARKS):
    """Angles ``(n_loops, P)`` in [0, 2 pi) of the ``n_loops`` longest H1 bars
    of ``distance`` (longest first), and those bars ``(n_loops, 2)``."""
    D = check_distance_matrix(distance)
    n = len(D)
    if int(n_loops) != n_loops or n_loops < 1:
        raise ValueError(f"n_loops must be an integer >= 1, got {n_loops!r}")
    kwargs = {"n_perm": int(max_landmarks)} if n > max_landmarks else {}
    result = ripser(D, distance_matrix=True, maxdim=1, coeff=COEFF, do_cocycles=True, **kwargs)
    landmarks = np.asarray(result.get("idx_perm", np.arange(n)), dtype=int)
    bars, cocycles = result["dgms"][1], result["cocycles"][1]
    if len(bars) < n_loops:
        raise ValueError(f"distance has {len(bars)} H1 bars, fewer than n_loops = {n_loops}")
    order = np.argsort(bars[:, 0] - bars[:, 1])[:n_loops]       # longest first
    DL = D[np.ix_(landmarks, landmarks)]
    nearest = np.argmin(D[:, landmarks], axis=1)
    # ripser names a cocycle's vertices by their index among all the points:
    # renamed here by their place among the landmarks.
    place = np.full(n, -1, dtype=np.int64)
    place[landmarks] = np.arange(len(landmarks))
    renamed = []
    for k in order:
        cocycle = np.asarray(cocycles[k], dtype=np.int64).reshape(-1, 3).copy()
        cocycle[:, :2] = place[cocycle[:, :2]]
        renamed.append(cocycle)
    angles = np.array([_smooth_angle(DL, c, *bars[k])[nearest] for c, k in zip(renamed, order)])
    return angles, bars[order]


def _smooth_angle(D: np.ndarray, cocycle: np.ndarray, birth: float, death: float) -> np.ndarray:
    """Landmark angles of one cocycle (module docstring)."""
    radius = birth + 0.5 * (death - birth) if np.isfinite(death) else 2.0 * birth
    i, j = np.nonzero(np.triu(D < radius, k=1))
    labels = {}
    for a, b, value in np.asarray(cocycle, dtype=np.int64).reshape(-1, 3):
        lifted = value if value <= COEFF // 2 else value - COEFF
        labels[(a, b)], labels[(b, a)] = lifted, -lifted
    z = np.array([labels.get((a, b), 0) for a, b in zip(i, j)], dtype=float)
    rows = np.repeat(np.arange(len(i)), 2)
    cols = np.column_stack([i, j]).ravel()
    values = np.tile([-1.0, 1.0], len(i))
    delta = coo_matrix((values, (rows, cols)), shape=(len(i), len(D))).tocsr()
    f = lsqr(delta, z, atol=1e-10, btol=1e-10)[0]
    return 2 * np.pi * (f - np.floor(f)) if len(z) else np.zeros(len(D))


def circular_correlation(a, b) -> float:
    """Fisher and Lee's (1983) circular correlation of two angle samples, in
    absolute value (a coordinate may run either way round): 1 exactly when
    ``a = +-b + c``, whatever the offset ``c``, and defined for angles
    spread evenly round the circle (where the mean direction, which the
    Jammalamadaka coefficient needs, is not)."""
    a, b = np.asarray(a, float).ravel(), np.asarray(b, float).ravel()
    if a.shape != b.shape or len(a) < 2:
        raise ValueError(f"need two angle samples of one length >= 2, got {a.shape}, {b.shape}")
    n = len(a)
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    numerator = 4.0 * (np.sum(ca * cb) * np.sum(sa * sb) - np.sum(ca * sb) * np.sum(sa * cb))
    spread_a = n * n - np.sum(np.cos(2 * a)) ** 2 - np.sum(np.sin(2 * a)) ** 2
    spread_b = n * n - np.sum(np.cos(2 * b)) ** 2 - np.sum(np.sin(2 * b)) ** 2
    denominator = np.sqrt(max(spread_a, 0.0) * max(spread_b, 0.0))
    return float(abs(numerator) / denominator) if denominator > 0 else 0.0


def looped_coordinate(angles: np.ndarray, pairs: np.ndarray, set_ids: np.ndarray,
                      max_coefficient: int = 2):
    """The angle of the looped dimension among the circular coordinates
    ``angles`` ``(L, P)`` of a space's loops, from the agent's equality sets.

    The loops of a space of poses have many bases (on plane x circle, the
    eye's heading, the heading relative to the direction of the base, ...);
    the one whose dimension is the turn of the object is told apart by what
    a change does to it: every POV of one equality set (one change seen from
    many POVs) moves by the same step along it, since a displacement of the
    object turns every pose by the same angle, while it moves them by
    different steps along any other loop. Among the integer combinations
    ``sum_k c_k angles_k`` (``|c_k| <= max_coefficient``, coprime), the one
    whose steps agree best within the sets (least mean circular variance)
    is returned (the smallest coefficients among equals), with its
    coefficients and that variance (None when every
    combination is bunched on part of the circle: a constant agrees
    trivially, so a candidate must go round, mean resultant at most
    ``MAX_RESULTANT``)."""
    angles = np.atleast_2d(np.asarray(angles, float))
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    set_ids = np.asarray(set_ids).reshape(-1)
    if len(pairs) == 0:
        raise ValueError("pairs: the looped coordinate needs equality sets, got none")
    grids = np.meshgrid(*[np.arange(-max_coefficient, max_coefficient + 1)] * len(angles))
    best = None
    candidates = np.column_stack([g.ravel() for g in grids])
    for c in candidates[np.argsort(np.abs(candidates).sum(axis=1), kind="stable")]:
        if not np.any(c) or np.gcd.reduce(np.abs(c)) != 1 or c[np.flatnonzero(c)[0]] < 0:
            continue
        theta = (c @ angles) % (2 * np.pi)
        if abs(np.mean(np.exp(1j * theta))) > MAX_RESULTANT:
            continue            # bunched on part of the circle: it does not go round the loop
        step = np.exp(1j * (theta[pairs[:, 1]] - theta[pairs[:, 0]]))
        _, inverse, counts = np.unique(set_ids, return_inverse=True, return_counts=True)
        mean = np.bincount(inverse, step.real) ** 2 + np.bincount(inverse, step.imag) ** 2
        variance = float(np.mean(1.0 - np.sqrt(mean) / counts))
        if best is None or variance < best[2] - 1e-12:      # equals: the simpler stays
            best = (theta, c, variance)
    return best


def synchronized_angle(theta0, pairs, set_ids, iterations: int = SYNC_ITERATIONS,
                       anchor_weight: float = SYNC_ANCHOR_WEIGHT) -> np.ndarray:
    """The angle coordinate ``theta0`` ``(P,)`` made consistent with the
    equality sets (angular synchronisation, Singer 2011).

    One equality set is one change seen from many POVs: along the looped
    dimension every pair ``(i, j)`` of one set steps by the same angle
    ``phi`` (a displacement turns every pose by the same angle), so the
    coordinate should satisfy ``theta_j = theta_i + phi_set``. Alternately:
    each set's step is the circular mean of its pairs' steps, then
    ``z = exp(i theta)`` minimises ``sum |z_j - w_set z_i|^2 + anchor_weight
    sum |z - z0|^2`` (a sparse linear system, ``w = exp(i phi)``), projected
    back on the circle. POVs joined by the sets share one coordinate up to
    the sets' steps: the scatter a coordinate read from the metric alone
    has within a class of POVs the changes join (one orientation) is
    averaged out; POVs in no pair keep ``theta0``. ``anchor_weight`` keeps
    each component of the pair graph at its mean of ``theta0``: the sets
    fix differences, never the offset, and a constant (every step 0) would
    satisfy them too."""
    theta0 = np.asarray(theta0, dtype=float).reshape(-1)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    set_ids = np.asarray(set_ids).reshape(-1)
    if len(set_ids) != len(pairs):
        raise ValueError(f"set_ids: {len(set_ids)} ids for {len(pairs)} pairs")
    if len(pairs) and (pairs.min() < 0 or pairs.max() >= len(theta0)):
        raise ValueError(f"pairs: indices must lie in [0, {len(theta0)})")
    if int(iterations) != iterations or iterations < 1:
        raise ValueError(f"iterations must be an integer >= 1, got {iterations!r}")
    if not anchor_weight > 0:
        raise ValueError(f"anchor_weight must be > 0, got {anchor_weight!r}")
    keep = pairs[:, 0] != pairs[:, 1]
    pairs, set_ids = pairs[keep], set_ids[keep]
    z0 = np.exp(1j * theta0)
    if not len(pairs):
        return np.mod(theta0, 2 * np.pi)
    _, inverse = np.unique(set_ids, return_inverse=True)
    i, j, n = pairs[:, 0], pairs[:, 1], len(theta0)
    degree = np.bincount(i, minlength=n) + np.bincount(j, minlength=n)
    z = z0
    for _ in range(int(iterations)):
        agreement = np.bincount(inverse, (z[j] * np.conj(z[i])).real) + \
            1j * np.bincount(inverse, (z[j] * np.conj(z[i])).imag)
        w = np.exp(1j * np.angle(agreement))[inverse]
        rows = np.concatenate([i, j, np.arange(n)])
        cols = np.concatenate([j, i, np.arange(n)])
        values = np.concatenate([-np.conj(w), -w, degree + anchor_weight])
        system = coo_matrix((values, (rows, cols)), shape=(n, n)).tocsc()
        solved = spsolve(system, anchor_weight * z0)
        z = solved / np.maximum(np.abs(solved), 1e-300)
    return np.mod(np.angle(z), 2 * np.pi)


def synchronized_translations(embedding, pairs, set_ids,
                              anchor_weight: float = SYNC_ANCHOR_WEIGHT,
                              neighbours: int = 6) -> np.ndarray:
    """A flat embedding ``(P, d)`` of POVs of one orientation made consistent
    with the equality sets read as vectors: a change that translates the
    object translates every pose it is compensated from by one vector, so
    every pair ``(i, j)`` of one set should satisfy ``y_j - y_i = v_set``.
    ``y`` and the sets' vectors ``v`` minimise ``sum |y_j - y_i - v_set|^2 +
    anchor_weight sum |y - embedding|^2`` (one sparse linear system per
    coordinate). Stronger than the paper's regularisation, which equalises
    the lengths of a set's changes only: their directions agree too, which
    holds along translations and not along turns. Where the pairs pin the
    POVs (the only solutions of the sets are affine images of the true
    positions) the result is one, whatever the metric's distortion; a POV in
    no pair (of a set of two pairs or more) is placed by the affine map that takes its ``neighbours`` nearest
    placed POVs (in ``embedding``) to their places."""
    Y0 = np.asarray(embedding, dtype=float)
    if Y0.ndim != 2:
        raise ValueError(f"embedding must be (P, d), got shape {Y0.shape}")
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    set_ids = np.asarray(set_ids).reshape(-1)
    if len(set_ids) != len(pairs):
        raise ValueError(f"set_ids: {len(set_ids)} ids for {len(pairs)} pairs")
    n = len(Y0)
    if len(pairs) and (pairs.min() < 0 or pairs.max() >= n):
        raise ValueError(f"pairs: indices must lie in [0, {n})")
    if not anchor_weight > 0:
        raise ValueError(f"anchor_weight must be > 0, got {anchor_weight!r}")
    keep = pairs[:, 0] != pairs[:, 1]
    pairs, set_ids = pairs[keep], set_ids[keep]
    _, sets = np.unique(set_ids, return_inverse=True)
    # A set of one pair constrains nothing: its vector is free.
    keep = np.bincount(sets.reshape(-1))[sets.reshape(-1)] >= 2 if len(pairs) else keep[:0]
    pairs = pairs[keep]
    if not len(pairs):
        return Y0.copy()
    _, sets = np.unique(set_ids[keep], return_inverse=True)
    k, n_sets = len(pairs), int(sets.max()) + 1
    rows = np.concatenate([np.arange(k)] * 3 + [k + np.arange(n)])
    cols = np.concatenate([pairs[:, 1], pairs[:, 0], n + sets.reshape(-1), np.arange(n)])
    values = np.concatenate([np.ones(k), -np.ones(k), -np.ones(k),
                             np.full(n, np.sqrt(anchor_weight))])
    system = coo_matrix((values, (rows, cols)), shape=(k + n, n + n_sets)).tocsr()
    normal = (system.T @ system).tocsc()
    out = np.empty_like(Y0)
    for d in range(Y0.shape[1]):
        rhs = np.concatenate([np.zeros(k), np.sqrt(anchor_weight) * Y0[:, d]])
        out[:, d] = spsolve(normal, system.T @ rhs)[:n]
    return _place_unpaired(Y0, out, np.bincount(pairs.ravel(), minlength=n) > 0, neighbours)


def _place_unpaired(before: np.ndarray, after: np.ndarray, paired: np.ndarray,
                    neighbours: int) -> np.ndarray:
    """``after`` with each unpaired row moved by the affine map (least
    squares) from ``before`` to ``after`` of its ``neighbours`` nearest
    paired rows in ``before`` (left as is with fewer paired rows than an
    affine map needs)."""
    placed = np.flatnonzero(paired)
    d = before.shape[1]
    if len(placed) < d + 1 or paired.all():
        return after
    out = after.copy()
    k = min(max(int(neighbours), d + 1), len(placed))
    for i in np.flatnonzero(~paired):
        near = placed[np.argsort(np.linalg.norm(before[placed] - before[i], axis=1))[:k]]
        lifted = np.column_stack([before[near], np.ones(k)])
        affine, *_ = np.linalg.lstsq(lifted, after[near], rcond=None)
        out[i] = np.append(before[i], 1.0) @ affine
    return out
