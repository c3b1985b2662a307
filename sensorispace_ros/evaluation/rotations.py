"""Ground truth of a world whose object turns (``world.rotation_count`` > 0):
the compensable (position, orientation) poses, the pose each compensation
asks for, and the naive agent's coverage of the compensable poses.

A displacement of the object is a rigid motion of the plane (a translation of
its centre and a turn about it); it is compensated by the sensor pose that
keeps the pose relative to the object (``exploration.moved_pose``), the eye
turning with the object. Poses are compared as points of the plane times
the circle: ``pose_key`` maps ``(x, y, alpha)`` to ``(x, y, cos alpha, sin
alpha)``, so two poses are close when their positions are and their
orientations are (the chord of the angle, ~ the angle when small).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from pathlib import Path

from sensorispace_ros.core import arm
from sensorispace_ros.core import world as world_mod


FIGURE_NAME = "rotations_orientation.png"
CLASS_GAP = 0.05          # rad: angles of one orientation class lie closer than this
MIN_CLASS_POVS = 10       # an orientation class with fewer POVs gets no flat embedding
MAX_CLASS_POVS = 600      # a larger class is embedded from this many of its POVs
TIE_TOL = 1e-6            # true distances closer than this (relative) are tied


def turns(world) -> bool:
    """Whether the object of ``world`` turns (some event has an orientation)."""
    return any(event.orientation != 0.0 for event in world.events)


def pose_key(poses: np.ndarray) -> np.ndarray:
    """``(x, y, cos alpha, sin alpha)`` of poses ``(P, 3)``: a point of plane x circle."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    return np.column_stack([poses[:, :2], np.cos(poses[:, 2]), np.sin(poses[:, 2])])


def compensable_poses(world) -> tuple[np.ndarray, np.ndarray]:
    """From the body's geometry alone: every (grid position, orientation) the
    object is moved to (not its start) whose compensating pose (the start's pose moved with the
    object) the paper strategy keeps (``exploration.in_working_region``).
    Returns ``(pairs (Q, 2) of (grid index, orientation index), poses (Q, 3))``."""
    from sensorispace_ros.core.paper import exploration   # numba and scipy: on first use

    pose0 = world.arm.forward(world.m0)
    angles = world_mod.orientations(int(world.params.get("rotation_count", 0)))
    start = {(int(g), 0) for g in np.flatnonzero(np.all(world.grid == world.initial_center,
                                                         axis=1))}
    pairs, poses = [], []
    for g, center in enumerate(world.grid):
        for k, angle in enumerate(angles):
            if (g, k) in start:
                continue
            target = exploration.moved_pose(pose0, world.initial_center, center, float(angle))
            if exploration.in_working_region(world.arm, target):
                pairs.append((g, k))
                poses.append(target)
    return np.asarray(pairs, dtype=int).reshape(-1, 2), np.asarray(poses).reshape(-1, 3)


def compensation_targets(anchor_poses, centers_before, centers_after, turns_by) -> np.ndarray:
    """The pose each compensation asks for ``(C, 3)``: its anchor's pose moved
    with the object (centre before -> after, turned by ``turns_by``)."""
    from sensorispace_ros.core.paper import exploration

    return np.array([exploration.moved_pose(p, a, b, float(t)) for p, a, b, t in
                     zip(np.asarray(anchor_poses, float), np.asarray(centers_before, float),
                         np.asarray(centers_after, float), np.asarray(turns_by, float))]
                    ).reshape(-1, 3)


def pose_coverage(true_poses: np.ndarray, reference_poses: np.ndarray, tolerance: float) -> dict:
    """Distinct sensor poses among ``true_poses`` (two closer than ``tolerance``
    in ``pose_key`` are one) and the share of ``reference_poses`` within
    ``tolerance`` of one (``naive.*`` coverage numbers on plane x circle)."""
    keys = pose_key(true_poses)
    distinct, covered = 0, 0
    if len(keys):
        close = cKDTree(keys).query_pairs(tolerance, output_type="ndarray")
        duplicate = np.zeros(len(keys), dtype=bool)
        duplicate[close.max(axis=1) if len(close) else []] = True
        distinct = int(np.sum(~duplicate))
        if len(reference_poses):
            distance, _ = cKDTree(keys).query(pose_key(reference_poses), k=1)
            covered = int(np.sum(distance <= tolerance))
    n_ref = max(len(reference_poses), 1)
    return {"naive.coverage": distinct / n_ref, "naive.distinct_positions": distinct,
            "naive.duplicate_povs": int(len(keys) - distinct),
            "naive.paper_positions": int(len(reference_poses)),
            "naive.coverage_of_paper_positions": covered / n_ref}


