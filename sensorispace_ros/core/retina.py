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


def sensation(pose: np.ndarray, lights_world: np.ndarray,
              receptor_positions: np.ndarray) -> np.ndarray:
    """Sensory vector of the eye at ``pose``: shape ``(..., n_receptors)``."""
    projection, distance, visible = project(pose, lights_world)
    receptors = np.asarray(receptor_positions, dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        gap = receptors - projection[..., :, None]          # (..., L, R)
        response = np.exp(-gap * gap)
    response = np.where(visible[..., :, None], response, 0.0)
    safe_distance = np.where(visible, distance, 1.0)
    return np.sum(response / safe_distance[..., :, None], axis=-2)


def lights_in_view(pose: np.ndarray, lights_world: np.ndarray,
                   receptor_positions: np.ndarray, reach: float = 2.0) -> np.ndarray:
    """How many lights project within ``reach`` of some receptor (they excite it)."""
    projection, _, visible = project(pose, lights_world)
    receptors = np.asarray(receptor_positions, dtype=float)
    with np.errstate(invalid="ignore"):
        near = np.abs(projection[..., :, None] - receptors).min(axis=-1) < reach
    return np.sum(near & visible, axis=-1)
