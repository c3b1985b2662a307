"""The representation against ground truth: the numbers of ``evaluate``.

A run's representation (offline, from the representation node, from a bag)
against the true sensor positions of its points of view: quality of the
embeddings, regularity of the metric, topology, reaching, the working-ring
positions no POV covers. ``runs.evaluate_output`` calls it for every run;
a naive run's own products are judged in ``naive``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.offline.representation import STAGES, Representation, random_state
from sensorispace_ros.offline.timing import timed_stage


def evaluate(representation: Representation, true_positions: np.ndarray, povs: np.ndarray,
             cfg: dict, seed: int, progress=None) -> dict:
    """Ground-truth numbers of a representation (flat dotted keys).

    ``quality.<dim>.<stage>.*``: ``core.quality.quality_report`` plus
    ``neighbours_true_fraction``; ``metric.*.unit_step_cv``: spread of the
    internal lengths of equal external grid steps (Fig. 9 as a number);
    ``metric.*.diagonal_ratio``: internal length of the (+1, +1) grid
    diagonals over the (+1, -1) ones (Fig. 13 as a number, 1 = consistent);
    ``exploration.missed_in_ring``: working-ring positions no POV covers
    (Fig. 7a's red outlines, ``missed_ring_positions``);
    ``topology.<space>.*``: Betti numbers of the true positions, the
    Hausdorff metric and every embedding (``core.topology``), timed as
    ``timings_s.topology``;
    ``regularization.<dim>.set_spread``: spread of the equality sets'
    distances, first of the Hausdorff metric then after each iteration;
    ``reaching.<graph>.*``: straightness of Dijkstra paths between the same
    random start/target pairs in every graph, with its pruning radius and
    degrees; ``timings_s.reaching``. ``povs`` is accepted so callers hand
    over the whole run; no number here needs it yet.
    """
    true_positions = np.asarray(true_positions, dtype=float)
    metrics = _metric_numbers(representation, true_positions)
    from sensorispace_ros.core.world import grid_spacing

    step = grid_spacing(cfg["world"]["grid_half_width"], cfg["world"]["grid_count"])
    metrics["exploration.missed_in_ring"] = len(missed_ring_positions(
        true_positions, step, Arm.from_config(cfg["arm"]).working_ring))
    timings: dict = {}
    with timed_stage(progress, "topology", timings):
        metrics.update(_topology_numbers(representation, true_positions))
    metrics["timings_s.topology"] = timings["topology"]
    with timed_stage(progress, "reaching", timings):
        metrics.update(_reaching_numbers(representation, true_positions, cfg, seed, progress))
    metrics["timings_s.reaching"] = timings["reaching"]
    return metrics


def _metric_numbers(representation: Representation, true_positions: np.ndarray) -> dict:
    """``metric.*``, ``quality.*`` and ``regularization.*`` of ``evaluate``."""
    from scipy.spatial.distance import pdist, squareform

    from sensorispace_ros.core.quality import quality_report
    from sensorispace_ros.core.sensor_grid import diagonal_ratio

    metrics: dict[str, Any] = {}
    spacing = _grid_step(true_positions)
    external = pdist(true_positions)
    neighbours = _true_neighbour_pairs(true_positions, spacing)
    hausdorff_condensed = squareform(representation.distance, checks=False)
    metrics["metric.hausdorff.spearman"] = _spearman(hausdorff_condensed, external)
    metrics["metric.hausdorff.unit_step_cv"] = _unit_step_cv(representation.distance, neighbours)
    metrics["metric.hausdorff.diagonal_ratio"] = diagonal_ratio(representation.distance,
                                                                true_positions, spacing)
    for dim in representation.before:
        for stage in STAGES:
            embedding = representation.embedding(dim, stage)
            prefix = f"quality.{dim}.{stage}"
            for key, value in quality_report(embedding, true_positions).items():
                metrics[f"{prefix}.{key}"] = value
            metrics[f"{prefix}.neighbours_true_fraction"] = _neighbours_true_fraction(
                embedding, true_positions)
            internal = squareform(pdist(embedding))
            metrics[f"metric.{dim}.{stage}.unit_step_cv"] = _unit_step_cv(internal, neighbours)
            metrics[f"metric.{dim}.{stage}.diagonal_ratio"] = diagonal_ratio(
                internal, true_positions, spacing)
        spread = representation.set_spread[dim]
        metrics[f"regularization.{dim}.set_spread"] = [float(v) for v in spread]
    return metrics


def topology_spaces(representation: Representation, true_positions: np.ndarray) -> dict:
    """The distance matrices ``topology.<space>`` measures: ``truth`` (the
    true positions, evaluation only), ``hausdorff`` and ``<dim>.<stage>``."""
    from sensorispace_ros.core.topology import euclidean_distances

    spaces = {"truth": euclidean_distances(true_positions), "hausdorff": representation.distance}
    for dim in representation.before:
        for stage in STAGES:
            spaces[f"{dim}.{stage}"] = euclidean_distances(representation.embedding(dim, stage))
    return spaces


def _topology_numbers(representation: Representation, true_positions: np.ndarray) -> dict:
    """``topology.<space>.*`` of ``evaluate`` (``core.topology.topology_report``)."""
    from sensorispace_ros.core.topology import topology_report

    return {f"topology.{space}.{key}": value
            for space, distance in topology_spaces(representation, true_positions).items()
            for key, value in topology_report(distance).items()}


def missed_ring_positions(true_positions: np.ndarray, spacing: float,
                          ring: tuple = PAPER_ARM.working_ring) -> np.ndarray:
    """``(M, 2)`` sensor positions of the arm's working ring that no POV
    covers, on the lattice most POVs lie on (``core.sensor_grid``): the
    positions that should have been compensated but were not, for any
    strategy. Fig. 7a outlines them. ``spacing`` is the object grid's step
    (the world's): on a fine grid the compensations' pose errors make the
    positions' median neighbour distance a step that is off by enough to
    slide the lattice's far positions off their POVs."""
    from sensorispace_ros.core.sensor_grid import missed_in_ring

    positions = np.asarray(true_positions, dtype=float).reshape(-1, 2)
    if len(positions) < 2:
        return np.zeros((0, 2))
    return missed_in_ring(positions, spacing, ring)


def _reaching_numbers(representation: Representation, true_positions: np.ndarray, cfg: dict,
                      seed: int, progress=None) -> dict:
    """``reaching.<graph>.*`` of ``evaluate``: the Hausdorff metric and every embedding."""
    from scipy.spatial.distance import pdist, squareform

    from sensorispace_ros.core.reach import reaching_evaluation

    reaching = cfg["representation"]["reaching"]
    options = {"n_pairs": reaching["pairs"], "max_degree": reaching["max_degree"],
               "radius": reaching["radius"]}
    # One stream for every representation: all are tested on the same pairs.
    reaching_seed = random_state(seed, "reaching")
    graphs = {"hausdorff": representation.distance}
    for dim in representation.before:
        for stage in STAGES:
            graphs[f"{dim}.{stage}"] = squareform(pdist(representation.embedding(dim, stage)))
    metrics = {}
    for k, (name, distance) in enumerate(graphs.items()):
        result = reaching_evaluation(distance, true_positions, random_state=reaching_seed,
                                     **options)
        reached = [v for v in result["straightness"] if v is not None]
        degree = np.sum(distance < result["radius"], axis=1) - 1
        metrics.update({
            f"reaching.{name}.straightness_median": result["straightness_median"],
            f"reaching.{name}.straightness_p90": float(np.percentile(reached, 90))
            if reached else float("nan"),
            f"reaching.{name}.radius": result["radius"],
            f"reaching.{name}.degree_mean": float(np.mean(degree)),
            f"reaching.{name}.degree_max": int(np.max(degree)),
            f"reaching.{name}.graph_components": result["n_components"],
            f"reaching.{name}.unreachable": result["unreachable"],
        })
        if progress is not None:
            progress(k + 1, len(graphs))
    return metrics


def _grid_step(positions: np.ndarray) -> float:
    """Median nearest-neighbour distance: the grid step of the sensor positions."""
    from scipy.spatial import cKDTree

    if len(positions) < 2:
        return 1.0
    distance, _ = cKDTree(positions).query(positions, k=2)
    return float(np.median(distance[:, 1]))


def _true_neighbour_pairs(positions: np.ndarray, spacing: float) -> np.ndarray:
    """POV pairs one grid step apart outside (the paper's Fig. 9 transitions)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(positions).query_pairs(1.01 * spacing, output_type="ndarray")
    return np.asarray(pairs, dtype=int).reshape(-1, 2)


def _unit_step_cv(distance: np.ndarray, pairs: np.ndarray) -> float:
    """Coefficient of variation of the internal lengths of equal external grid
    steps: 0 for a metric as regular as the external one (paper Fig. 9)."""
    if len(pairs) == 0:
        return float("nan")
    lengths = distance[pairs[:, 0], pairs[:, 1]]
    return float(np.std(lengths) / np.mean(lengths))


def _neighbours_true_fraction(embedding: np.ndarray, positions: np.ndarray,
                              k: int = 4) -> float:
    """Fraction of POVs whose ``k`` nearest neighbours in the representation
    are also their ``k`` nearest outside (ties in the grid allowed)."""
    from scipy.spatial import cKDTree

    k = min(k, len(embedding) - 1)
    _, index = cKDTree(embedding).query(embedding, k=k + 1)
    true_kth, _ = cKDTree(positions).query(positions, k=k + 1)
    gap = np.linalg.norm(positions[index[:, 1:]] - positions[:, None, :], axis=-1)
    # Ties: compensated sensor positions sit up to the compensation threshold
    # off the exact lattice, whose distances (1, sqrt 2, 2 steps) are far
    # more than 5 % apart.
    return float(np.mean(np.all(gap <= true_kth[:, -1:] * 1.05, axis=1)))


def _spearman(a: np.ndarray, b: np.ndarray) -> float:
    from scipy.stats import spearmanr

    return float(spearmanr(a, b).statistic)