def orientation_class_error(orientations: np.ndarray, alpha0: float, count: int) -> float:
    """Largest distance of an eye orientation to the nearest of the ``count``
    orientations the object can give it (``alpha0`` turned by k 2 pi / count)."""
    if not len(orientations):
        return 0.0
    step = 2.0 * np.pi / count
    offset = arm.wrap_angle(np.asarray(orientations, float) - alpha0)
    return float(np.max(np.abs(offset - step * np.round(offset / step))))


def rotation_numbers(distance: np.ndarray, embeddings: dict, true_poses: np.ndarray,
                     pairs: np.ndarray, set_ids: np.ndarray, space_dim: int,
                     strategy: str, cfg: dict | None = None,
                     seed: int = 0) -> tuple[dict, np.ndarray | None]:
    """``topology_h2.*`` (Betti numbers up to H2 of the truth on plane x circle,
    the agent's metric and every embedding ``embeddings[name]``) and, for the
    naive agent, its looped and flat dimensions (``core.naive.looped_dims``);
    ``rotation.*`` and the angle coordinate (``angle_numbers``; None without one);
    with the run's ``cfg``, the flat embedding of the translations
    (``translation_numbers``)."""
    from sensorispace_ros.core.naive.looped_dims import looped_dimensions
    from sensorispace_ros.core.topology import euclidean_distances
    from sensorispace_ros.core.looped_space import betti_up_to_h2

    numbers = {}
    spaces = {"truth": euclidean_distances(pose_key(true_poses)), "hausdorff": distance,
              **{name: euclidean_distances(emb) for name, emb in embeddings.items()}}
    for name, matrix in spaces.items():
        for key, value in betti_up_to_h2(matrix, rule="gap").items():
            numbers[f"topology_h2.{name}.{key}"] = value
    if strategy == "naive":
        numbers.update(looped_dimensions(pairs, set_ids, max(int(space_dim), 0)).metrics())
    angle_metrics, angle = angle_numbers(distance, true_poses, pairs, set_ids)
    if angle is not None and cfg is not None:
        angle_metrics.update(translation_numbers(distance, true_poses, angle, pairs, set_ids,
                                                 cfg, seed))
    return {**numbers, **angle_metrics}, angle


def orientation_classes(angle: np.ndarray, gap: float = CLASS_GAP) -> np.ndarray:
    """Class of each POV ``(P,)``: the angle coordinate's clusters on the
    circle, split wherever two neighbouring angles are more than ``gap`` apart."""
    angle = np.mod(np.asarray(angle, dtype=float).reshape(-1), 2 * np.pi)
    if not len(angle):
        return np.zeros(0, dtype=int)
    order = np.argsort(angle, kind="stable")
    sorted_angle = angle[order]
    steps = np.diff(np.append(sorted_angle, sorted_angle[0] + 2 * np.pi))
    cuts = np.flatnonzero(steps > gap)
    labels = np.zeros(len(angle), dtype=int)
    if len(cuts):
        # start after the last cut, so a class that straddles 0 stays one
        shifted = np.roll(np.arange(len(angle)), -(cuts[-1] + 1))
        boundaries = np.zeros(len(angle), dtype=int)
        boundaries[(cuts + 1) % len(angle)] = 1
        labels[order[shifted]] = np.cumsum(boundaries[shifted]) - boundaries[shifted[0]]
    return labels


