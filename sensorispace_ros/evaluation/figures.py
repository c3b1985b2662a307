"""The paper's result figures, drawn from a run's arrays (``arrays.npz``).

Every function takes the mapping of arrays a run writes (``run_files``),
so a figure can be redrawn from ``arrays.npz`` without re-running anything.
File names follow the paper's figure numbers (LaTeX source order): 6 point
of view, 7 exploration, 8 projections, 9 metric differences, 11 equality
sets, 12 regularised projections, 14/15 reaching, 16 metric comparisons;
``persistence_diagrams`` is the topology the evaluation measures.
Drawing pieces shared by the figures are in ``figure_style``.

Colour code (as in the paper): a POV is coloured by the position of its
sensor, hue = angle of the tip around the arm's base, saturation = distance
from the base (pale near the hole of radius 1, vivid at the reach 3). The
same POV has the same colour in every panel, so topology can be read by eye.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import to_rgb  # noqa: E402
from matplotlib.patches import Circle, Wedge  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: E402

from sensorispace_ros.core import arm  # noqa: E402
from sensorispace_ros.core.seeding import rng_for  # noqa: E402
from sensorispace_ros.core.arm import Arm  # noqa: E402
from sensorispace_ros.core.paper.points_of_view import (project_onto_pose,  # noqa: E402
                                                        sample_points_of_view)
from sensorispace_ros.evaluation.evaluator import missed_ring_positions  # noqa: E402
from sensorispace_ros.evaluation.figure_style import (ARM_HOLE, ARM_REACH, DPI,  # noqa: E402
                                                      PAIR_COLOURS, add_segments, centred_loop,
                                                      closed, draw_arms, equal_3d, face_on,
                                                      grid_transitions, motor_axes, panel_axes,
                                                      position_colours, scatter_points,
                                                      segments_of, wrapped_path)
from sensorispace_ros.evaluation.space_figures import (fig14_reaching_2d,  # noqa: E402
                                                       fig15_reaching_3d, persistence_diagrams)
from sensorispace_ros.offline.chain_pool import can_fork  # noqa: E402
from sensorispace_ros.offline.strategies import pov_params  # noqa: E402


# ---------------------------------------------------------------------------
# Figures


def fig06_point_of_view(arrays: Mapping) -> plt.Figure:
    """Paper Fig. 6: (a) one POV, arm configurations and its motor-space loop;
    (b) POVs of tips along the x axis; closer than 1 to the base the fibre
    splits and the kernel walk traces only one of its two loops."""
    fig = plt.figure(figsize=(12, 9.5))
    example = np.asarray(arrays["pov_example"])
    n = len(example)
    order_colours = plt.get_cmap("viridis")(np.linspace(0.0, 1.0, n, endpoint=False))[:, :3]
    shown = np.arange(0, n, max(n // 12, 1))

    _one_pov_panels(fig, example, order_colours, shown)
    _povs_along_x_panels(fig, arrays)
    fig.tight_layout()
    return fig


def _one_pov_panels(fig, example: np.ndarray, order_colours, shown: np.ndarray) -> None:
    """Fig. 6a: one POV's arm configurations, and its loop in motor space."""
    n = len(example)
    ax = fig.add_subplot(2, 2, 1)
    draw_arms(ax, example[shown], order_colours[shown], linewidth=1.2, eye_length=0.35)
    ax.set_aspect("equal")
    ax.set_xlim(-3.2, 3.2)
    ax.set_ylim(-3.2, 3.2)
    tip = arm.forward(example[0])
    ax.set_title(f"(a) one point of view: {len(shown)} of its {n} arm configurations\n"
                 f"share the sensor pose ({tip[0]:.2f}, {tip[1]:.2f}, "
                 f"{arm.wrap_angle(tip[2]):.2f} rad)", fontsize=10)

    ax = fig.add_subplot(2, 2, 2, projection="3d")
    loop = closed(centred_loop(example))
    segments = np.stack([loop[:-1, :3], loop[1:, :3]], axis=1)
    ax.add_collection3d(Line3DCollection(segments, colors=order_colours, linewidths=2.0))
    ax.scatter(*example[shown, :3].T, c=order_colours[shown], s=25, depthshade=False)
    equal_3d(ax, loop[:, :3])
    face_on(ax, loop[:, :3])
    motor_axes(ax)
    ax.set_title("(a) the same POV in motor space: a closed 1-D loop\n"
                 "(joints 1-3; colour = position along the loop)", fontsize=10)


