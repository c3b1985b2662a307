"""1-D points of view: the predictor-corrector walk of a sensory level set.

Where the sensory Jacobian ``J_s`` has rank ``M - 1`` (the POV dimension
the agent measured is 1), a point of view is a closed curve in the motor
torus and its tangent is the null vector of ``J_s``. The walk predicts
states along the null vector (a quadratic arc, its bend from the last two
tangents), then takes one minimum-norm Gauss-Newton step each back onto
``sense(m) = s_i`` using the Jacobian measured at the predicted state. The
``sense`` calls are the sequential cost (a round trip each over ROS), rows
are cheap, so one call carries, for every walking POV at once: two fronts
leaving the start in opposite directions and meeting half way round, each
probing ``knots_per_step`` states ``h, 2h, ...`` ahead: the farthest, with
its finite-difference stencil, sets the reach; the nearer ones (one row
each, Jacobian interpolated) keep the knots ``h`` apart. ``h`` adapts to the
size of the farthest correction. The knots get one more Gauss-Newton step
together (one call), the closed loop is resampled at ``N`` points equally
spaced in arc length along a periodic cubic spline (a polyline's arc length
at such steps is off by ~h^2 kappa^2 / 24 relative), and the samples are
projected back onto the level set.

Steps and tolerances are in phases (a joint's period is 2 pi). The fronts
meet in the torus; a loop is kept only if its path also closes in the
unwrapped motor space (``motor_loops.closure_gap_ratio`` at most
``closure_tol``): a loop that comes back a period away may be one of several
pieces of its POV.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from sensorispace_ros.core.motor_loops import closure_gap_ratio, loop_winding, wrap_phase
from sensorispace_ros.core.naive.jacobians import (NOT_CLOSED, RANK_DEFICIENT, REPEAT_JITTER,
    SPLIT, VALID, has_full_pose_rank, jacobian_stencil, jacobian_svd, loop_smoothed_correction,
    minimum_norm_correction, repair_rows, sensory_jacobian, shrink, stencil_jacobian,
    stencil_rows)

TWO_PI = 2.0 * np.pi

# Gauss-Legendre nodes on [0, 1] for the spline's arc length; a cubic's
# speed is smooth between knots, 5 nodes integrate it to ~1e-12.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(5)
_GL_NODES = 0.5 * (_GL_NODES + 1.0)
_GL_WEIGHTS = 0.5 * _GL_WEIGHTS


def _correction_and_null(jacobians: np.ndarray, residuals: np.ndarray, rank: int,
                         noise: np.ndarray | None = None):
    """``minimum_norm_correction`` and the unit null vector of each Jacobian
    of rank ``rank = M - 1`` from one SVD (the walk's inner loop). ``noise``
    ``(B,)``: the sd of each residual's component along any direction; the
    components are then shrunk toward 0 where they are noise (``jacobians.shrink``)."""
    u, singular, right = np.linalg.svd(jacobians, full_matrices=False)
    along = np.einsum("bsk,bs->bk", u[:, :, :rank], residuals)
    if noise is not None:
        along = along * shrink(along, noise)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        coeff = along / singular[:, :rank]
    return -np.einsum("bk,bkm->bm", coeff, right[:, :rank, :]), right[:, rank, :].copy()


class LoopWalk:
    """One batch of 1-D POV walks (``points_of_view.sample_sensory_points_of_view``).

    Per POV: its path (start, then the knots of both fronts once the loop
    closed), the sensory Jacobians along it, its rows probed and its
    outcome. Per walking POV (``active``), arrays ``(A, 2, ...)`` describe
    its two fronts, front 0 along +tangent and front 1 along -tangent:
    ``point`` the last accepted (corrected) knot and ``point_jac`` its
    sensory Jacobian, ``direction`` the unit tangent there, ``bend``
    d(tangent)/d(arc) from the last two knots, ``spacing`` the knot interval
    ``h`` and ``arc`` the arc length walked.
    """

    def __init__(self, body, start, *, rank, fd_step, min_step, max_step, predictor_tol,
                 max_queries, min_loop_length, knots_per_step, closure_tol, noise_sd=0.0):
        self.body, self.start, self.rank = body, start, int(rank)
        # The measured sensory noise (0: none; corrections are then exact
        # Gauss-Newton steps): how far one sensing's residual may be noise.
        self.noise_sd = float(noise_sd)
        self.repeats = getattr(fd_step, "repeats", 1)
        self.closure_tol = closure_tol
        self.fd_step, self.min_step, self.max_step = fd_step, min_step, max_step
        self.predictor_tol, self.max_queries = predictor_tol, max_queries
        self.min_loop_length = min_loop_length
        n_pov = len(start)
        self.n_motors = start.shape[1]
        self.rows_per_state = stencil_rows(self.n_motors, fd_step)
        self.n_knots = int(knots_per_step)
        self.fraction = np.arange(1, self.n_knots + 1)             # probe k at k * spacing
        self.rows_per_call = 2 * (self.rows_per_state + self.n_knots - 1)  # per walking POV
        self.queries = np.zeros(n_pov, dtype=int)
        self.steps = np.zeros(n_pov, dtype=int)
        self.reason = [VALID] * n_pov
        self.paths: list[list[np.ndarray]] = [[start[p].copy()] for p in range(n_pov)]
        self.jacobians_along: list[list[np.ndarray]] = [[] for _ in range(n_pov)]
        self.branches = [([], []) for _ in range(n_pov)]             # knots of each front
        self.branch_jacobians = [([], []) for _ in range(n_pov)]
        self.calls = 0

    def begin(self, rank_ratio: float, min_singular: float, pattern_ratio: float,
              initial_step: float) -> None:
        """Sense the starts with their Jacobians; the POVs whose start has
        full pose rank set off, two fronts each along the null vector."""
        start, n_pov = self.start, len(self.start)
        self.target, jac, _ = sensory_jacobian(self.body, start, self.fd_step)
        self.calls += 1
        self.queries += self.rows_per_state
        for p in range(n_pov):
            self.jacobians_along[p].append(jac[p])
        full_rank = has_full_pose_rank(jac, self.rank, rank_ratio, min_singular, self.target,
                                       pattern_ratio)
        _, right = jacobian_svd(jac)
        tangent = right[:, self.rank, :].copy()
        # SVD null vectors have an arbitrary sign: start along the one whose
        # largest component is positive so a run is reproducible.
        tangent *= np.sign(tangent[np.arange(n_pov), np.argmax(np.abs(tangent), axis=1)])[:, None]
        for p in np.flatnonzero(~full_rank):
            self.reason[p] = RANK_DEFICIENT
        # Two fronts per POV walk the loop in opposite directions from the
        # start, in the same sense calls, until they meet half way round.
        active = self.active = np.flatnonzero(full_rank)
        self.point = np.repeat(start[active, None, :], 2, axis=1)
        self.point_jac = np.repeat(jac[active, None], 2, axis=1)
        self.direction = tangent[active, None, :] * np.array([1.0, -1.0])[None, :, None]
        self.spacing = np.full((len(active), 2), float(initial_step))
        self.arc = np.zeros((len(active), 2))
        self.bend = np.zeros_like(self.direction)

    def advance(self) -> None:
        """One ``sense`` call: every front probes ahead, keeps what it can
        and adapts its step; fronts that met close their loop."""
        jac, null, size, knots = self._probe()
        self._accept(jac, null, size, knots)
        self._close()

    def _probe(self):
        """Predict ``knots_per_step`` states ahead of every front, sense them
        (the farthest with its stencil) and correct them back onto the level
        set. Returns per probe ``(A, 2, K, ...)``: its Jacobian, the null
        vector there (oriented along the walk), the size of its correction
        and the corrected knot."""
        n_motors, n_knots, fraction = self.n_motors, self.n_knots, self.fraction
        point, direction, bend, spacing = self.point, self.direction, self.bend, self.spacing
        reach = spacing[..., None] * fraction                                # (A, 2, K)
        predicted = (point[:, :, None, :] + reach[..., None] * direction[:, :, None, :]
                     + (0.5 * reach * reach)[..., None] * bend[:, :, None, :])
        # One call: the farthest probe of each front with its stencil, the
        # nearer probes one row each. Their Jacobians are interpolated
        # between the front's last knot and the farthest probe (the knots'
        # Gauss-Newton pass in ``resample`` removes what that costs in accuracy).
        farthest = predicted[:, :, -1, :]
        stencil = jacobian_stencil(farthest.reshape(-1, n_motors), self.fd_step)
        answer = np.asarray(self.body.sense(np.concatenate([
            stencil, predicted[:, :, :-1, :].reshape(-1, n_motors)])), dtype=float)
        self.calls += 1
        self.queries[self.active] += self.rows_per_call
        n_stencil_rows = len(stencil)
        at_farthest = answer[:n_stencil_rows].reshape(farthest.shape[:2]
                                                      + (self.rows_per_state, -1))
        farthest_sensation, farthest_jac = stencil_jacobian(at_farthest, self.fd_step)
        sensation = np.concatenate([answer[n_stencil_rows:].reshape(
            predicted.shape[:2] + (n_knots - 1, answer.shape[1])),
            farthest_sensation[:, :, None]], axis=2)
        along = (fraction / n_knots)[:, None, None]                          # (K, 1, 1)
        jac = ((1.0 - along) * self.point_jac[:, :, None] + along * farthest_jac[:, :, None])
        correction, null = _correction_and_null(
            jac.reshape((-1,) + jac.shape[3:]),
            (sensation - self.target[self.active][:, None, None, :]).reshape(
                -1, sensation.shape[-1]), self.rank,
            self._noise((len(self.active), 2, n_knots), averaged_last=True))
        correction = correction.reshape(predicted.shape)
        null = null.reshape(predicted.shape)
        size = _correction_size(correction)                                  # (A, 2, K)
        _orient(null, direction[:, :, None, :] + reach[..., None] * bend[:, :, None, :])
        return jac, null, size, predicted + correction

    def _noise(self, shape, averaged_last: bool = False) -> np.ndarray | None:
        """The noise sd of a residual's component against the start's
        sensation (averaged over the stencil's ``repeats``) for rows of
        ``shape`` sensed once, the last along the final axis with its stencil
        (averaged too) with ``averaged_last``; None on a noiseless body."""
        if self.noise_sd <= 0:
            return None
        noise = np.full(shape, self.noise_sd * np.sqrt(1.0 + 1.0 / self.repeats))
        if averaged_last:
            noise[..., -1] = self.noise_sd * np.sqrt(2.0 / self.repeats)
        return noise.reshape(-1)

    def _accept(self, jac, null, size, knots) -> None:
        """Each front keeps its probes up to the first whose correction is
        too large (the predictor error grows with the reach), moves to the
        last one kept and adapts its knot interval."""
        point, spacing, active = self.point, self.spacing, self.active
        good = ((size <= 4.0 * self.predictor_tol)
                | ((spacing[..., None] <= self.min_step) & (size < np.inf)))
        kept = np.cumprod(good, axis=-1).sum(axis=-1)                        # (A, 2)
        accepted = kept > 0
        last = np.maximum(kept - 1, 0)
        front_of = (np.arange(len(active))[:, None], np.arange(2)[None, :])
        # Probes past the first rejected one may have infinite corrections:
        # their links are never used (``kept``).
        with np.errstate(over="ignore", invalid="ignore"):
            links = np.linalg.norm(np.diff(np.concatenate([point[:, :, None, :], knots], axis=2),
                                           axis=2), axis=-1)                 # (A, 2, K)
        travelled = np.sum(np.where(np.arange(self.n_knots) < kept[..., None], links, 0.0),
                           axis=-1)
        previous_null = np.where((last > 0)[..., None], null[front_of + (last - 1,)],
                                 self.direction)
        new_bend = ((null[front_of + (last,)] - previous_null)
                    / np.maximum(links[front_of + (last,)], 1e-12)[..., None])
        # Predictor error ~ h^3 (the bend makes it second order): aim the
        # farthest probe's correction at predictor_tol.
        scale = (self.predictor_tol / np.maximum(size[..., -1], 1e-12)) ** (1.0 / 3.0)
        self.spacing = np.where(~accepted, 0.5 * spacing,
                                np.clip(spacing * np.clip(0.9 * scale, 0.5, 1.5),
                                        self.min_step, self.max_step))
        self.bend = np.where(accepted[..., None], new_bend, self.bend)
        self.point = np.where(accepted[..., None], knots[front_of + (last,)], point)
        self.point_jac = np.where(accepted[..., None, None], jac[front_of + (last,)],
                                  self.point_jac)
        self.direction = np.where(accepted[..., None], null[front_of + (last,)], self.direction)
        self.arc += travelled
        self.steps[active] += kept.sum(axis=1)
        for k, front in zip(*np.nonzero(accepted)):
            self.branches[active[k]][front].extend(knots[k, front, :kept[k, front]])
            self.branch_jacobians[active[k]][front].extend(jac[k, front, :kept[k, front]])

    def _close(self) -> None:
        """The fronts meet, modulo 2 pi per joint (a split POV meets itself a
        turn away). Within about a knot interval of each other they close
        the loop. Within reach of both next calls they aim at their midpoint
        instead: the last knot interval is then no longer than the others,
        and the fronts cannot pass each other between two calls. A POV out
        of budget stops, not closed."""
        point, direction, spacing, active = self.point, self.direction, self.spacing, self.active
        gap = wrap_phase(point[:, 1] - point[:, 0])
        distance = np.linalg.norm(gap, axis=1)
        facing = (np.sum(gap * direction[:, 0], axis=1) > 0.0) & (
            np.sum(gap * direction[:, 1], axis=1) < 0.0)
        long_enough = self.arc.sum(axis=1) > self.min_loop_length
        widest = spacing.max(axis=1)
        closing = long_enough & ((facing & (distance < 1.25 * widest)) |
                                 (distance < 0.5 * widest))
        converge = (long_enough & facing & ~closing
                    & (distance < 1.1 * self.n_knots * spacing.sum(axis=1)))
        spacing[converge] = np.maximum(distance[converge] / (2 * self.n_knots),
                                       self.min_step)[:, None]
        out_of_budget = self.queries[active] + self.rows_per_call > self.max_queries
        for k in np.flatnonzero(closing):
            p = active[k]
            forward, backward = self.branches[p]
            forward_jac, backward_jac = self.branch_jacobians[p]
            if backward and distance[k] < 0.2 * widest[k]:
                backward, backward_jac = backward[:-1], backward_jac[:-1]   # near-duplicate knot
            # Unwrapped, the backward front ends a whole number of turns from
            # the forward one: shift it so the path is continuous (a split
            # POV's path then ends a turn away from its start).
            turns = TWO_PI * np.rint((point[k, 1] - point[k, 0] - gap[k]) / TWO_PI)
            self.paths[p] = [self.start[p].copy()] + forward + [b - turns for b in backward[::-1]]
            self.jacobians_along[p] = self.jacobians_along[p] + forward_jac + backward_jac[::-1]
        for k in np.flatnonzero(out_of_budget & ~closing):
            self.reason[active[k]] = NOT_CLOSED
        keep = ~(closing | out_of_budget)
        self.active, self.point, self.point_jac, self.direction, self.bend = (
            active[keep], point[keep], self.point_jac[keep], direction[keep], self.bend[keep])
        self.spacing, self.arc = spacing[keep], self.arc[keep]

    def resample(self, n_samples: int, polish_knots: bool = True) -> np.ndarray:
        """``(P, n_samples, M)`` samples: the starts repeated, and for every
        closed loop that is not split, its polished knots resampled along a
        periodic spline. Without ``polish_knots`` the knots are taken as the
        walk corrected them (no call: their small offset from the level set
        only biases the samples' spacing along the loop, not their POV)."""
        start, paths, reason = self.start, self.paths, self.reason
        n_pov = len(start)
        samples = np.repeat(start[:, None, :], n_samples, axis=1)
        for p in range(n_pov):
            # A loop that came back to its start only a period away (the
            # fronts met in the torus, not in the unwrapped motor space) may
            # be one of several that make up the POV: it is not taken.
            if reason[p] == VALID and closure_gap_ratio(np.asarray(paths[p])) > self.closure_tol:
                reason[p] = SPLIT
        whole = [p for p in range(n_pov) if reason[p] == VALID]
        if whole and not polish_knots:
            for p in whole:
                if not np.all(np.isfinite(np.asarray(paths[p]))):
                    reason[p] = NOT_CLOSED
                    continue
                samples[p] = resample_loop_spline(np.asarray(paths[p]), n_samples)
        elif whole:
            # One more Gauss-Newton step on every knot (with the Jacobian of its
            # probe, in one call): a knot corrected once from a prediction
            # ~predictor_tol off the level set is still slightly off,
            # systematically on one side, which biases the spline's arc
            # length and so shifts the samples along the loop.
            knots = np.concatenate([np.asarray(paths[p][1:]) for p in whole])
            knot_jacobians = np.concatenate([np.asarray(self.jacobians_along[p][1:])
                                             for p in whole])
            counts = [len(paths[p]) - 1 for p in whole]
            sensation = np.asarray(self.body.sense(knots), dtype=float)
            self.calls += 1
            knots = knots + _correction_and_null(
                knot_jacobians, sensation - np.repeat(self.target[whole], counts, axis=0),
                self.rank, self._noise(len(knots)))[0]
            for p, chunk in zip(whole, np.split(knots, np.cumsum(counts)[:-1])):
                self.queries[p] += len(chunk)
                paths[p] = [paths[p][0]] + list(chunk)
                # A knot corrected through a lost row or a blank Jacobian is
                # non-finite: the loop is not whole.
                if not np.all(np.isfinite(chunk)):
                    reason[p] = NOT_CLOSED
                    continue
                samples[p] = resample_loop_spline(np.asarray(paths[p]), n_samples)
        return samples

    def project(self, samples: np.ndarray, polish_iterations: int,
                sample_tol: float = np.inf, step_tol: float = np.inf, checked: int = 0) -> float:
        """Project the valid POVs' samples (in place) back onto the level set
        with ``polish_iterations`` Gauss-Newton steps each; returns the
        largest sensory error before the last step (0 without steps).

        The Jacobian is the one of the nearest knot (at most half a knot
        interval away): its error only slows the convergence of a
        correction that is already tiny (spline between polished knots), so
        it costs one row per sample instead of M + 1. Samples whose last
        correction is still above ``sample_tol`` (where the spline strays
        from a sharply bent loop) get steps with their own Jacobian
        (``_repair``). A POV with a sample that its steps moved farther than
        ``step_tol`` is not kept (``NOT_CLOSED``): that sample lay as far off
        the level set as an uncorrected prediction, so the knots it was drawn
        from were not on it, and one step does not bring it back
        (``points_of_view.brief_loop_walks``). ``checked`` > 0: only that many
        samples, evenly spread along the loop, are sensed and stepped (a
        loop that left the level set leaves it over a stretch); the others
        stay as the spline put them."""
        n_pov, n_samples, n_motors = samples.shape
        max_residual = 0.0
        good = np.flatnonzero([r == VALID for r in self.reason])
        cols = np.arange(1, n_samples) if not 0 < checked < n_samples - 1 else \
            1 + np.unique(np.rint(np.linspace(0, n_samples - 2, checked)).astype(int))
        n_cols = len(cols)
        if len(good) and polish_iterations:
            projected = samples[good][:, cols].reshape(-1, n_motors)
            flat = projected
            flat_target = np.repeat(self.target[good], n_cols, axis=0)
            nearest_jac = np.concatenate([
                np.asarray(self.jacobians_along[p])[
                    _nearest_rows(samples[p, cols], np.asarray(self.paths[p]))]
                for p in good])
            for _ in range(polish_iterations):
                sensation = self._sensed(flat)
                self.calls += 1
                self.queries[good] += n_cols * self.repeats
                residual = sensation - flat_target
                max_residual = float(np.max(np.linalg.norm(residual, axis=1)))
                step = minimum_norm_correction(nearest_jac, residual, self.rank) \
                    if self.noise_sd <= 0 else loop_smoothed_correction(
                        nearest_jac, residual, self.rank, self._noise(1, True)[0], n_cols)
                flat = flat + _finite_or_zero(step)     # a lost row is not a step
            with np.errstate(invalid="ignore"):
                stray = ~(np.linalg.norm(step, axis=1) <= sample_tol)
            if stray.any():
                self._repair(flat, flat_target, stray, np.repeat(good, n_cols), sample_tol)
            if np.isfinite(step_tol):
                with np.errstate(over="ignore", invalid="ignore"):
                    moved = np.linalg.norm(flat - projected, axis=1)
                for p in np.unique(np.repeat(good, n_cols)[~(moved <= step_tol)]):
                    self.reason[p] = NOT_CLOSED
            samples[np.ix_(good, cols)] = flat.reshape(len(good), n_cols, n_motors)
        return max_residual

    def _sensed(self, states: np.ndarray) -> np.ndarray:
        """Sensations of ``states`` in one call: sensed once on a noiseless
        body; under noise each state ``repeats`` times (as the stencil's rows
        are, ``jacobians.AveragedStep``) and averaged."""
        if self.noise_sd <= 0 or self.repeats <= 1:
            return np.asarray(self.body.sense(states), dtype=float)
        rows = np.repeat(states, self.repeats, axis=0)
        rows[:, 0] += REPEAT_JITTER * np.tile(np.arange(self.repeats), len(states))
        sensed = np.asarray(self.body.sense(rows), dtype=float)
        return sensed.reshape(len(states), self.repeats, -1).mean(axis=1)

    def _repair(self, flat, target, stray, owner, sample_tol, rounds: int = 3) -> None:
        """Gauss-Newton steps with fresh Jacobians (one call each) on the
        ``stray`` rows of ``flat`` (in place) until each step is within
        ``sample_tol``; a POV with a row that does not get there in
        ``rounds`` steps is not kept (``NOT_CLOSED``)."""
        calls, sensed, failed = repair_rows(self.body, flat, target, np.flatnonzero(stray),
                                            rank=self.rank, fd_step=self.fd_step,
                                            tol=sample_tol, rounds=rounds)
        self.calls += calls
        for rows in sensed:
            np.add.at(self.queries, owner[rows], self.rows_per_state)
        for p in np.unique(owner[failed]):
            self.reason[p] = NOT_CLOSED


def _correction_size(correction: np.ndarray) -> np.ndarray:
    """The length of each correction (last axis). A probe that lands where
    the sensation is blank or pins no pose has an infinite (or NaN)
    correction: ``inf``, too large like any other."""
    with np.errstate(over="ignore", invalid="ignore"):
        size = np.linalg.norm(correction, axis=-1)
    return np.where(np.isfinite(size), size, np.inf)


def _orient(null: np.ndarray, heading: np.ndarray) -> None:
    """Turn each null vector (in place) along the walk's ``heading``: an SVD
    null vector has an arbitrary sign."""
    null *= np.where(np.sum(null * heading, axis=-1) < 0.0, -1.0, 1.0)[..., None]


def _finite_or_zero(step: np.ndarray) -> np.ndarray:
    """``step`` with its rows that are not finite (a lost sensation) at zero:
    such a row stays where it was and counts as stray."""
    return np.where(np.isfinite(step).all(axis=1, keepdims=True), step, 0.0)


def resample_loop_spline(path: np.ndarray, n_samples: int = 100) -> np.ndarray:
    """``n_samples`` points equally spaced in arc length along a closed loop
    interpolated by a periodic cubic spline through ``path`` ``(n, M)``.

    ``path`` starts at the POV's first state and ends near it (the loop is
    closed by appending the start, shifted by ``loop_winding`` turns). Arc
    length is Euclidean in unwrapped coordinates, as in
    ``core.paper.points_of_view.resample_closed_path``, but measured on the spline
    (Gauss-Legendre per knot interval) instead of on the chords: at the
    naive walk's steps (~0.05 rad) the chord length underestimates each arc
    by ~h^2 kappa^2 / 24, which moves the 50th sample by ~1e-3 rad.
    """
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or len(path) < 3:
        raise ValueError(f"path must have shape (n >= 3, joints), got {path.shape}")
    winding = loop_winding(path)
    loop = np.vstack([path, path[0] + TWO_PI * winding])
    # A periodic spline needs equal ends: remove the winding as a linear drift
    # in the parameter and add it back at the samples.
    # Repeated knots are dropped; the closing point always stays (the
    # spline's ends must be equal), so a knot on it goes instead.
    chord = np.linalg.norm(np.diff(loop, axis=0), axis=1)
    keep = np.r_[True, chord[:-1] > 1e-12, True]
    if keep.sum() > 2 and np.linalg.norm(loop[-1] - loop[keep][-2]) <= 1e-12:
        keep[np.flatnonzero(keep)[-2]] = False
    loop = loop[keep]
    chord = np.linalg.norm(np.diff(loop, axis=0), axis=1)
    knots = np.concatenate([[0.0], np.cumsum(chord)])
    period = knots[-1]
    drift = TWO_PI * winding / period
    values = loop - knots[:, None] * drift
    # Equal in exact arithmetic; rounding of a long loop's drift can leave
    # them further apart than the spline accepts.
    if not np.allclose(values[0], values[-1], rtol=1e-15, atol=1e-15):
        values[-1] = values[0]
    spline = CubicSpline(knots, values, bc_type="periodic")
    speed_of = spline.derivative()

    def speed(u):
        return np.linalg.norm(speed_of(u) + drift, axis=-1)

    width = np.diff(knots)
    nodes = knots[:-1, None] + width[:, None] * _GL_NODES
    piece = width * (speed(nodes) @ _GL_WEIGHTS)
    arc_at_knot = np.concatenate([[0.0], np.cumsum(piece)])
    total = arc_at_knot[-1]
    wanted = np.arange(n_samples) * (total / n_samples)
    interval = np.clip(np.searchsorted(arc_at_knot, wanted, side="right") - 1, 0, len(width) - 1)
    u = knots[interval] + (wanted - arc_at_knot[interval]) / np.maximum(
        piece[interval], 1e-300) * width[interval]
    for _ in range(4):
        # Newton on arc(u) = wanted inside each knot interval.
        lo = knots[interval]
        span = u - lo
        partial = span * (speed(lo[:, None] + span[:, None] * _GL_NODES) @ _GL_WEIGHTS)
        u = u - (arc_at_knot[interval] + partial - wanted) / speed(u)
    u[0] = 0.0
    return spline(u) + u[:, None] * drift


def _nearest_rows(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    gap = np.sum((points[:, None, :] - path[None, :, :]) ** 2, axis=-1)
    return np.argmin(gap, axis=1)
