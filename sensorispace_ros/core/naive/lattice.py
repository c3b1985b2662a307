"""Where the agent's POVs lie on the lattice of the world's displacements,
from its equality sets alone.

Every pair ``i -> j`` of one equality set moves a POV by one displacement:
``x[j] - x[i]`` is the same for all its pairs. Asking that of consecutive
pairs of every set gives a linear system in the POVs' positions ``x``; the
constant and the space's own coordinates solve it, so the near-zero
eigenvectors of its normal matrix are the POVs' positions up to an affine
map (``null_space_positions``). The number of such directions beyond the
constant is the dimension of the space, measured.

The world moves by steps of a grid, so the POVs found by compensating lie
on a lattice: whitened (an affine map of the lattice is a lattice), the
shortest differences between POVs give a reduced basis (Lagrange-Gauss),
and each POV's coordinates in it are integers (``lattice_coordinates``).
Where they are not (a wrong equality, positions off the grid, a space of
more than two dimensions) there is no lattice: the caller does without.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import ArpackNoConvergence, eigsh
from scipy.spatial import cKDTree

__all__ = ["Lattice", "basis_coordinates", "consecutive_pairs", "constraint_normal_matrix",
           "lattice_coordinates", "null_space_positions", "reduced_basis", "smallest_eigenvectors"]

NULL_TOL = 1e-8         # an eigenvalue this small (relative to the largest entry) is null
GAP = 1e-5              # the first non-null eigenvalue is at least this (relative)
SHIFT = 1e-8            # the shift-invert's shift below zero (relative)
INTEGER_TOL = 0.15      # a coordinate farther than this from an integer: no lattice
NEIGHBOURS = 7          # nearest POVs whose differences propose basis vectors


@dataclass
class Lattice:
    """``ij`` ``(P, d)`` integer coordinates of the POVs with ``placed`` true
    (the others are not tied to the largest connected group of equalities);
    ``residual`` the largest distance of a placed POV's coordinates from integers."""

    ij: np.ndarray
    placed: np.ndarray
    residual: float

    @property
    def dim(self) -> int:
        return self.ij.shape[1]


def consecutive_pairs(pairs: np.ndarray, set_ids: np.ndarray):
    """``(first, second)`` ``(C, 2)`` each: the pairs ``i1 -> j1``, ``i2 -> j2``
    that follow each other in one set (sets in order of their ids, each
    set's pairs in their order): one equality of steps per row."""
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    set_ids = np.asarray(set_ids, dtype=int).reshape(-1)
    order = np.argsort(set_ids, kind="stable")
    ids, ordered = set_ids[order], pairs[order]
    consecutive = np.flatnonzero(ids[1:] == ids[:-1])
    return ordered[consecutive], ordered[consecutive + 1]


def constraint_normal_matrix(pairs: np.ndarray, set_ids: np.ndarray, n_povs: int):
    """Sparse ``(P, P)`` normal matrix ``A^T A`` of the rows
    ``x[j2] - x[i2] - x[j1] + x[i1] = 0``, one per ``consecutive_pairs``."""
    first, second = consecutive_pairs(pairs, set_ids)
    rows = np.repeat(np.arange(len(first)), 4)
    cols = np.stack([second[:, 1], second[:, 0], first[:, 1], first[:, 0]], axis=1).ravel()
    values = np.tile([1.0, -1.0, -1.0, 1.0], len(first))
    a = coo_matrix((values, (rows, cols)), shape=(len(first), n_povs)).tocsr()
    return (a.T @ a).tocsr()


def smallest_eigenvectors(pairs, set_ids, n_povs: int, max_dim: int = 3):
    """``(group, values, vectors, scale)``: the ``max_dim + 2`` smallest
    eigenvalues (ascending) and eigenvectors of the constraints' normal matrix
    on ``group``, the POVs of the largest connected group of equalities, and
    the matrix's largest entry; None when the group is too small."""
    normal = constraint_normal_matrix(pairs, set_ids, n_povs)
    tied = np.flatnonzero(normal.diagonal() > 0)
    if len(tied) < 2 * (max_dim + 2):
        return None
    sub = normal[tied][:, tied]
    _, label = connected_components(sub != 0, directed=False)
    group = tied[label == np.bincount(label).argmax()]
    if len(group) < 2 * (max_dim + 2):
        return None
    sub = normal[group][:, group]
    scale = float(abs(sub).max())
    k = min(max_dim + 2, len(group) - 1)
    # Shift-invert about a point just below zero: the smallest eigenvalues of a
    # positive semi-definite matrix, from a sparse factorisation. The shift lies
    # far below the gap a null space must show, so the null directions stand
    # apart from the others after the inversion. A fixed start vector (ARPACK's
    # own is drawn from a state the process carries): the same sets give the
    # same positions in any process.
    start = np.sin(1.0 + np.arange(len(group)))
    try:
        values, vectors = eigsh(sub, k=k, sigma=-SHIFT * scale, which="LM", v0=start)
    except ArpackNoConvergence:
        return None
    order = np.argsort(values)
    return group, values[order], vectors[:, order], scale


