"""The figure of a turning world's representation: the agent's 3-D embedding
coloured by the true orientation of each POV (a hue wheel: a loop respected
shows the hues in order round it), and the angle coordinate of the looped
dimension (``evaluation.rotations.angle_numbers``) against the true orientation."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

FIGURE_NAME = "rotations_orientation.png"


def draw_orientation_figure(arrays: dict, angle: np.ndarray | None, path: str | Path) -> Path:
    """Draw the figure from a run's ``arrays`` (``true_poses``,
    ``embedding_3d_before``) and the angle coordinate (None: not drawn)."""
    poses = np.asarray(arrays["true_poses"], dtype=float)
    heading = np.mod(poses[:, 2], 2 * np.pi)
    colours = plt.cm.hsv(heading / (2 * np.pi))
    embedding = np.asarray(arrays["embedding_3d_before"], dtype=float)
    figure = plt.figure(figsize=(10, 4.5))
    ax = figure.add_subplot(1, 2, 1, projection="3d")
    ax.scatter(*embedding.T[:3], c=colours, s=6)
    ax.set_title("3-D embedding, coloured by true orientation", fontsize=9)
    ax = figure.add_subplot(1, 2, 2)
    if angle is not None:
        ax.scatter(heading, np.mod(angle, 2 * np.pi), c=colours, s=6)
        ax.set_xlabel("true orientation (rad)")
        ax.set_ylabel("agent's angle coordinate (rad)")
    ax.set_title("angle coordinate of the looped dimension", fontsize=9)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)
    return path