def _povs_along_x_panels(fig, arrays: Mapping) -> None:
    """Fig. 6b: POVs of tips along the x axis, arms and loops in motor space."""
    povs = np.asarray(arrays["pov_examples_x"])
    valid = np.asarray(arrays["pov_examples_x_valid"], dtype=bool)
    tips = arm.forward(povs[:, 0])
    cmap = plt.get_cmap("cool")
    colours = [cmap(k / max(len(povs) - 1, 1))[:3] for k in range(len(povs))]
    colours = [c if ok else to_rgb("#e66101") for c, ok in zip(colours, valid)]

    ax = fig.add_subplot(2, 2, 3)
    for k in range(len(povs)):
        draw_arms(ax, povs[k, 0], colours[k], linewidth=1.4, eye_length=0.35)
    ax.add_patch(Circle((0, 0), ARM_HOLE, fill=False, linestyle=":", color="0.4"))
    ax.set_aspect("equal")
    ax.set_xlim(-3.2, 3.2)
    ax.set_ylim(-3.2, 3.2)
    ax.set_title("(b) sensor moved along the x axis (one arm configuration each);\n"
                 "dotted: |tip| = 1", fontsize=10)

    ax = fig.add_subplot(2, 2, 4, projection="3d")
    for k in range(len(povs)):
        if valid[k]:
            loop = closed(centred_loop(povs[k]))
            label = f"|tip| = {np.hypot(*tips[k, :2]):.2f}"
        else:
            # A split fibre: the walk wraps around a joint circle, so the
            # trace is not closed in unwrapped coordinates; draw it as traced.
            loop = wrapped_path(povs[k])
            label = f"|tip| = {np.hypot(*tips[k, :2]):.2f}: one of two loops"
        ax.plot(*loop[:, :3].T, color=colours[k], linewidth=1.5, label=label)
    if valid.any():
        face_on(ax, np.concatenate([closed(centred_loop(p))[:, :3] for p in povs[valid]]))
    motor_axes(ax)
    ax.legend(fontsize=7, loc="upper left")
    ax.set_title("(b) their points of view in motor space", fontsize=10)


def fig07_exploration(arrays: Mapping) -> plt.Figure:
    """Paper Fig. 7: (a) object grid, working space, compensated positions;
    (b) compensating arm configurations; (c) compensating motor states;
    (d) their points of view."""
    m0 = np.asarray(arrays["initial_motor_state"], dtype=float)
    motor = np.asarray(arrays["motor_states"])
    povs = np.asarray(arrays["povs"])
    colours = position_colours(np.asarray(arrays["true_positions"]))

    fig = plt.figure(figsize=(13, 11.5))
    _object_positions_panel(fig.add_subplot(2, 2, 1), arrays)

    ax = fig.add_subplot(2, 2, 2)
    draw_arms(ax, motor, colours, linewidth=0.4, alpha=0.7, eye_length=0.12)
    draw_arms(ax, m0, "k", linewidth=2.0)
    ax.set_aspect("equal")
    ax.set_xlim(-3.3, 3.3)
    ax.set_ylim(-3.3, 3.3)
    ax.set_title("(b) compensating arm configurations\n(colour = angle of the tip around "
                 "the base; pale = near the base)", fontsize=10)

    _motor_states_panel(fig.add_subplot(2, 2, 3, projection="3d"), motor, m0, colours)
    _pov_loops_panel(fig.add_subplot(2, 2, 4, projection="3d"), povs, colours)
    fig.tight_layout()
    return fig