def tied_trustworthiness(true_positions, embedding, n_neighbors: int = 5,
                         tie_tol: float = TIE_TOL) -> float:
    """Venna and Kaski's trustworthiness where the truth has ties: the rank of
    a point among another's true neighbours is one more than the number of
    points strictly closer (within ``tie_tol`` of the largest true distance).
    On a lattice four neighbours are equally close, and which of them an
    embedding lists fifth is no error; scikit-learn's ranks break such ties
    by index order, so an exact copy of a lattice, moved by 1e-4 of a step,
    already loses 0.005 there. Without ties this is the usual measure."""
    T = np.asarray(true_positions, dtype=float)
    Y = np.asarray(embedding, dtype=float)
    n, k = len(T), int(n_neighbors)
    if Y.shape[0] != n or not 1 <= k < n / 2:
        raise ValueError(f"need as many embedded as true points and 1 <= n_neighbors < "
                         f"{n / 2}, got {Y.shape[0]} and {n}, n_neighbors={n_neighbors!r}")
    dt = np.linalg.norm(T[:, None] - T[None], axis=-1)
    dy = np.linalg.norm(Y[:, None] - Y[None], axis=-1)
    np.fill_diagonal(dy, np.inf)
    tol = tie_tol * float(dt.max())
    penalty = 0.0
    for i in range(n):
        for j in np.argsort(dy[i], kind="stable")[:k]:
            rank = int(np.sum(dt[i] < dt[i, j] - tol))     # itself included: 1-based
            penalty += max(rank - k, 0)
    return float(1.0 - 2.0 / (n * k * (2 * n - 3 * k - 1)) * penalty)


