"""The representation in use, drawn from a run's arrays: reaching paths
(paper Fig. 14, 15) and the topology the evaluation measures (persistence
diagrams). Registered with the other figures in ``figures.FIGURES``."""
from __future__ import annotations

from typing import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sensorispace_ros.core import reach  # noqa: E402
from sensorispace_ros.core.seeding import rng_for  # noqa: E402
from sensorispace_ros.core.topology import K_SCALE, betti_numbers, persistence  # noqa: E402
from sensorispace_ros.evaluation.evaluator import topology_spaces  # noqa: E402
from sensorispace_ros.evaluation.figure_style import (PAIR_COLOURS, closed,  # noqa: E402
                                                      equal_3d, lighter, motor_axes, panel_axes,
                                                      plot_path, run_config, scatter_points,
                                                      wrapped_path)
from sensorispace_ros.evaluation.run_files import representation_from_arrays  # noqa: E402


def reaching_examples(arrays: Mapping, dim: str, seed: int = 0, count: int = 3) -> dict:
    """Paths of ``count`` random start/target pairs, before and after, through
    the pruned graph of the ``dim`` representation (the figure's data)."""
    cfg = run_config(arrays)["representation"]["reaching"]
    positions = np.asarray(arrays["true_positions"])
    povs = np.asarray(arrays["povs"])
    rng = rng_for(seed, "figures.reaching")
    embeddings = {"before": np.asarray(arrays[f"embedding_{dim}_before"]),
                  "after": np.asarray(arrays[f"embedding_{dim}_iterations"])[-1]}
    graphs = {stage: reach.pruned_graph(_euclidean(points), max_degree=cfg["max_degree"],
                                        radius=cfg["radius"])
              for stage, points in embeddings.items()}
    out = {"starts": [], "targets": [], "paths": {"before": [], "after": []},
           "motor": {"before": [], "after": []}, "embeddings": embeddings}
    tries = 0
    while len(out["starts"]) < count and tries < 100 * count:
        tries += 1
        start, target = rng.choice(len(positions), size=2, replace=False)
        if np.hypot(*(positions[start] - positions[target])) < 2.0:
            continue                      # short paths say little about straightness
        if any(graph.component_labels[start] != graph.component_labels[target]
               for graph in graphs.values()):
            continue                      # not connected in a pruned graph: no path to draw
        paths = {stage: reach.shortest_path(graph, int(start), int(target))
                 for stage, graph in graphs.items()}
        if any(p is None or len(p) < 2 for p in paths.values()):
            continue
        start_sample = int(rng.integers(povs.shape[1]))
        out["starts"].append(int(start))
        out["targets"].append(int(target))
        for stage, path in paths.items():
            out["paths"][stage].append(np.asarray(path, dtype=int))
            out["motor"][stage].append(reach.motor_trajectory(povs, path, start_sample))
    return out


def _euclidean(points: np.ndarray) -> np.ndarray:
    diff = points[:, None, :] - points[None, :, :]
    return np.sqrt(np.sum(diff * diff, axis=-1))