def _object_positions_panel(ax, arrays: Mapping) -> None:
    """Fig. 7 (a): the object grid, the arm's working space, the compensated
    displacements and the grid positions in reach that none compensated."""
    grid = np.asarray(arrays["grid"])
    m0 = np.asarray(arrays["initial_motor_state"], dtype=float)
    tip0 = arm.forward(m0)[:2]
    ax.add_patch(Wedge((0, 0), ARM_REACH, 0, 360, width=ARM_REACH - ARM_HOLE,
                       color="#a6dba0", alpha=0.6, linewidth=0, label="arm working space"))
    ax.scatter(*grid.T, s=2, color="0.75", linewidths=0, label="object positions (grid)")
    # Each POV compensates the object displacement that moved its sensor
    # from the start: tip_i - tip0. Drawn at start centre (0, 0) + that
    # displacement, so the paper strategy's POVs land on their grid positions
    # and a naive run's (anchored with the object on the grid, hence half a
    # cell off the paper's lattice) are shown where they really are.
    equivalent = np.asarray(arrays["true_positions"]) - tip0
    ax.scatter(*equivalent.T, s=7, color="#2166ac", linewidths=0,
               label=f"compensated displacements ({len(equivalent)} POVs)")
    for radius in (ARM_HOLE, ARM_REACH):
        ax.add_patch(Circle(-tip0, radius, fill=False, linestyle="--", color="#2166ac",
                            linewidth=0.8, label=None if radius == ARM_HOLE else
                            "object positions the tip can follow"))
    # The evaluator's ring positions no POV covers (exploration.missed_in_ring),
    # drawn at the object displacement that asks for them.
    missed = missed_ring_positions(np.asarray(arrays["true_positions"]),
                                   float(arrays["grid_spacing"])) - tip0
    if len(missed):
        ax.scatter(*missed.T, s=30, facecolors="none", edgecolors="#d7191c",
                   linewidths=1.0, label=f"in reach, not compensated ({len(missed)})")
    draw_arms(ax, m0, "k", linewidth=2.0)
    ax.set_aspect("equal")
    half = np.abs(grid).max() + 0.3
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.legend(fontsize=7, loc="upper right", framealpha=0.9)
    ax.set_title("(a) object positions and the arm's initial configuration", fontsize=10)


def _motor_states_panel(ax, motor: np.ndarray, m0: np.ndarray, colours) -> None:
    """Fig. 7 (c): the compensating motor states, joints 1-3."""
    shown = centred_loop(motor[:, None, :])[:, 0]
    ax.scatter(*shown[:, :3].T, c=colours, s=8, depthshade=False, linewidths=0)
    m0_shown = centred_loop(m0[None, None, :])[0, 0]
    ax.scatter(*m0_shown[:3], color="k", s=80, marker="o", depthshade=False,
               label="initial motor state")
    motor_axes(ax)
    ax.legend(fontsize=7)
    ax.set_title("(c) compensating motor states (joints 1-3)", fontsize=10)


def _pov_loops_panel(ax, povs: np.ndarray, colours) -> None:
    """Fig. 7 (d): every POV as a loop in motor space, joints 1-3."""
    loops = closed(centred_loop(povs))[:, :, :3]
    # One polyline per loop (not 2-point segments): far quicker to save.
    ax.add_collection3d(Line3DCollection(loops, colors=colours,
                                         linewidths=0.3 if len(povs) > 200 else 0.8,
                                         alpha=0.6))
    equal_3d(ax, loops.reshape(-1, 3))
    motor_axes(ax)
    ax.set_title(f"(d) their {len(povs)} points of view (loops in motor space)", fontsize=10)


def _projection_panels(fig, arrays: Mapping, panels, suptitle: str) -> plt.Figure:
    colours = position_colours(arrays["true_positions"])
    for position, points, title in panels:
        points = np.asarray(points)
        ax = panel_axes(fig, position, points.shape[1], title)
        scatter_points(ax, points, colours, size=10)
        if points.shape[1] == 3:
            equal_3d(ax, points)
    fig.suptitle(suptitle, fontsize=11)
    fig.tight_layout()
    return fig


def fig08_projections_before(arrays: Mapping) -> plt.Figure:
    """Paper Fig. 8: CCA projections of the POVs (Hausdorff metric) in 2-D and 3-D."""
    fig = plt.figure(figsize=(12, 5.8))
    return _projection_panels(fig, arrays, [
        (121, arrays["embedding_2d_before"], "(a) 2-D projection"),
        (122, arrays["embedding_3d_before"], "(b) 3-D projection"),
    ], "Points of view projected by CCA from the Hausdorff metric (colour = sensor position)")