def null_space_positions(pairs, set_ids, n_povs: int, max_dim: int = 3):
    """``(P, d)`` positions up to an affine map (NaN where a POV is not in the
    largest connected group of equalities), ``d`` the null directions beyond
    the constant, or None when the group has no clear null space of
    dimension 1 to ``max_dim`` (too few sets, or equalities that contradict)."""
    smallest = smallest_eigenvectors(pairs, set_ids, n_povs, max_dim)
    if smallest is None:
        return None
    group, values, vectors, scale = smallest
    k = len(values)
    null = int(np.count_nonzero(np.abs(values) < NULL_TOL * scale))
    if not 2 <= null <= max_dim + 1 or (null < k and values[null] < GAP * scale):
        return None
    coords = vectors[:, :null]
    coords = coords - coords.mean(axis=0)
    # Drop the constant: the directions orthogonal to it.
    u, s, _ = np.linalg.svd(coords, full_matrices=False)
    coords = u[:, :null - 1] * s[:null - 1]
    positions = np.full((n_povs, null - 1), np.nan)
    positions[group] = coords
    return positions


def basis_coordinates(points: np.ndarray, flat: float = 0.0) -> np.ndarray | None:
    """``(n, d)`` coordinates of ``points`` in a reduced basis of the lattice
    they lie on, whitened first (an affine map of a lattice is a lattice),
    from the first point; None where some direction's variance is at most
    ``flat`` times the largest, or no basis is found."""
    variance, axes = np.linalg.eigh(np.atleast_2d(np.cov(points.T)))
    if np.any(variance <= flat * variance.max()):
        return None
    points = points @ axes / np.sqrt(variance)
    basis = reduced_basis(points)
    if basis is None:
        return None
    return np.linalg.solve(basis.T, (points - points[0]).T).T


def reduced_basis(points: np.ndarray) -> np.ndarray | None:
    """``(d, d)`` rows a reduced basis of the lattice the ``(n, d)`` whitened
    ``points`` lie on (d 1 or 2): the shortest difference, then the shortest
    not along it, reduced (Lagrange-Gauss). None for other dimensions."""
    d = points.shape[1]
    if d not in (1, 2) or len(points) < 3:
        return None
    _, near = cKDTree(points).query(points, k=min(NEIGHBOURS, len(points)))
    diffs = (points[near[:, 1:]] - points[:, None, :]).reshape(-1, d)
    norms = np.linalg.norm(diffs, axis=1)
    keep = norms > 1e-6 * np.median(norms)
    diffs, norms = diffs[keep], norms[keep]
    if not len(diffs):
        return None
    first = diffs[np.argmin(norms)]
    if d == 1:
        return first[None]
    sine = np.abs(diffs[:, 0] * first[1] - diffs[:, 1] * first[0]) / (
        norms * np.linalg.norm(first))
    across = sine > 0.2
    if not np.any(across):
        return None
    second = diffs[across][np.argmin(norms[across])]
    for _ in range(32):
        if second @ second < first @ first:
            first, second = second, first
        m = np.round((first @ second) / (first @ first))
        if m == 0:
            break
        second = second - m * first
    return np.stack([first, second])


def lattice_coordinates(pairs, set_ids, n_povs: int) -> Lattice | None:
    """The POVs' integer coordinates on the lattice their equality sets
    imply (module docstring), or None where they imply none."""
    positions = null_space_positions(pairs, set_ids, n_povs)
    if positions is None:
        return None
    placed = np.all(np.isfinite(positions), axis=1)
    coords = basis_coordinates(positions[placed])
    if coords is None:
        return None
    residual = float(np.max(np.abs(coords - np.round(coords))))
    if residual > INTEGER_TOL:
        return None
    ij = np.zeros((n_povs, coords.shape[1]), dtype=int)
    ij[placed] = np.round(coords).astype(int)
    return Lattice(ij=ij, placed=placed, residual=residual)