def _reaching_figure(arrays: Mapping, dim: str, number: int, seed: int) -> plt.Figure:
    examples = reaching_examples(arrays, dim, seed=seed)
    positions = np.asarray(arrays["true_positions"])
    povs = np.asarray(arrays["povs"])
    n_dim = int(dim[0])
    fig = plt.figure(figsize=(18, 5.2))
    for k, stage in enumerate(("before", "after")):
        points = examples["embeddings"][stage]
        ax = panel_axes(fig, 141 + k, n_dim,
                        f"(a) internal paths, {dim[0]}-D {stage} regularisation")
        scatter_points(ax, points, "0.82", size=4)
        for colour, path in zip(PAIR_COLOURS, examples["paths"][stage]):
            plot_path(ax, points[path], colour, marker=".", markersize=4)
            scatter_points(ax, points[path[[0, -1]]], colour, size=40)
        if n_dim == 3:
            equal_3d(ax, points)

    ax = fig.add_subplot(143, projection="3d")
    rng = rng_for(seed, "figures.reaching_background")
    for loop in povs[rng.permutation(len(povs))[:max(len(povs) // 10, 1)]]:
        ax.plot(*wrapped_path(closed(loop))[:, :3].T, color="0.88", linewidth=0.4)
    for stage, light in (("before", 0.5), ("after", 0.0)):
        for colour, motor in zip(PAIR_COLOURS, examples["motor"][stage]):
            shown = wrapped_path(motor)
            ax.plot(*shown[:, :3].T, color=lighter(colour, light), linewidth=1.4,
                    marker=".", markersize=3)
    motor_axes(ax)
    ax.set_xlim(-np.pi, np.pi)
    ax.set_ylim(-np.pi, np.pi)
    ax.set_zlim(-np.pi, np.pi)
    ax.set_title("(b) motor trajectories, angles wrapped to [-pi, pi)\n"
                 "(light: before, dark: after; grey: 10 % of the points of view)", fontsize=10)

    ax = fig.add_subplot(144)
    ax.scatter(*positions.T, s=4, color="0.82", linewidths=0)
    for stage, light in (("before", 0.6), ("after", 0.0)):
        for colour, path in zip(PAIR_COLOURS, examples["paths"][stage]):
            ax.plot(*positions[path].T, color=lighter(colour, light), linewidth=2.0,
                    marker=".", markersize=4,
                    label=None if colour != PAIR_COLOURS[0] else f"{stage} regularisation")
    for colour, s, t in zip(PAIR_COLOURS, examples["starts"], examples["targets"]):
        ax.scatter(*positions[[s, t]].T, color=colour, s=40, zorder=3)
    ax.set_aspect("equal")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title("(c) external sensor paths (light: before, dark: after)", fontsize=10)
    fig.suptitle(f"Reaching through the {dim[0]}-D representation (Fig. {number})", fontsize=11)
    fig.tight_layout()
    return fig


def fig14_reaching_2d(arrays: Mapping, seed: int = 0) -> plt.Figure:
    """Paper Fig. 14: three reaching tasks solved in the 2-D representations."""
    return _reaching_figure(arrays, "2d", 14, seed)


def fig15_reaching_3d(arrays: Mapping, seed: int = 0) -> plt.Figure:
    """Paper Fig. 15: the same tasks solved in the 3-D representations."""
    return _reaching_figure(arrays, "3d", 15, seed)


def persistence_diagrams(arrays: Mapping) -> plt.Figure:
    """Rips persistence diagrams (H0, H1) of the true positions, the Hausdorff
    metric and every embedding, in units of each space's own scale, with the
    threshold of the Betti-number rule (``core.topology``)."""
    spaces = topology_spaces(representation_from_arrays(arrays),
                             np.asarray(arrays["true_positions"]))
    order = ["truth", "2d.before", "3d.before", "hausdorff", "2d.after", "3d.after"]
    fig, axes = plt.subplots(2, 3, figsize=(14, 9.2))
    for ax, space in zip(axes.ravel(), order):
        bars = persistence(spaces[space])
        betti = betti_numbers(bars)
        h0, h1 = bars.h0 / bars.scale, bars.h1 / bars.scale
        finite = np.isfinite(h0[:, 1])
        top = 1.1 * max(np.max(h0[finite, 1], initial=1.0), np.max(h1[:, 1], initial=1.0))
        ax.plot([0, top], [0, top], color="0.6", linewidth=0.8)
        ax.plot([0, top - K_SCALE], [K_SCALE, top], color="#d7191c", linestyle="--",
                linewidth=0.8, label=f"lifetime = {K_SCALE:g} x scale")
        ax.scatter(*h0[finite].T, s=9, color="#2166ac", label="H0")
        ax.scatter(h0[~finite, 0], np.full(np.sum(~finite), top), s=30, marker="^",
                   color="#2166ac", label="H0, never dies")
        ax.scatter(*h1.T, s=9, color="#e66101", label="H1")
        ax.set_xlim(0, top)
        ax.set_ylim(0, top * 1.03)
        ax.set_aspect("equal")
        ax.set_xlabel("birth / scale")
        ax.set_ylabel("death / scale")
        ax.set_title(f"{space}: b0 = {betti.betti0}, b1 = {betti.betti1}, "
                     f"margin {betti.margin:.2f}\n({len(bars.landmarks)} of "
                     f"{len(spaces[space])} points)", fontsize=10)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle("Persistent homology (Vietoris-Rips) of the truth and of the agent's "
                 "representations")
    fig.tight_layout()
    return fig