def fig09_metric_differences(arrays: Mapping) -> plt.Figure:
    """Paper Fig. 9: equal external grid steps (blue horizontal, red vertical)
    and the internal 2-D / 3-D vectors that represent them."""
    positions = np.asarray(arrays["true_positions"])
    horizontal, vertical = grid_transitions(positions, float(arrays["grid_spacing"]))
    fig = plt.figure(figsize=(16, 5.5))
    spaces = [(positions, "(a) external sensor positions: every step has the same length"),
              (np.asarray(arrays["embedding_2d_before"]), "(b) the same steps in 2-D"),
              (np.asarray(arrays["embedding_3d_before"]), "(c) the same steps in 3-D")]
    for k, (points, title) in enumerate(spaces):
        ax = panel_axes(fig, 131 + k, points.shape[1], title)
        add_segments(ax, segments_of(points, horizontal), "#2166ac", linewidth=0.7)
        add_segments(ax, segments_of(points, vertical), "#d6604d", linewidth=0.7)
        if points.shape[1] == 3:
            equal_3d(ax, points)
        else:
            ax.autoscale()
    fig.tight_layout()
    return fig


def choose_equality_sets(arrays: Mapping, count: int = 3, seed: int = 0) -> list[int]:
    """``count`` well-populated sets with short, differently directed displacements."""
    pairs = np.asarray(arrays["pairs"], dtype=int)
    set_ids = np.asarray(arrays["set_ids"], dtype=int)
    positions = np.asarray(arrays["true_positions"])
    spacing = float(arrays["grid_spacing"])
    ids, sizes = np.unique(set_ids, return_counts=True)
    if len(ids) == 0:
        return []
    first = np.array([np.flatnonzero(set_ids == i)[0] for i in ids])
    displacement = positions[pairs[first, 1]] - positions[pairs[first, 0]]
    length = np.hypot(*displacement.T)
    # Readable arrows: a few grid steps long, in sets larger than most.
    candidate = (length >= 2.5 * spacing) & (length <= 4.5 * spacing)
    candidate &= sizes >= np.quantile(sizes, 0.5)
    if candidate.sum() < count:
        candidate = np.ones(len(ids), dtype=bool)
    pool = np.flatnonzero(candidate)
    rng = rng_for(seed, "figures.equality_sets")
    chosen: list[int] = []
    for k in rng.permutation(pool):
        direction = np.arctan2(displacement[k, 1], displacement[k, 0])
        if all(abs(arm.wrap_angle(direction - np.arctan2(displacement[c, 1], displacement[c, 0])))
               > np.pi / 4 for c in chosen):
            chosen.append(int(k))
        if len(chosen) == count:
            break
    return [int(ids[k]) for k in chosen]


def fig11_equality_sets(arrays: Mapping, seed: int = 0) -> plt.Figure:
    """Paper Fig. 11: three sets of POV changes that compensate one object
    displacement each: equal vectors outside, unequal inside (before
    regularisation)."""
    pairs = np.asarray(arrays["pairs"], dtype=int)
    set_ids = np.asarray(arrays["set_ids"], dtype=int)
    chosen = choose_equality_sets(arrays, seed=seed)
    rng = rng_for(seed, "figures.equality_set_members")
    members = []
    for set_id in chosen:
        rows = np.flatnonzero(set_ids == set_id)
        members.append(pairs[np.sort(rng.permutation(rows)[:15])])
    fig = plt.figure(figsize=(16, 5.5))
    spaces = [(np.asarray(arrays["true_positions"]), "(a) external space: identical displacements"),
              (np.asarray(arrays["embedding_2d_before"]), "(b) 2-D representation"),
              (np.asarray(arrays["embedding_3d_before"]), "(c) 3-D representation")]
    for k, (points, title) in enumerate(spaces):
        ax = panel_axes(fig, 131 + k, points.shape[1], title)
        scatter_points(ax, points, "0.82", size=5)
        for colour, rows in zip(PAIR_COLOURS, members):
            segments = segments_of(points, rows)
            add_segments(ax, segments, colour, linewidth=1.3)
            scatter_points(ax, segments[:, 1], colour, size=14)     # heads mark the direction
        if points.shape[1] == 3:
            equal_3d(ax, points)
    fig.suptitle("Three equality sets (up to 15 members each; dots mark where each change ends)",
                 fontsize=11)
    fig.tight_layout()
    return fig


