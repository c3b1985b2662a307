"""Persistent homology of a metric, and Betti numbers read without ground truth.

``persistence(distance)`` computes the Vietoris-Rips barcodes H0 and H1 of a
distance matrix with ripser; ``betti_numbers`` counts the features that stand
out; ``topology_report`` gives both as the ``topology.<space>.*`` numbers.
Nothing here needs more than the distance matrix, so the same call measures
the agent's Hausdorff metric, every embedding and (for evaluation) the true
sensor positions. The points of view of the paper's arm fill its working ring
(``|tip| < 1`` is left out, paper Sec. 3.1), so a faithful representation has
one component (b0 = 1) and one hole (b1 = 1).

The rule. A feature counts when its lifetime (death - birth) exceeds
``k * scale``, with ``scale`` the median nearest-neighbour distance of the
points the barcodes were computed on and ``k = K_SCALE = 4``; H0's infinite
bar is the one component that never dies and always counts. The threshold
is the space's own sampling step, so the rule is scale-free: it reads a
metric in radians of motor space and one in units of the plane alike. Its
resolution: a hole must stay open over four sampling steps to count, so a
hole only a few steps across reads as noise (more landmarks resolve it).

Landmarks. Above ``MAX_POINTS`` points the barcodes are those of a greedy
(furthest-point) subsample, ripser's ``n_perm``; every point lies within
``cover_radius`` of a landmark, and the landmarks are at least that far
apart, so ``cover_radius <= scale``. By the stability theorem the landmarks'
diagrams are within bottleneck distance ``2 * cover_radius`` of the full
ones: a landmark feature longer than ``4 * cover_radius`` (hence any counted
one, ``k = 4``) is a feature of the full set too.

The margin says how clear the answer was: the factor by which the threshold
could be multiplied or divided before either Betti number changes (the
smallest counted finite lifetime over the threshold, the threshold over the
largest uncounted lifetime; 1 = on the edge).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ripser import ripser
from scipy.spatial.distance import pdist, squareform

MAX_POINTS = 300          # greedy landmarks above this many points
K_SCALE = 4.0             # a feature counts when its lifetime > K_SCALE * scale
TOP_H1 = 3                # longest H1 lifetimes reported


@dataclass(frozen=True)
class Persistence:
    """Rips barcodes of a distance matrix (rows: birth, death).

    ``h0`` has one infinite death (the component that never merges);
    ``landmarks`` are the indices the barcodes were computed on (all points
    when there were at most ``max_points``); ``cover_radius`` the largest
    distance of a point to its nearest landmark (0 with all points);
    ``scale`` the landmarks' median nearest-neighbour distance.
    """

    h0: np.ndarray
    h1: np.ndarray
    landmarks: np.ndarray
    cover_radius: float
    scale: float


@dataclass(frozen=True)
class BettiNumbers:
    """``betti0``/``betti1`` by the rule (module docstring), its
    ``threshold`` (same unit as the distances), ``margin`` and every H1
    lifetime, longest first."""

    betti0: int
    betti1: int
    threshold: float
    margin: float
    h1_lifetimes: np.ndarray


def check_distance_matrix(distance, name: str = "distance") -> np.ndarray:
    """``distance`` as a float array, or a ValueError saying what is wrong."""
    D = np.asarray(distance, dtype=float)
    if D.ndim != 2 or D.shape[0] != D.shape[1]:
        raise ValueError(f"{name} must be a square (P, P) matrix, got shape {D.shape}")
    if D.shape[0] < 2:
        raise ValueError(f"{name} needs at least 2 points, got {D.shape[0]}")
    if not np.all(np.isfinite(D)):
        raise ValueError(f"{name} contains NaN or infinite values")
    if np.any(D < 0):
        raise ValueError(f"{name} has negative entries: not a distance matrix")
    if np.any(np.diag(D) != 0):
        raise ValueError(f"{name} has a non-zero diagonal: not a distance matrix")
    if not np.allclose(D, D.T, rtol=1e-9, atol=1e-12 * float(D.max())):
        raise ValueError(f"{name} is not symmetric: not a distance matrix")
    return D


def euclidean_distances(points) -> np.ndarray:
    """The (P, P) Euclidean distance matrix of a (P, D) point cloud."""
    X = np.asarray(points, dtype=float)
    if X.ndim != 2:
        raise ValueError(f"points must be a (P, D) array, got shape {X.shape}")
    return squareform(pdist(X))


def persistence(distance, max_points: int = MAX_POINTS) -> Persistence:
    """H0 and H1 Rips barcodes of ``distance`` (a (P, P) distance matrix),
    on at most ``max_points`` greedy landmarks (the first is point 0, so the
    result is a function of the matrix alone)."""
    D = check_distance_matrix(distance)
    if int(max_points) != max_points or max_points < 3:
        raise ValueError(f"max_points must be an integer >= 3, got {max_points!r}")
    n = D.shape[0]
    if n > max_points:
        result = ripser(D, distance_matrix=True, maxdim=1, n_perm=int(max_points))
        landmarks = np.asarray(result["idx_perm"], dtype=int)
        cover = float(result["r_cover"])
    else:
        result = ripser(D, distance_matrix=True, maxdim=1)
        landmarks, cover = np.arange(n), 0.0
    h0, h1 = (np.asarray(d, dtype=float).reshape(-1, 2) for d in result["dgms"][:2])
    return Persistence(h0=h0, h1=h1, landmarks=landmarks, cover_radius=cover,
                       scale=_nearest_neighbour_scale(D[np.ix_(landmarks, landmarks)]))


def _nearest_neighbour_scale(D: np.ndarray) -> float:
    """Median distance of each point to its nearest other point (coincident
    points give no scale and are left out)."""
    masked = np.where(D > 0, D, np.inf)
    nearest = masked.min(axis=1)
    nearest = nearest[np.isfinite(nearest)]
    if len(nearest) == 0:
        raise ValueError("distance: all points coincide, there is no scale to read it by")
    return float(np.median(nearest))


def _lifetimes(diagram: np.ndarray) -> np.ndarray:
    life = diagram[:, 1] - diagram[:, 0]
    return np.sort(life[life > 0])[::-1]


def betti_numbers(bars: Persistence, k: float = K_SCALE) -> BettiNumbers:
    """Betti numbers by the rule of the module docstring, with its margin."""
    if not k > 0:
        raise ValueError(f"k must be > 0, got {k}")
    threshold = float(k * bars.scale)
    h0, h1 = _lifetimes(bars.h0), _lifetimes(bars.h1)
    finite0 = h0[np.isfinite(h0)]
    essential0 = len(h0) - len(finite0)          # 1: the component that never dies
    betti0 = essential0 + int(np.sum(finite0 > threshold))
    betti1 = int(np.sum(h1 > threshold))
    pooled = np.concatenate([finite0, h1[np.isfinite(h1)]])
    counted, uncounted = pooled[pooled > threshold], pooled[pooled <= threshold]
    up = counted.min() / threshold if len(counted) else np.inf
    down = threshold / uncounted.max() if len(uncounted) else np.inf
    return BettiNumbers(betti0=betti0, betti1=betti1, threshold=threshold,
                        margin=float(min(up, down)), h1_lifetimes=h1)


def topology_report(distance, max_points: int = MAX_POINTS, k: float = K_SCALE) -> dict:
    """``betti0``, ``betti1``, ``h1_lifetimes_top3`` (longest first, fewer if
    there are fewer bars), ``margin`` and ``threshold`` of ``distance``."""
    betti = betti_numbers(persistence(distance, max_points), k)
    return {"betti0": betti.betti0, "betti1": betti.betti1,
            "h1_lifetimes_top3": [float(v) for v in betti.h1_lifetimes[:TOP_H1]],
            "margin": betti.margin, "threshold": betti.threshold}
