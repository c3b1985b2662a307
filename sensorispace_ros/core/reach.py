"""Reaching through a representation (paper Sec. "Evaluating the internal
representations").

POVs are nodes of a graph whose edges are the internal distances; long edges
are pruned so a path must go through intermediate POVs (paper: 0.72, "so
that each node is not connected to more than 50 nodes"), and Dijkstra gives
the shortest path between a start and a target POV. Internal metrics of
different representations have different scales, so by default the radius is
chosen per representation as the largest one that keeps every node at
``max_degree`` neighbours or fewer. The motor trajectory steps, inside each
POV of the path, to the sample closest to the previous motor state (Eq.
reaching_motor). A representation is good for reaching when the external
path of the sensor is straight: ``path_straightness`` = external path length
/ straight start-target distance.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from sensorispace_ros.core.cca import check_distance_matrix
from sensorispace_ros.core.hausdorff import motor_distance


def automatic_radius(distance, max_degree: int = 50) -> float:
    """Largest r such that every node has at most ``max_degree`` nodes at
    distance < r: the smallest, over nodes, (max_degree + 1)-th neighbour
    distance (inf when no node has that many others)."""
    D = check_distance_matrix(distance, "distance")
    P = D.shape[0]
    if not isinstance(max_degree, (int, np.integer)) or max_degree < 1:
        raise ValueError(f"max_degree must be a positive integer, got {max_degree!r}")
    if max_degree >= P - 1:
        return float("inf")
    others = D + np.diag(np.full(P, np.inf))
    kth = np.partition(others, max_degree, axis=1)[:, max_degree]
    return float(kth.min())


def pruned_graph(distance, *, radius=None, max_degree: int = 50) -> csr_matrix:
    """Undirected graph (CSR, symmetric) with an edge i-j of weight d_ij for
    every pair with d_ij < radius.

    The returned matrix carries ``radius`` (the one used), ``n_components``
    and ``component_labels`` (scipy connected components) so a disconnected
    graph is visible to the caller; ``shortest_path`` raises on unreachable
    targets.
    """
    D = check_distance_matrix(distance, "distance")
    if radius is None:
        radius = automatic_radius(D, max_degree)
    elif not radius > 0:
        raise ValueError(f"radius must be > 0, got {radius!r}")
    keep = D < radius
    np.fill_diagonal(keep, False)
    rows, cols = np.nonzero(keep)
    # csgraph reads stored zeros as edges, but keep weights positive for
    # coincident POVs so no tool mistakes them for missing edges.
    weights = np.maximum(D[rows, cols], np.finfo(float).tiny)
    graph = csr_matrix((weights, (rows, cols)), shape=D.shape)
    n_components, labels = connected_components(graph, directed=False)
    graph.radius = float(radius)
    graph.n_components = int(n_components)
    graph.component_labels = labels
    return graph


def _predecessor_path(predecessors: np.ndarray, start: int, target: int) -> list[int]:
    path = [target]
    while path[-1] != start:
        path.append(int(predecessors[path[-1]]))
    return path[::-1]


def shortest_path(graph, start: int, target: int) -> list[int]:
    """Dijkstra path start -> target as node indices (both included)."""
    P = graph.shape[0]
    for name, node in (("start", start), ("target", target)):
        if not 0 <= node < P:
            raise ValueError(f"{name} must be a node index in [0, {P}), got {node}")
    dist, pred = dijkstra(graph, directed=False, indices=int(start), return_predecessors=True)
    if not np.isfinite(dist[target]):
        raise ValueError(f"target {target} is not reachable from start {start}: the pruned "
                         "graph is disconnected (raise radius or max_degree)")
    return _predecessor_path(pred, int(start), int(target))


def motor_trajectory(povs, path, start_sample: int) -> np.ndarray:
    """Motor states along a POV path (Eq. reaching_motor): the start sample of
    the first POV, then in each next POV the sample nearest (periodic motor
    metric) to the previous motor state. Shape (len(path), K)."""
    povs = np.asarray(povs, dtype=float)
    path = [int(p) for p in path]
    if not path:
        raise ValueError("path must contain at least one POV")
    if not 0 <= start_sample < povs.shape[1]:
        raise ValueError(f"start_sample must be in [0, {povs.shape[1]}), got {start_sample}")
    states = np.empty((len(path), povs.shape[2]))
    states[0] = povs[path[0], start_sample]
    for step, node in enumerate(path[1:], start=1):
        samples = povs[node]
        states[step] = samples[np.argmin(motor_distance(samples, states[step - 1]))]
    return states


def path_straightness(path, positions) -> float:
    """External length of the path / straight start-target distance (>= 1)."""
    positions = np.asarray(positions, dtype=float)
    points = positions[np.asarray(path, dtype=int)]
    straight = np.linalg.norm(points[-1] - points[0])
    if straight == 0:
        raise ValueError("path starts and ends at the same position: straightness undefined")
    return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)) / straight)


def pair_paths(D: np.ndarray, n_pairs: int, random_state, max_degree: int, radius):
    """The pruned graph of ``D``, ``n_pairs`` seeded draws of two distinct
    nodes (start, target) and the Dijkstra path of each (a list of nodes,
    None where the graph does not join them)."""
    if not isinstance(n_pairs, (int, np.integer)) or n_pairs < 1:
        raise ValueError(f"n_pairs must be a positive integer, got {n_pairs!r}")
    rng = random_state if isinstance(random_state, np.random.Generator) \
        else np.random.default_rng(random_state)
    graph = pruned_graph(D, radius=radius, max_degree=max_degree)
    P = D.shape[0]
    starts = rng.integers(P, size=n_pairs)
    targets = (starts + rng.integers(1, P, size=n_pairs)) % P
    sources, row_of = np.unique(starts, return_inverse=True)
    dist, pred = dijkstra(graph, directed=False, indices=sources, return_predecessors=True)
    paths = [_predecessor_path(pred[row], int(start), int(target))
             if np.isfinite(dist[row, target]) else None
             for row, start, target in zip(row_of.ravel(), starts, targets)]
    return graph, starts, targets, paths


def reaching_evaluation(distance, positions, *, n_pairs: int = 100, random_state=None,
                        max_degree: int = 50, radius=None) -> dict:
    """Straightness of Dijkstra paths between random start/target POVs.

    Pairs are ``n_pairs`` draws of two distinct nodes (uniform, seeded; a
    close pair may be one hop, straightness exactly 1). Unreachable pairs
    (disconnected graph) are counted in ``unreachable`` and left out of the
    median, with None in ``straightness``. Plain Python types throughout.
    """
    D = check_distance_matrix(distance, "distance")
    P = D.shape[0]
    positions = np.asarray(positions, dtype=float)
    if positions.ndim != 2 or positions.shape[0] != P:
        raise ValueError(f"positions must have shape ({P}, dim), got {positions.shape}")
    graph, starts, targets, found = pair_paths(D, n_pairs, random_state, max_degree, radius)
    straightness, paths, unreachable = [], [], 0
    for path in found:
        paths.append(path)
        if path is None:
            unreachable += 1
            straightness.append(None)
            continue
        straightness.append(path_straightness(path, positions))
    reached = [s for s in straightness if s is not None]
    return {
        "straightness": straightness,
        "straightness_median": float(np.median(reached)) if reached else float("nan"),
        "radius": graph.radius,
        "n_components": graph.n_components,
        "unreachable": unreachable,
        "pairs": [[int(s), int(t)] for s, t in zip(starts, targets)],
        "paths": paths,
    }