def fig12_projections_regularized(arrays: Mapping) -> plt.Figure:
    """Paper Fig. 12: projections after the first and the last regularisation iteration."""
    it2 = np.asarray(arrays["embedding_2d_iterations"])
    it3 = np.asarray(arrays["embedding_3d_iterations"])
    last = len(it2)
    fig = plt.figure(figsize=(12, 11))
    return _projection_panels(fig, arrays, [
        (221, it2[0], "2-D after iteration 1"),
        (222, it2[-1], f"2-D after iteration {last}"),
        (223, it3[0], "3-D after iteration 1"),
        (224, it3[-1], f"3-D after iteration {last}"),
    ], "Projections during metric regularisation (colour = sensor position)")


def fig16_metric_comparisons(arrays: Mapping, seed: int = 0,
                             fraction: float = 0.05) -> plt.Figure:
    """Paper Fig. 16: distances of a random 5 % of POV pairs in pairs of metrics."""
    positions = np.asarray(arrays["true_positions"])
    n = len(positions)
    rows, cols = np.triu_indices(n, k=1)
    rng = rng_for(seed, "figures.metric_comparisons")
    keep = rng.random(len(rows)) < fraction
    rows, cols = rows[keep], cols[keep]

    def pair_distance(points):
        points = np.asarray(points)
        return np.linalg.norm(points[rows] - points[cols], axis=1)

    external = pair_distance(positions)
    hausdorff = np.asarray(arrays["hausdorff"])[rows, cols]
    internal = {f"{d} {stage}": pair_distance(arrays[f"embedding_{d}_{stage}"])
                for d in ("2d", "3d") for stage in ("before",)}
    internal.update({f"{d} after":
                     pair_distance(np.asarray(arrays[f"embedding_{d}_iterations"])[-1])
                     for d in ("2d", "3d")})
    panels = [
        ("(a)", external, hausdorff, "external", "Hausdorff"),
        ("(a)", hausdorff, internal["2d before"], "Hausdorff", "2-D before"),
        ("(a)", hausdorff, internal["3d before"], "Hausdorff", "3-D before"),
        ("(b)", external, internal["2d before"], "external", "2-D before"),
        ("(b)", external, internal["3d before"], "external", "3-D before"),
        ("(c)", external, internal["2d after"], "external", "2-D after"),
        ("(c)", external, internal["3d after"], "external", "3-D after"),
    ]
    size = float(np.clip(4000.0 / max(len(rows), 1), 1.5, 12.0))
    alpha = float(np.clip(2000.0 / max(len(rows), 1), 0.25, 0.8))
    fig, axes = plt.subplots(3, 3, figsize=(12, 11.5))
    slots = [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (2, 0), (2, 1)]
    for (r, c), (label, x, y, xname, yname) in zip(slots, panels):
        ax = axes[r, c]
        ax.scatter(x, y, s=size, color="#2166ac", alpha=alpha, linewidths=0, rasterized=True)
        ax.set_xlabel(f"{xname} distance", fontsize=8)
        ax.set_ylabel(f"{yname} distance", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_title(f"{label} {yname} vs {xname}", fontsize=9)
    for r, c in [(1, 2), (2, 2)]:
        axes[r, c].axis("off")
    axes[1, 2].text(0.0, 0.5,
                    f"{len(rows)} of {n * (n - 1) // 2} POV pairs ({100 * fraction:.0f} %)\n\n"
                    "(a) the agent's metric and its projections\n"
                    "(b) before regularisation vs the external metric\n"
                    "(c) after regularisation vs the external metric",
                    fontsize=9, va="center", transform=axes[1, 2].transAxes)
    fig.tight_layout()
    return fig


FIGURES: dict[str, Callable] = {
    "fig06_point_of_view": fig06_point_of_view,
    "fig07_exploration": fig07_exploration,
    "fig08_projections_before": fig08_projections_before,
    "fig09_metric_differences": fig09_metric_differences,
    "fig11_equality_sets": fig11_equality_sets,
    "fig12_projections_regularized": fig12_projections_regularized,
    "fig14_reaching_2d": fig14_reaching_2d,
    "fig15_reaching_3d": fig15_reaching_3d,
    "fig16_metric_comparisons": fig16_metric_comparisons,
    "persistence_diagrams": persistence_diagrams,
}
SEEDED = {"fig11_equality_sets", "fig14_reaching_2d", "fig15_reaching_3d",
          "fig16_metric_comparisons"}


def draw_all(arrays: Mapping, out_dir: str | Path, seed: int = 0,
             progress: Callable | None = None, only=None) -> list[Path]:
    """Write every figure (or those named in ``only``) as
    ``out_dir/<name>.png``; return the paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if only is not None:
        unknown = sorted(set(only) - set(FIGURES))
        if unknown:
            raise ValueError(f"only names unknown figures: {unknown}")
    chosen = [(name, draw) for name, draw in FIGURES.items() if only is None or name in only]
    written = []
    for k, (name, draw) in enumerate(chosen):
        fig = draw(arrays, seed=seed) if name in SEEDED else draw(arrays)
        path = out_dir / f"{name}.png"
        fig.savefig(path, dpi=DPI)
        plt.close(fig)
        written.append(path)
        if progress is not None:
            progress(k + 1, len(chosen))
    return written


EXAMPLES_FIGURE = "fig06_point_of_view"
# Figures that draw the paper's arm (its links, its 1-D loops in joints 1-3).
PAPER_ARM_FIGURES = (EXAMPLES_FIGURE, "fig07_exploration")


def draw_run_figures(arrays: Mapping, cfg: dict, figures_dir: Path, progress=None) -> dict:
    """Every figure of a run; returns the arrays of Fig. 6's example POVs.

    Fig. 6 samples POVs of its own (``figure_examples``), so when
    ``chain_pool.can_fork`` a forked process does it while this one draws the others.
    On another body than the paper's, the figures of the paper's arm
    (``PAPER_ARM_FIGURES``) are left out and the others drawn.
    """

    if not Arm.from_config(cfg["arm"]).is_paper:
        draw_all(arrays, figures_dir, seed=cfg["seed"], progress=progress,
                 only=[name for name in FIGURES if name not in PAPER_ARM_FIGURES])
        return {}
    others = [name for name in FIGURES if name != EXAMPLES_FIGURE]
    if not (can_fork() and (os.cpu_count() or 1) > 1):
        examples = _examples_figure(cfg, figures_dir)
        draw_all(arrays, figures_dir, seed=cfg["seed"], progress=progress, only=others)
        return examples
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=1,
                             mp_context=multiprocessing.get_context("fork")) as pool:
        future = pool.submit(_examples_figure, cfg, figures_dir)
        draw_all(arrays, figures_dir, seed=cfg["seed"], progress=progress, only=others)
        return future.result()


def _examples_figure(cfg: dict, figures_dir: Path) -> dict:
    """Fig. 6 from its own POVs (``figure_examples``); returns those arrays."""
    examples = figure_examples(cfg)
    draw_all(examples, figures_dir, seed=cfg["seed"], only=[EXAMPLES_FIGURE])
    return examples


def figure_examples(cfg: dict) -> dict:
    """POVs drawn only for Fig. 6: the initial motor state's POV, and POVs
    of sensor poses along the x axis (one of them inside |tip| < 1)."""

    m0 = np.asarray(cfg["arm"]["initial_motor_state"], dtype=float)
    reach = np.array([0.6, 1.3, 1.8, 2.3, 2.8])
    # Start each from a folded arm pointing along x, projected onto its pose.
    guess = np.array([[-1.2, 1.6, -0.4 - 0.2 * k, 0.0] for k in range(len(reach))])
    guess[:, 3] = -np.sum(guess[:, :3], axis=1) + np.pi / 2     # eye looking up
    targets = np.stack([reach, np.zeros_like(reach), np.full_like(reach, np.pi / 2)], axis=1)
    starts, error = project_onto_pose(guess[:, None, :], targets)
    starts = starts[:, 0][error[:, 0] < 1e-9]
    sampled = sample_points_of_view(np.vstack([m0[None, :], starts]), **pov_params(cfg))
    tips = np.hypot(*arm.forward(sampled.samples[1:, 0])[:, :2].T)
    return {"pov_example": sampled.samples[0],
            "pov_examples_x": sampled.samples[1:],
            "pov_examples_x_valid": np.asarray(sampled.valid[1:], dtype=bool),
            "pov_examples_x_reach": tips}
