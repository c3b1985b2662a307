"""Points of view from the sensorimotor flow alone (naive strategy).

The paper samples a point of view (POV) by walking the kernel of the arm's
Jacobian J_f (Sec. 4.1). A naive agent has no f. It has a body that answers
motor states with sensations in a static environment, and a POV is, for an
environment without symmetries, the level set ``{m : sense(m) = sense(m_i)}``
(paper Eq. equivalenceClass). Its tangent space is the null space of the
*sensory* Jacobian ``J_s = dsense/dm``, which the agent estimates by finite
differences through ``sense``; its dimension is the number of joints minus
the pose rank the agent measured of itself (``structure``):

* 0: the POV is isolated motor states, the start (the agent adds the other
  solutions a search finds for the same sensation);
* 1: a closed curve, walked by two fronts that meet (``loop_walk``);
* 2: a closed surface, covered by a growing front (``surface``).

Nothing here knows the arm, the retina or the world: ``body`` only needs
``sense``, ``n_motors`` and ``n_sensors``. Motor states are phases (a
joint's period is 2 pi).
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.jacobians import (NOT_CLOSED, RANK_DEFICIENT, SPLIT,  # noqa: F401
    UNSUPPORTED, VALID, SensoryPointsOfView, has_full_pose_rank, jacobian_stencil, jacobian_svd,
    minimum_norm_correction, sensory_jacobian)
from sensorispace_ros.core.naive.loop_walk import LoopWalk, resample_loop_spline  # noqa: F401
from sensorispace_ros.core.naive.secant_walk import SecantLoopWalk


PERIOD = 2.0 * np.pi     # a joint's period in phases
KNOTS_PER_STEP = 4       # a 1-D walk's probes per front and call (the farthest with its stencil)


def torus_phases(motor_states: np.ndarray) -> np.ndarray:
    """``motor_states`` as phases in ``[0, 2 pi)``: ``np.mod`` rounds a phase
    just below 0 up to exactly 2 pi, which is 0."""
    at = np.mod(motor_states, PERIOD)
    return np.where(at < PERIOD, at, 0.0)


def torus_tree(motor_states: np.ndarray):
    """A ``cKDTree`` of ``(K, M)`` motor states on the torus of phases (it
    refuses a coordinate equal to its box: ``torus_phases``)."""
    from scipy.spatial import cKDTree
    return cKDTree(torus_phases(motor_states), boxsize=PERIOD)


class PovStore:
    """Growing ``(P, N, M)`` array of POV samples (amortised appends);
    ``append`` returns the new POV's index. Pickled without ``near``'s tree,
    which is rebuilt, over the same POVs, when next queried."""

    def __init__(self, n_samples: int, n_motors: int):
        self._data = np.zeros((16, n_samples, n_motors))
        self.count = 0
        self._separation = (0, 0.0)      # (POVs then, separation())
        self._near_built = 0             # POVs in near()'s tree
        self._near_tree = None           # that tree, once built

    def __getstate__(self) -> dict:
        return {**vars(self), "_data": self._data[:self.count], "_near_tree": None}

    def mark(self) -> tuple:
        """What ``truncate`` needs to bring the store back to now."""
        return self.count, self._separation, self._near_built

    def truncate(self, mark: tuple) -> None:
        """Back to ``mark`` (``mark()``): the POVs appended since dropped."""
        count, self._separation, built = mark
        if built != self._near_built:
            self._near_built, self._near_tree = built, None
        self.count = count

    def append(self, samples: np.ndarray) -> int:
        if self.count == len(self._data):
            grown = np.zeros((max(16, 2 * len(self._data)),) + self._data.shape[1:])
            grown[:self.count] = self._data[:self.count]
            self._data = grown
        self._data[self.count] = samples
        self.count += 1
        return self.count - 1

    def replace(self, index: int, samples: np.ndarray) -> None:
        """POV ``index``'s samples moved to ``samples``; ``near``'s tree is
        rebuilt when next queried."""
        self._data[index] = samples
        self._near_built, self._near_tree = 0, None

    @property
    def samples(self) -> np.ndarray:
        return self._data[:self.count]

    def separation(self) -> float:
        """How far apart distinct POVs lie in motor space (phases): the
        median over POVs of the distance from a POV's first sample to the
        nearest sample of another POV, on the torus of phases (0 with fewer
        than two POVs). Recomputed when the POVs have grown by an eighth
        since the last time."""
        count = self.count
        cached = self._separation
        if count < 2 or count < cached[0] * 9 / 8:
            return cached[1] if count >= 2 else 0.0
        samples = torus_phases(self._data[:count])
        owner = np.repeat(np.arange(count), samples.shape[1])
        tree = torus_tree(samples.reshape(-1, samples.shape[2]))
        k = min(samples.shape[1] + 1, count * samples.shape[1])
        distance, index = tree.query(samples[:, 0], k=k)
        other = owner[index] != np.arange(count)[:, None]
        nearest = np.where(other.any(axis=1), np.where(other, distance, np.inf).min(axis=1),
                           np.inf)
        value = float(np.median(nearest[np.isfinite(nearest)])) if np.isfinite(nearest).any() \
            else 0.0
        self._separation = (count, value)
        return value

    def near(self, point: np.ndarray, radius: float) -> np.ndarray:
        """Indices of the POVs with a sample within ``radius`` of ``point``
        (torus of phases). A tree over the samples is rebuilt when the POVs
        have grown by an eighth; the POVs appended since are measured one by
        one."""
        from sensorispace_ros.core.naive.neighbours import curve_distances
        tree, built = self._tree()
        if tree is None:
            return np.zeros(0, dtype=int)
        hits = tree.query_ball_point(torus_phases(point), radius)
        indexed = np.unique(np.asarray(hits, dtype=int) // self._data.shape[1])
        later = built + np.flatnonzero(curve_distances(point, self._data[built:self.count])
                                       <= radius)
        return np.concatenate([indexed, later]).astype(int)

    def nearest(self, point: np.ndarray, allowed: np.ndarray, k: int) -> np.ndarray:
        """The ``k`` POVs with ``allowed`` (``(P,)`` bools) nearest ``point``
        by their nearest sample (torus of phases), nearest first (fewer when
        fewer are allowed): ``near``'s tree, then the POVs appended since."""
        from sensorispace_ros.core.naive.neighbours import curve_distances
        tree, built = self._tree()
        later = built + np.flatnonzero(allowed[built:self.count])
        ids, reach = [later], [curve_distances(point, self._data[later])]
        if tree is not None:
            seen, distance = self._tree_nearest(tree, built, point, allowed[:built], k)
            ids.append(seen)
            reach.append(distance)
        ids, reach = np.concatenate(ids), np.concatenate(reach)
        return ids[np.argsort(reach, kind="stable")[:k]]

    def _tree_nearest(self, tree, built, point, allowed, k):
        """The allowed POVs of ``tree`` met among ``point``'s nearest samples
        and their distances (each its nearest sample's), at least ``k`` of
        them (or every allowed one): a POV not met lies farther than all."""
        n_samples = self._data.shape[1]
        total = built * n_samples
        asked = min(total, 4 * n_samples)
        at = torus_phases(np.asarray(point, dtype=float))
        while True:
            distance, index = tree.query(at, k=asked)
            owner, first = np.unique(np.atleast_1d(index) // n_samples, return_index=True)
            met = allowed[owner]
            if met.sum() >= k or asked == total:
                return owner[met], np.atleast_1d(distance)[first][met]
            asked = min(total, 2 * asked)

    def _tree(self):
        """``(tree, built)``: a tree over the samples of the first ``built``
        POVs, rebuilt when the POVs have grown by an eighth (None before any)."""
        if self.count >= self._near_built * 9 / 8 + 1:
            self._near_built, self._near_tree = self.count, None
        built = self._near_built
        if self._near_tree is None and built:
            self._near_tree = torus_tree(self._data[:built].reshape(-1, self._data.shape[2]))
        return self._near_tree, built


def sample_sensory_points_of_view(
        body, motor_states: np.ndarray, *, rank: int, n_samples: int = 100,
        fd_step: float = 1e-6, initial_step: float = 0.05, min_step: float = 1e-3,
        max_step: float = 0.15, predictor_tol: float = 2e-3, rank_ratio: float = 1e-3,
        max_queries: int = 5000, polish_iterations: int = 2, min_loop_length: float = 0.3,
        knots_per_step: int = KNOTS_PER_STEP, closure_tol: float = 0.1, sample_tol: float = 1e-6,
        surface_step: float = 0.15,
        surface_max_queries: int = 400_000, min_singular: float = 0.0,
        pattern_ratio: float = 1e-6, noise_sd: float = 0.0) -> SensoryPointsOfView:
    """Sample the POV of every motor state in ``motor_states`` ``(P, M)``
    through ``body.sense`` in the current (static) environment; ``rank`` is
    the body's pose rank, so the POVs have dimension ``M - rank``.

    1-D (``loop_walk.LoopWalk``): each call has ``2 * (M + knots_per_step)``
    rows per walking POV (two fronts; per front ``knots_per_step`` probes,
    the farthest with its ``M``-row stencil). ``initial_step``/``min_step``/
    ``max_step`` bound the knot interval ``h``, so a call reaches up to
    ``knots_per_step * max_step``; ``h`` grows or shrinks so the farthest
    probe's Gauss-Newton correction stays near ``predictor_tol``. A front
    keeps its probes up to the first whose correction exceeds ``4 *
    predictor_tol``; if that is the first, it retries at half ``h``. The
    loop closes when the two fronts, after ``min_loop_length`` of arc
    together, face each other within about one knot interval in the torus;
    it is kept if it also closes in the unwrapped motor space (``closure_tol``,
    relative to its length), else it is ``SPLIT``, and if every sample comes
    back onto the level set within ``sample_tol``. ``max_queries``: rows per
    POV. 2-D (``surface``): a front of knots ``surface_step`` apart grows
    over the surface until it has covered it (``surface_max_queries`` rows
    at most). 0-D: the start itself.
    ``rank_ratio``: smallest accepted ratio of the ``rank``-th to the first
    singular value of the sensory Jacobian at the start, ``min_singular``
    the smallest such value (sensation units), ``pattern_ratio`` the ratio
    for the gain-free Jacobian: below them the sensation does not pin the
    sensor's configuration (``jacobians.has_full_pose_rank``). ``noise_sd``:
    the noise a 1-D walk leaves alone (``jacobians.loop_smoothed_correction``).
    """
    start = _checked_starts(body, motor_states, rank)
    n_motors = start.shape[1]
    _check_walk_parameters(**{name: value for name, value in locals().items()
                              if name in _WALK_PARAMETERS})
    dim = n_motors - int(rank)
    if len(start) == 0 or rank == 0 or dim > 2:
        return _none_walked(body, start, n_samples, UNSUPPORTED)
    if dim == 0:
        return _isolated(body, start, rank=rank, n_samples=n_samples, fd_step=fd_step,
                         rank_ratio=rank_ratio, min_singular=min_singular,
                         pattern_ratio=pattern_ratio)
    if dim == 2:
        from sensorispace_ros.core.naive.surface import cover_surfaces
        return cover_surfaces(
            body, start, rank=rank, n_samples=n_samples, fd_step=fd_step, step=surface_step,
            predictor_tol=predictor_tol, rank_ratio=rank_ratio, min_singular=min_singular,
            pattern_ratio=pattern_ratio, max_queries=surface_max_queries,
            polish_iterations=polish_iterations, sample_tol=sample_tol)
    return _walk_loops(body, start, rank=rank, n_samples=n_samples, fd_step=fd_step,
                       initial_step=initial_step, min_step=min_step, max_step=max_step,
                       predictor_tol=predictor_tol, max_queries=max_queries,
                       min_loop_length=min_loop_length, knots_per_step=knots_per_step,
                       closure_tol=closure_tol, checks=(rank_ratio, min_singular, pattern_ratio),
                       polish=(polish_iterations, sample_tol), noise_sd=noise_sd)


def brief_loop_walks(body, start, *, rank: int, n_samples: int, fd_step, initial_step: float,
                     min_step: float, max_step: float, predictor_tol: float, max_queries: int,
                     closure_tol: float, checks: tuple, polish_iterations: int = 1,
                     knots_per_step: int = KNOTS_PER_STEP, min_loop_length: float = 0.3,
                     checked_samples: int = 0, noise_sd: float = 0.0, secant_calls: int = 1):
    """1-D POVs of ``start`` ``(P, M)`` walked with fewer rows, for an agent
    whose world may change under a walk (``ClockedAgent``; docs/clock.md):
    the knots as the walk corrected them (``resample(polish_knots=False)``:
    that pass only evens the samples' spacing along the loop), and the
    samples given ``polish_iterations`` steps with their nearest knot's
    Jacobian and no repair (``project`` with no ``sample_tol``). Those knots
    were corrected once and never sensed again: a POV with a sample the
    steps moved farther than ``predictor_tol`` (what the walk aims a raw
    prediction's correction at) is ``NOT_CLOSED`` (``project``'s
    ``step_tol``), as its loop was not on the level set there. The caller
    may set ``predictor_tol`` larger than the full walk's: fewer knots.
    ``checks``: the start's rank test ``(rank_ratio, min_singular,
    pattern_ratio)``; ``checked_samples`` > 0: only that many samples are
    sensed and stepped (``project``'s ``checked``); ``noise_sd``: the noise its
    corrections leave alone, as the full walk's; ``secant_calls`` > 1: a front
    senses its stencil every that many calls (``secant_walk.SecantLoopWalk``).
    Returns a ``SensoryPointsOfView``."""
    return _walk_loops(body, np.array(start, dtype=float, copy=True), rank=rank,
                       n_samples=n_samples, initial_step=initial_step, checks=checks,
                       polish=(polish_iterations, np.inf, predictor_tol, checked_samples),
                       polish_knots=False,
                       fd_step=fd_step, min_step=min_step, max_step=max_step,
                       predictor_tol=predictor_tol, max_queries=max_queries,
                       min_loop_length=min_loop_length, knots_per_step=knots_per_step,
                       closure_tol=closure_tol, noise_sd=noise_sd, secant_calls=secant_calls)


def _walk_loops(body, start, *, rank, n_samples, initial_step, checks, polish,
                polish_knots=True, secant_calls: int = 1, **walk_parameters) -> SensoryPointsOfView:
    """1-D POVs: ``LoopWalk`` from every start, resampled and polished.
    ``checks``: the start's rank test ``(rank_ratio, min_singular,
    pattern_ratio)``; ``polish``: ``(iterations, sample_tol[, step_tol[, checked]])``;
    ``polish_knots``: see ``LoopWalk.resample``."""
    walk = (SecantLoopWalk(body, start, rank=rank, refresh_calls=secant_calls, **walk_parameters)
            if secant_calls > 1 else LoopWalk(body, start, rank=rank, **walk_parameters))
    walk.begin(*checks, initial_step)
    while len(walk.active):
        walk.advance()
    samples = walk.resample(n_samples, polish_knots=polish_knots)
    max_residual = walk.project(samples, *polish)
    reason = walk.reason
    return SensoryPointsOfView(samples=samples, valid=np.array([r == VALID for r in reason]),
                               reason=reason, queries=walk.queries, steps=walk.steps,
                               calls=walk.calls, max_residual=max_residual,
                               target_sensations=walk.target)


def _checked_starts(body, motor_states, rank) -> np.ndarray:
    """``motor_states`` as a ``(P, M)`` float copy, after checking it and ``rank``."""
    start = np.array(motor_states, dtype=float, copy=True)
    n_motors = int(body.n_motors)
    if start.ndim != 2 or start.shape[1] != n_motors:
        raise ValueError(f"motor_states must have shape (P, {n_motors}), got {start.shape}")
    if not np.all(np.isfinite(start)):
        raise ValueError("motor_states contains non-finite values")
    if int(rank) != rank or not 0 <= rank <= n_motors:
        raise ValueError(f"rank must be an integer in [0, {n_motors}], got {rank}")
    return start


def _none_walked(body, start, n_samples, reason) -> SensoryPointsOfView:
    """Every start rejected with ``reason``, nothing sensed."""
    none = np.zeros(len(start), dtype=int)
    return SensoryPointsOfView(np.repeat(start[:, None, :], n_samples, axis=1),
                               np.zeros(len(start), bool), [reason] * len(start), none,
                               none.copy(), 0, 0.0, np.zeros((len(start), int(body.n_sensors))))


def _isolated(body, start, *, rank, n_samples, fd_step, rank_ratio, min_singular,
              pattern_ratio) -> SensoryPointsOfView:
    """0-D POVs: the starts whose sensation pins their configuration (one
    call, usually answered from memory: a search's solution was sensed with
    its stencil), each repeated ``n_samples`` times."""
    target, jac, _ = sensory_jacobian(body, start, fd_step)
    full = has_full_pose_rank(jac, rank, rank_ratio, min_singular, target, pattern_ratio)
    queries = np.full(len(start), start.shape[1] + 1)
    return SensoryPointsOfView(np.repeat(start[:, None, :], n_samples, axis=1), full,
                               [VALID if f else RANK_DEFICIENT for f in full], queries,
                               np.zeros(len(start), dtype=int), 1, 0.0, target)


def isolated_samples(solutions: np.ndarray, n_samples: int) -> np.ndarray:
    """A 0-D POV's ``(n_samples, M)`` samples from its distinct solutions
    ``(K, M)`` (the first is its start): repeated in turn."""
    solutions = np.asarray(solutions, dtype=float)
    return solutions[np.arange(n_samples) % len(solutions)]


_WALK_PARAMETERS = ("n_samples", "fd_step", "initial_step", "min_step", "max_step",
                    "predictor_tol", "rank_ratio", "max_queries", "polish_iterations",
                    "min_loop_length", "knots_per_step", "closure_tol", "sample_tol",
                    "surface_step", "surface_max_queries")


def _check_walk_parameters(**values) -> None:
    positive = ("fd_step", "initial_step", "min_step", "max_step", "predictor_tol",
                "rank_ratio", "min_loop_length", "closure_tol", "surface_step")
    for name in positive:
        if not np.isfinite(values[name]) or values[name] <= 0:
            raise ValueError(f"{name} must be a finite number > 0, got {values[name]}")
    if not values["sample_tol"] > 0:        # inf: no sample is repaired
        raise ValueError(f"sample_tol must be > 0, got {values['sample_tol']}")
    if not values["min_step"] <= values["initial_step"] <= values["max_step"]:
        raise ValueError("initial_step must lie in [min_step, max_step], got "
                         f"{values['initial_step']} not in [{values['min_step']}, "
                         f"{values['max_step']}]")
    for name, minimum in (("n_samples", 2), ("max_queries", 1), ("polish_iterations", 0),
                          ("knots_per_step", 1), ("surface_max_queries", 1)):
        value = values[name]
        if int(value) != value or value < minimum:
            raise ValueError(f"{name} must be an integer >= {minimum}, got {value}")
