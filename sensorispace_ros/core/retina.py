"""Pinhole eye with a 1-D retina of receptors (paper Sec. 2.3, "The agent").

A light at sensor-frame coordinates (depth u > 0, lateral v) projects on the
retina at ``p_l = v / u`` (unit focal length; the paper leaves the retina's
size free because the geometry is projective). Receptor r outputs
``sum_l exp(-(p_r - p_l)**2) / d_l`` over the lights in front of the lens,
``d_l`` being the lens-light distance. A light that approaches the lens plane
projects to infinity, so its contribution fades smoothly to zero: the
sensation is a smooth function of the pose.
"""
from __future__ import annotations

import numpy as np

N_RECEPTORS = 6


def draw_receptor_positions(rng: np.random.Generator, count: int = N_RECEPTORS,
                            half_width: float = 1.0) -> np.ndarray:
    """Receptor positions drawn uniformly on the retina, sorted for readability."""
    if count < 1:
        raise ValueError(f"receptor count must be >= 1, got {count}")
    if half_width <= 0:
        raise ValueError(f"retina half_width must be > 0, got {half_width}")
    return np.sort(rng.uniform(-half_width, half_width, size=count))


def project(pose: np.ndarray, lights_world: np.ndarray):
    """Projection ``p`` and distance ``d`` of each light; ``visible`` mask.

    ``pose``: ``(..., 3)``; ``lights_world``: ``(L, 2)`` or ``(..., L, 2)``.
    Returns arrays of shape ``(..., L)``.
    """
    pose = np.asarray(pose, dtype=float)
    lights = np.asarray(lights_world, dtype=float)
    rel = lights - pose[..., None, :2]
    cos_a = np.cos(pose[..., 2])[..., None]
    sin_a = np.sin(pose[..., 2])[..., None]
    depth = rel[..., 0] * cos_a + rel[..., 1] * sin_a
    lateral = -rel[..., 0] * sin_a + rel[..., 1] * cos_a
    distance = np.hypot(rel[..., 0], rel[..., 1])
    visible = depth > 0.0
    safe_depth = np.where(visible, depth, 1.0)
    projection = np.where(visible, lateral / safe_depth, np.inf)
    return projection, distance, visible


# exp(-x) for x above this is exactly 0.0 in float64 (below half the smallest
# subnormal from x ~ 745.1 on).
_EXP_UNDERFLOW = 800.0


def sensation(pose: np.ndarray, lights_world: np.ndarray,
              receptor_positions: np.ndarray) -> np.ndarray:
    """Sensory vector of the eye at ``pose``: shape ``(..., n_receptors)``.

    The same floating-point operations as ``project`` followed by the sum of
    ``exp(-(p_r - p_l)**2) / d_l`` over lights in light order, evaluated only
    for the (pose, light) pairs in front of the lens; the others add an exact
    0.0. About half the lights of a batch are behind the lens, so this is ~3x
    faster than the dense ``(..., L, R)`` evaluation with identical bits
    (tests/core/test_body_simulation.py).
    """
    pose = np.asarray(pose, dtype=float)
    lights = np.asarray(lights_world, dtype=float)
    receptors = np.asarray(receptor_positions, dtype=float)
    if receptors.ndim != 1:
        raise ValueError(f"receptor_positions must be 1-D, got shape {receptors.shape}")
    if pose.shape[-1:] != (3,) or lights.ndim < 2 or lights.shape[-1] != 2:
        raise ValueError(f"pose must be (..., 3) and lights_world (L, 2) or (..., L, 2), "
                         f"got {pose.shape} and {lights.shape}")
    n_lights, n_receptors = lights.shape[-2], len(receptors)
    lead = pose.shape[:-1]
    if lights.ndim > 2:                  # one light configuration per pose
        lead = np.broadcast_shapes(lead, lights.shape[:-2])
        lights = np.broadcast_to(lights, lead + lights.shape[-2:]).reshape(-1, n_lights, 2)
        pose = np.broadcast_to(pose, lead + (3,))
    pose = pose.reshape(-1, 3)
    n_poses = len(pose)
    # Light-major (L, poses) tables: the sum over lights at the end is then a
    # reduction over the first axis (summing the middle axis of (poses, L, R)
    # runs 6-element inner loops: 10x slower for 649 poses).
    lights_x, lights_y = (lights[..., 0].T, lights[..., 1].T) if lights.ndim > 2 else (
        lights[:, 0:1], lights[:, 1:2])
    cos_a = np.cos(pose[:, 2])
    sin_a = np.sin(pose[:, 2])
    rel_x = lights_x - pose[:, 0]                           # (L, n_poses)
    rel_y = lights_y - pose[:, 1]
    depth = rel_x * cos_a + rel_y * sin_a
    in_front = (depth > 0.0).reshape(-1).nonzero()[0]       # light * n_poses + pose
    owner = in_front % n_poses
    rel_x, rel_y = rel_x.reshape(-1)[in_front], rel_y.reshape(-1)[in_front]
    projection = (-rel_x * sin_a[owner] + rel_y * cos_a[owner]) / depth.reshape(-1)[in_front]
    distance = np.hypot(rel_x, rel_y)
    with np.errstate(over="ignore", invalid="ignore"):
        exponent = receptors - projection[:, None]          # (in front, R)
        exponent *= exponent
    # Far projections: exp(-x) = 0.0 for every x >= _EXP_UNDERFLOW; clipping them
    # there keeps exp out of its slow underflow path (NaN stays NaN).
    np.minimum(exponent, _EXP_UNDERFLOW, out=exponent)
    np.negative(exponent, out=exponent)
    term = np.exp(exponent, out=exponent)
    term /= distance[:, None]
    # Hidden lights add an exact 0.0; the lights are added in light order, as
    # the dense evaluation adds them.
    terms = np.zeros((n_lights * n_poses, n_receptors))
    terms[in_front] = term
    return np.add.reduce(terms.reshape(n_lights, -1), axis=0).reshape(lead + (n_receptors,))


def lights_in_view(pose: np.ndarray, lights_world: np.ndarray,
                   receptor_positions: np.ndarray, reach: float = 2.0) -> np.ndarray:
    """How many lights project within ``reach`` of some receptor (they excite it)."""
    projection, _, visible = project(pose, lights_world)
    receptors = np.asarray(receptor_positions, dtype=float)
    with np.errstate(invalid="ignore"):
        near = np.abs(projection[..., :, None] - receptors).min(axis=-1) < reach
    return np.sum(near & visible, axis=-1)