def translation_numbers(distance: np.ndarray, true_poses: np.ndarray, angle: np.ndarray,
                        pairs: np.ndarray, set_ids: np.ndarray, cfg: dict, seed: int) -> dict:
    """``rotation.translation.*``: the flat embedding of the translations,
    one orientation at a time. The POVs of one class of the angle
    coordinate (``orientation_classes``) are embedded in 2-D from their own
    Hausdorff distances and regularised with the equality pairs inside the
    class (CCA and iterations as the representation's) and synchronised
    with them read as vectors (``looped_space.synchronized_translations``:
    within one orientation every set is a translation), then compared with
    their true positions: the largest 2-D after affine residual and the
    smallest trustworthiness (``tied_trustworthiness``: the positions are a
    lattice) over the classes of at least
    ``MIN_CLASS_POVS`` POVs (at most ``MAX_CLASS_POVS`` of them, evenly
    chosen, embedded). A POV no pair inside its class places is placed
    through the sets that join it to other classes (``place_by_turns``);
    ``paired_affine_residual_max`` is the residual over the POVs the pairs
    inside their class place, ``unpaired_povs`` the others, ``unplaced_povs``
    those the turns did not place either (they keep the metric's place)."""
    from sensorispace_ros.core import quality
    from sensorispace_ros.core.seeding import rng_for

    classes = orientation_classes(angle)
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    set_ids = np.asarray(set_ids).reshape(-1)
    positions = np.asarray(true_poses, dtype=float)[:, :2]
    flat, paired, embedded = _class_embeddings(distance, classes, pairs, set_ids, cfg,
                                               rng_for(seed, "rotation.translation"))
    placed_flat, placed = place_by_turns(flat, paired, classes, pairs, set_ids)
    residuals, trust, sizes, paired_residuals = [], [], [], []
    for members in embedded:
        embedding = placed_flat[members]
        residuals.append(quality.affine_residual(embedding, positions[members]))
        inside = paired[members]
        if inside.sum() > 3:
            paired_residuals.append(quality.affine_residual(embedding[inside],
                                                            positions[members][inside]))
        trust.append(tied_trustworthiness(positions[members], embedding,
                                          n_neighbors=min(5, len(members) // 2 - 1)))
        sizes.append(len(members))
    unpaired = sum(int(np.sum(~paired[m])) for m in embedded)
    unplaced = sum(int(np.sum(~placed[m])) for m in embedded)
    if not sizes:
        return {"rotation.translation.classes": 0}
    return {"rotation.translation.classes": len(sizes),
            "rotation.translation.class_povs_min": int(min(sizes)),
            "rotation.translation.affine_residual_max": float(max(residuals)),
            "rotation.translation.affine_residual_median": float(np.median(residuals)),
            "rotation.translation.trustworthiness_min": float(min(trust)),
            # The POVs an equality pair inside their class places (the others: the metric).
            "rotation.translation.paired_affine_residual_max":
                float(max(paired_residuals)) if paired_residuals else float("nan"),
            "rotation.translation.unpaired_povs": unpaired,
            "rotation.translation.unplaced_povs": unplaced}


def place_by_turns(flat, placed, classes, pairs, set_ids):
    """Flat coordinates ``(P, 2)`` (one frame per orientation class) of the
    POVs not ``placed`` by the pairs inside their class, from the sets that
    join them to placed POVs of other classes, repeated while it places more.

    A set is one rigid motion: between two classes it maps one's poses to
    the other's by one turn and its own shift, so in the classes' frames by
    one linear map (the same for every set between those two classes: the
    same turn seen in the same two frames) and the set's own offset. The
    linear map is fitted on the placed pairs of every set with two or more
    of them between the two classes (centred by set), the offset on the
    set's own placed pairs; an unplaced POV takes the median of what its
    pairs say. Returns the coordinates and which POVs are placed."""
    out, done = np.array(flat, dtype=float, copy=True), np.array(placed, dtype=bool, copy=True)
    while True:
        fresh = {}
        for u in np.flatnonzero(~done & np.all(np.isfinite(out), axis=1)):
            guesses = [g for row in np.flatnonzero(np.any(pairs == u, axis=1))
                       if (g := _turn_guess(u, row, out, done, classes, pairs, set_ids))
                       is not None]
            if guesses:
                fresh[u] = np.median(np.array(guesses), axis=0)
        if not fresh:
            return out, done
        for u, y in fresh.items():
            out[u], done[u] = y, True


def _turn_guess(u, row, flat, placed, classes, pairs, set_ids):
    """Where pair ``row`` (``u`` at one end, a placed POV of another class at
    the other) puts ``u`` (``place_by_turns``); None if it cannot tell."""
    side = int(pairs[row, 1] == u)
    j = pairs[row, 1 - side]
    if not placed[j] or classes[j] == classes[u]:
        return None
    between = (classes[pairs[:, side]] == classes[u]) & \
        (classes[pairs[:, 1 - side]] == classes[j]) & placed[pairs[:, 0]] & placed[pairs[:, 1]]
    source, target = flat[pairs[between, 1 - side]], flat[pairs[between, side]]
    ids, index, counts = np.unique(set_ids[between], return_inverse=True, return_counts=True)
    index = index.reshape(-1)
    if not np.any(ids == set_ids[row]):
        return None
    centre_s = np.column_stack([np.bincount(index, source[:, k]) / counts for k in range(2)])
    centre_t = np.column_stack([np.bincount(index, target[:, k]) / counts for k in range(2)])
    several = counts[index] >= 2
    spread = source[several] - centre_s[index[several]]
    if several.sum() < 3 or np.linalg.matrix_rank(spread, tol=1e-9) < 2:
        return None
    linear, *_ = np.linalg.lstsq(spread, target[several] - centre_t[index[several]], rcond=None)
    own = int(np.flatnonzero(ids == set_ids[row])[0])
    return centre_t[own] + (flat[j] - centre_s[own]) @ linear


def _class_embeddings(distance, classes, pairs, set_ids, cfg: dict, rng):
    """Every orientation class of at least ``MIN_CLASS_POVS`` POVs (at most
    ``MAX_CLASS_POVS`` of them) embedded on its own (``_class_embedding``).
    Returns the coordinates ``(P, 2)`` (NaN: not embedded), which POVs the
    pairs inside their class place, and the embedded members of each class."""
    flat = np.full((len(classes), 2), np.nan)
    paired = np.zeros(len(classes), dtype=bool)
    embedded = []
    for label in np.unique(classes):
        members = np.flatnonzero(classes == label)
        if len(members) < MIN_CLASS_POVS:
            continue
        if len(members) > MAX_CLASS_POVS:      # evenly by discovery order: a bounded cost
            members = members[np.linspace(0, len(members) - 1, MAX_CLASS_POVS).astype(int)]
        flat[members], paired[members] = _class_embedding(distance, members, pairs, set_ids,
                                                          cfg, rng)
        embedded.append(members)
    return flat, paired, embedded


def _class_embedding(distance, members, pairs, set_ids, cfg: dict, rng):
    """The 2-D embedding of the POVs ``members`` of one orientation class
    (``translation_numbers``) and which of them the pairs inside the class
    place (``_main_component``)."""
    from sensorispace_ros.core.looped_space import synchronized_translations
    from sensorispace_ros.core.regularize import iterate_regularization
    from sensorispace_ros.offline.representation import cca_params

    place = np.full(int(max(members.max() + 1, pairs.max() + 1 if len(pairs) else 0)), -1)
    place[members] = np.arange(len(members))
    inside = np.all(place[pairs] >= 0, axis=1) if len(pairs) else np.zeros(0, bool)
    sub_pairs, sub_ids = place[pairs[inside]], set_ids[inside]
    result = iterate_regularization(
        np.asarray(distance)[np.ix_(members, members)], sub_pairs, sub_ids, n_components=2,
        n_iterations=cfg["representation"]["regularization"]["iterations"],
        cca_params=cca_params(cfg), random_state=rng)
    return synchronized_translations(result.embeddings[-1], sub_pairs, sub_ids), \
        _main_component(len(members), sub_pairs, sub_ids)


def _main_component(n: int, pairs, set_ids) -> np.ndarray:
    """Which of ``n`` POVs lie in the largest connected part of the graph of
    ``pairs`` (of sets of two pairs or more: a lone pair places nothing).
    The sets fix the shape of each part, never where one part lies against
    another: only the largest part is placed by them."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    _, sets, size = np.unique(set_ids, return_inverse=True, return_counts=True)
    used = pairs[size[sets.reshape(-1)] >= 2] if len(pairs) else pairs
    if not len(used):
        return np.zeros(n, dtype=bool)
    graph = coo_matrix((np.ones(len(used)), (used[:, 0], used[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    touched = np.zeros(n, dtype=bool)
    touched[used.ravel()] = True
    main = np.bincount(label[touched]).argmax()
    return touched & (label == main)


def angle_numbers(distance: np.ndarray, true_poses: np.ndarray, pairs: np.ndarray,
                  set_ids: np.ndarray) -> tuple[dict, np.ndarray | None]:
    """``rotation.*``: the angle coordinate of the looped dimension read from
    the agent's metric and equality sets (``core.looped_space``: the
    combination of the metric's two longest loops the sets single out, then
    synchronised with the sets) against the true orientation (circular
    correlation; ``metric_angle_circular_correlation`` before the
    synchronisation), its coefficients over the loops; and the coordinate."""
    from sensorispace_ros.core.looped_space import (circular_coordinates,
                                                    circular_correlation, looped_coordinate,
                                                    synchronized_angle)
    try:
        angles, _ = circular_coordinates(distance, n_loops=2)
        found = looped_coordinate(angles, pairs, set_ids)
    except ValueError as error:          # fewer than two loops, or no equality sets
        return {"rotation.angle_error": str(error)}, None
    if found is None:
        return {"rotation.angle_error": "no combination of the loops goes round the circle"}, None
    metric_theta, coefficients, variance = found
    theta = synchronized_angle(metric_theta, pairs, set_ids)
    orientation = np.asarray(true_poses)[:, 2]
    return {"rotation.angle_circular_correlation": circular_correlation(theta, orientation),
            "rotation.metric_angle_circular_correlation":
                circular_correlation(metric_theta, orientation),
            "rotation.angle_coefficients": [int(c) for c in coefficients],
            "rotation.angle_set_variance": variance}, theta



def draw_orientation_figure(arrays: dict, angle: np.ndarray | None, path: str | Path) -> Path:
    """The figure of a turning world's representation: the agent's 3-D
    embedding coloured by the true orientation of each POV (a hue wheel: a
    loop respected shows the hues in order round it), and the angle
    coordinate of the looped dimension against the true orientation; from a
    run's ``arrays`` (``true_poses``, ``embedding_3d_before``) and the angle
    (None: not drawn)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
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
