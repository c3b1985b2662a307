"""The manifold the known POVs' loops sweep in motor space, and how far a
motor state lies off it.

The POVs a naive agent finds by compensating the world's displacements
share every pose component a displacement cannot change (on the paper's
arm, the eye's orientation). Their loops therefore sweep a manifold of
fewer dimensions than the motor space: on the paper's four joints, loops of
one dimension over a plane of positions fill three. A search end that
changed such a component (noise hid the weakest pose direction from its
search) lies off that manifold, whatever its motor distance to the nearest
loop says; an end on a new position of the lattice lies on it.

All of it is measured from the loops: the manifold's dimension from the gap
in the singular values of the samples near a POV (``codimension``), its
local plane from the samples of the loops nearest a motor state
(``normal_offset``), and what "off" means from the POVs' own offsets, each
POV measured against the others (``own_offsets``).
"""
from __future__ import annotations

import numpy as np

K_LOOPS = 8     # loops whose nearest samples fit the local plane
AROUND = 2      # samples either side of each loop's nearest one
GAP = 10.0      # a singular value this many times the next one ends the plane


def local_samples(point: np.ndarray, loops: np.ndarray, exclude: int = -1):
    """The samples of the ``K_LOOPS`` loops of ``loops`` ``(K, N, M)``
    nearest ``point`` ``(M,)`` (torus of phases; loop ``exclude`` left
    out), each loop's nearest sample and ``AROUND`` either side of it,
    unwrapped next to ``point``: ``(k (2 AROUND + 1), M)``, and the
    distance from ``point`` to the nearest of them."""
    offsets = (loops - point + np.pi) % (2.0 * np.pi) - np.pi
    squared = np.sum(offsets * offsets, axis=2)
    reach = np.min(squared, axis=1)
    if exclude >= 0:
        reach[exclude] = np.inf
    nearest = np.argsort(reach, kind="stable")[:min(K_LOOPS, len(loops) - (exclude >= 0))]
    length = loops.shape[1]
    around = np.arange(-AROUND, AROUND + 1)
    index = (np.argmin(squared[nearest], axis=1)[:, None] + around) % length
    samples = point + offsets[nearest[:, None], index].reshape(-1, loops.shape[2])
    return samples, float(np.sqrt(reach[nearest[0]]))


def _plane(samples: np.ndarray):
    """Centroid, singular values and right singular vectors of ``samples``."""
    centroid = samples.mean(axis=0)
    _, singular, directions = np.linalg.svd(samples - centroid, full_matrices=True)
    return centroid, singular, directions


def codimension(loops: np.ndarray, probes: np.ndarray) -> int:
    """How many motor directions the loops ``(K, N, M)`` leave out, measured
    at the POVs ``probes`` (indices): at each, the samples of the other
    loops nearest its first sample; over the probes, the median singular
    values (each probe's scaled by its largest). The plane ends at the
    largest jump between consecutive ones if that jump is ``GAP`` or more;
    without one the loops fill the motor space (0)."""
    spectra = []
    for pov in probes:
        singular = _plane(local_samples(loops[pov, 0], loops, exclude=int(pov))[0])[1]
        if singular[0] > 0:
            spectra.append(singular / singular[0])
    if not spectra:
        return 0
    median = np.median(spectra, axis=0)
    if len(median) < 2:
        return 0
    with np.errstate(divide="ignore"):
        jumps = median[:-1] / median[1:]
    dimension = int(np.argmax(jumps)) + 1
    return len(median) - dimension if jumps[dimension - 1] >= GAP else 0


def normal_offset(point: np.ndarray, loops: np.ndarray, codim: int, exclude: int = -1):
    """Distance from ``point`` to the plane the samples of the loops
    nearest it span (``exclude`` left out), along the ``codim`` directions
    they leave out; and the distance from ``point`` to the nearest sample,
    which sizes how far the plane is extrapolated."""
    samples, reach = local_samples(point, loops, exclude)
    centroid, _, directions = _plane(samples)
    normal = directions[directions.shape[0] - codim:]
    return float(np.linalg.norm(normal @ (point - centroid))), reach


def own_offsets(loops: np.ndarray, probes: np.ndarray, codim: int) -> np.ndarray:
    """Each POV of ``probes``: its first sample's ``normal_offset`` from the
    other loops, what the POVs' own spread off their manifold is (measured
    a neighbour's distance away, what ``PovStore.separation`` is the median
    of)."""
    return np.array([normal_offset(loops[pov, 0], loops, codim, exclude=int(pov))[0]
                     for pov in probes])
