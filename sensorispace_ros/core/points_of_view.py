"""Points of view (POVs): the motor states that share one sensor pose
(paper Sec. 3.1, "Estimating the agent's points of view").

A POV is the 1-D fibre f^-1(f(m)) of the forward model f: R^4 -> R^3. It is
a closed loop in the motor torus and is represented by ``N`` motor states
spread evenly along it. Motor angles stay *unwrapped* (continuous along the
loop); compare them with the periodic motor metric.
"""
from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def loop_winding(path: np.ndarray) -> np.ndarray:
    """Per-joint number of 2 pi turns between the start and the end of a
    closed loop, ``(4,)`` int.

    ``path`` is an unwrapped motor path ``(n, J)`` whose end returns to its
    start modulo 2 pi per joint. A POV whose tip lies at ``|tip| < 1`` is split
    into two loops and the traced one winds around a joint circle (nonzero
    entry); a whole POV comes back with zero winding in every joint.
    """
    path = _as_path(path)
    return np.rint((path[-1] - path[0]) / TWO_PI).astype(int)


def resample_closed_path(path: np.ndarray, n_samples: int = 100) -> np.ndarray:
    """``n_samples`` points equally spaced in arc length along a closed loop.

    ``path`` ``(n, J)`` is unwrapped, starts at the POV's first motor state and
    ends near it modulo 2 pi per joint. The loop is closed by appending the
    start shifted by the per-joint multiple of 2 pi that makes the closing
    segment short (``loop_winding``). Arc length is Euclidean in unwrapped
    coordinates; the first sample is ``path[0]``. Angles are returned as given
    (not wrapped), shape ``(n_samples, J)``.
    """
    path = _as_path(path)
    if int(n_samples) != n_samples or n_samples < 1:
        raise ValueError(f"n_samples must be a positive integer, got {n_samples}")
    n_samples = int(n_samples)
    closing = path[0] + TWO_PI * loop_winding(path)
    loop = np.vstack([path, closing[None, :]])
    segment = np.linalg.norm(np.diff(loop, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(segment)])
    if arc[-1] <= 0.0:
        raise ValueError("path has zero length: cannot resample a loop")
    # Equal spacing over the whole closed length; the end (== start mod 2 pi)
    # is excluded so no sample repeats.
    targets = np.arange(n_samples) * (arc[-1] / n_samples)
    return np.stack([np.interp(targets, arc, loop[:, j]) for j in range(loop.shape[1])],
                    axis=-1)


def _as_path(path: np.ndarray) -> np.ndarray:
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or len(path) < 2:
        raise ValueError(f"path must have shape (n >= 2, joints), got {path.shape}")
    if not np.all(np.isfinite(path)):
        raise ValueError("path contains non-finite values")
    return path
