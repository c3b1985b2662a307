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
in the singular values of the samples near a POV, and what "off" means from
the POVs' own offsets, each POV measured against the others (``measure``);
a motor state's offset from the plane of the loops nearest it
(``normal_offset``).
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.motor_loops import wrap_phase

K_LOOPS = 8     # loops whose nearest samples fit the local plane
AROUND = 2      # samples either side of each loop's nearest one
GAP = 10.0      # a singular value this many times the next one ends the plane


def local_samples(point: np.ndarray, loops: np.ndarray, exclude: int = -1):
    """The samples of the ``K_LOOPS`` loops of ``loops`` ``(K, N, M)``
    nearest ``point`` ``(M,)`` (torus of phases; loop ``exclude`` left
    out), each loop's nearest sample and ``AROUND`` either side of it,
    unwrapped next to ``point``: ``(k (2 AROUND + 1), M)``, and the
    distance from ``point`` to the nearest of them."""
    offsets = wrap_phase(loops - point)
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


def measure(loops: np.ndarray, probes: np.ndarray):
    """``(codimension, own offsets)`` of the loops ``(K, N, M)``, measured at
    the POVs ``probes`` (indices), each from the plane of the other loops'
    samples nearest its first sample. The codimension is how many motor
    directions the loops leave out: over the probes, the median singular
    values of those samples (each probe's scaled by its largest); the plane
    ends at the largest jump between consecutive ones if that jump is
    ``GAP`` or more, else the loops fill the motor space (0). The own
    offsets ``(len(probes),)`` are each probe's ``normal_offset`` from its
    plane, the POVs' own spread off their manifold, measured a neighbour's
    distance away (what ``PovStore.separation`` is the median of); None
    where the codimension is 0."""
    points = loops[np.asarray(probes, dtype=int), 0]
    planes = [_plane(local_samples(point, loops, exclude=int(pov))[0])
              for point, pov in zip(points, probes)]
    codim = _codimension([singular for _, singular, _ in planes])
    if not codim:
        return 0, None
    return codim, np.array([_offset(point, plane, codim) for point, plane in zip(points, planes)])


def _codimension(spectra) -> int:
    """``measure``'s codimension from each probe's singular values."""
    spectra = [singular / singular[0] for singular in spectra if singular[0] > 0]
    if not spectra:
        return 0
    median = np.median(spectra, axis=0)
    if len(median) < 2:
        return 0
    with np.errstate(divide="ignore"):
        jumps = median[:-1] / median[1:]
    dimension = int(np.argmax(jumps)) + 1
    return len(median) - dimension if jumps[dimension - 1] >= GAP else 0


def _offset(point: np.ndarray, plane, codim: int) -> float:
    """Distance from ``point`` to ``plane`` (``_plane``'s) along its last
    ``codim`` directions."""
    centroid, _, directions = plane
    normal = directions[directions.shape[0] - codim:]
    return float(np.linalg.norm(normal @ (point - centroid)))


def normal_offset(point: np.ndarray, loops: np.ndarray, codim: int, exclude: int = -1):
    """Distance from ``point`` to the plane the samples of the loops
    nearest it span (``exclude`` left out), along the ``codim`` directions
    they leave out; and the distance from ``point`` to the nearest sample,
    which sizes how far the plane is extrapolated."""
    samples, reach = local_samples(point, loops, exclude)
    return _offset(point, _plane(samples), codim), reach
