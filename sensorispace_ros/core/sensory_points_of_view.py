"""Points of view from the sensorimotor flow alone (naive strategy, issue #3).

The paper samples a point of view (POV) by walking the kernel of the arm's
Jacobian J_f (Sec. 4.1). A naive agent has no f. It has a body that answers
motor states with sensations in a static environment, and a POV is, for an
environment without symmetries, the connected level set
``{m : sense(m) = sense(m_i)}`` (paper Eq. equivalenceClass). Its tangent is
the null vector of the *sensory* Jacobian ``J_s = dsense/dm`` (6x4, rank 3
because the sensation depends on the eye's 3-D pose only), which the agent
estimates by finite differences through ``sense``.

The walk is a predictor-corrector continuation: a predictor step of length
``h`` along the null vector, then one minimum-norm Gauss-Newton step back
onto ``sense(m) = s_i`` using the Jacobian measured at the predicted point.
Both come from one ``sense`` call per step whose rows are the predicted
point and its finite-difference stencil, for every walking POV at once.
``h`` adapts to the size of the correction, so steps are ~30-100 times
the paper's 1e-3. The closed loop is resampled at ``N`` points equally
spaced in arc length along a periodic cubic spline (a polyline's arc length
at such steps is off by ~h^2 kappa^2 / 24 relative, enough to shift samples
by ~1e-3 rad), and the samples are projected back onto the level set.

Nothing here knows the arm, the retina or the world: ``body`` only needs
``sense``, ``n_motors`` and ``n_sensors``; ``loop_winding`` comes from
``motor_loops``, which knows no arm either.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from .motor_loops import loop_winding

TWO_PI = 2.0 * np.pi

VALID = "ok"
SPLIT = "split"                 # the walk came back to the start only modulo 2 pi
NOT_CLOSED = "not_closed"       # query budget spent before the loop closed
RANK_DEFICIENT = "rank_deficient"  # the sensation does not pin the eye's pose here

# Gauss-Legendre nodes on [0, 1] for the spline's arc length; a cubic's
# speed is smooth between knots, 5 nodes integrate it to ~1e-12.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(5)
_GL_NODES = 0.5 * (_GL_NODES + 1.0)
_GL_WEIGHTS = 0.5 * _GL_WEIGHTS


def sensory_jacobian(body, motor_states: np.ndarray, fd_step: float = 1e-6):
    """Sensations and forward-difference sensory Jacobians of many motor states
    in ONE ``sense`` call.

    ``motor_states`` ``(B, M)``. Returns ``(sensations (B, S), jacobians
    (B, S, M), rows)`` where ``rows = B * (M + 1)`` is the number of motor
    states probed. Rows are ordered state by state (the state, then its
    ``M`` displaced copies), so the arm ends at the last state's stencil.
    """
    motor_states = np.asarray(motor_states, dtype=float)
    n_batch, n_motors = motor_states.shape
    stencil = np.repeat(motor_states[:, None, :], n_motors + 1, axis=1)
    stencil[:, 1:, :] += fd_step * np.eye(n_motors)
    answer = np.asarray(body.sense(stencil.reshape(-1, n_motors)), dtype=float)
    answer = answer.reshape(n_batch, n_motors + 1, -1)
    sensations = answer[:, 0, :]
    jacobians = np.swapaxes(answer[:, 1:, :] - sensations[:, None, :], 1, 2) / fd_step
    return sensations, jacobians, n_batch * (n_motors + 1)


def rank3_report(jacobians: np.ndarray):
    """SVD pieces of sensory Jacobians ``(B, S, M)``: singular values
    ``(B, min(S, M))`` and right singular vectors ``(B, M, M)`` (rows)."""
    _, singular, right = np.linalg.svd(jacobians)
    return singular, right


def has_full_pose_rank(jacobians: np.ndarray, rank_ratio: float = 1e-3,
                       min_singular: float = 0.0) -> np.ndarray:
    """True where a sensory Jacobian ``(B, S, M)`` has rank 3: its third
    singular value is at least ``rank_ratio`` times the first and at least
    ``min_singular``. The sensation then pins the eye's 3-D pose locally; a
    blank (J = 0) or one-light (rank 2) sensation does not."""
    singular = np.linalg.svd(np.asarray(jacobians, dtype=float), compute_uv=False)
    third = singular[:, 2]
    return (third >= rank_ratio * singular[:, 0]) & (third >= min_singular) & (third > 0.0)


def minimum_norm_correction(jacobians: np.ndarray, residuals: np.ndarray,
                            rank: int = 3) -> np.ndarray:
    """Gauss-Newton step ``-J_r^+ r`` with ``J`` truncated to its ``rank``
    largest singular values: the correction moves across the level set,
    never along it (the discarded direction is the POV's tangent)."""
    u, singular, right = np.linalg.svd(jacobians, full_matrices=False)
    # A blank sensation has J = 0: its "correction" is infinite, never small.
    with np.errstate(divide="ignore", invalid="ignore"):
        coeff = np.einsum("bsk,bs->bk", u[:, :, :rank], residuals) / singular[:, :rank]
        return -np.einsum("bk,bkm->bm", coeff, right[:, :rank, :])


def _correction_and_null(jacobians: np.ndarray, residuals: np.ndarray):
    """``minimum_norm_correction`` and the unit null vector of each rank-3
    Jacobian from one SVD (the walk's inner loop)."""
    u, singular, right = np.linalg.svd(jacobians, full_matrices=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        coeff = np.einsum("bsk,bs->bk", u[:, :, :3], residuals) / singular[:, :3]
    return -np.einsum("bk,bkm->bm", coeff, right[:, :3, :]), right[:, 3, :].copy()


@dataclass
class SensoryPointsOfView:
    """POVs sampled through the body, one row per starting motor state.

    ``samples[p]`` ``(n_samples, M)``: unwrapped motor states equally spaced
    in arc length, ``samples[p, 0]`` the start. ``valid[p]`` False when the
    walk could not sample a whole loop (``reason[p]``: ``"split"``,
    ``"not_closed"``, ``"rank_deficient"``). ``queries[p]``: motor states
    probed for POV ``p``; ``calls``: ``sense`` calls of the whole batch.
    ``steps[p]``: predictor-corrector steps; ``max_residual``: largest
    sensory error ``|sense(sample) - sense(start)|`` of a valid POV's final
    samples; ``target_sensations[p]`` the start's sensation.
    """

    samples: np.ndarray
    valid: np.ndarray
    reason: list
    queries: np.ndarray
    steps: np.ndarray
    calls: int
    max_residual: float
    target_sensations: np.ndarray


def sample_sensory_points_of_view(
        body, motor_states: np.ndarray, *, n_samples: int = 100, fd_step: float = 1e-6,
        initial_step: float = 0.05, min_step: float = 1e-3, max_step: float = 0.15,
        predictor_tol: float = 2e-3, rank_ratio: float = 1e-3, max_queries: int = 5000,
        polish_iterations: int = 2, min_loop_length: float = 0.3) -> SensoryPointsOfView:
    """Sample the POV of every motor state in ``motor_states`` ``(P, M)``
    through ``body.sense`` in the current (static) environment.

    All POVs walk together: each step is one ``sense`` call with
    ``(M + 1)`` rows per walking POV. ``initial_step``/``min_step``/
    ``max_step`` bound the predictor step (rad); the step grows or shrinks
    so the Gauss-Newton correction stays near ``predictor_tol`` (the
    correction of a tangent step of length h is ~ h^2 kappa / 2). A step
    whose correction exceeds ``4 * predictor_tol`` is redone at half length.
    The loop closes when the walk, after ``min_loop_length`` rad of arc,
    is within one step of the start in the periodic motor metric; a loop that
    closes only modulo 2 pi in some joint is a split POV (paper Fig. 5b,
    ``loop_winding``) and is rejected as in the paper. ``rank_ratio``:
    smallest accepted ratio of the 3rd to the 1st singular value of the
    sensory Jacobian at the start (below it the sensation does not determine
    the eye's pose and there is no 1-D level set to walk).
    """
    start = np.array(motor_states, dtype=float, copy=True)
    n_motors = int(body.n_motors)
    if start.ndim != 2 or start.shape[1] != n_motors:
        raise ValueError(f"motor_states must have shape (P, {n_motors}), got {start.shape}")
    if not np.all(np.isfinite(start)):
        raise ValueError("motor_states contains non-finite values")
    _check_walk_parameters(n_samples=n_samples, fd_step=fd_step, initial_step=initial_step,
                           min_step=min_step, max_step=max_step, predictor_tol=predictor_tol,
                           rank_ratio=rank_ratio, max_queries=max_queries,
                           polish_iterations=polish_iterations,
                           min_loop_length=min_loop_length)
    n_pov = len(start)
    rows_per_state = n_motors + 1
    queries = np.zeros(n_pov, dtype=int)
    steps = np.zeros(n_pov, dtype=int)
    reason = [VALID] * n_pov
    paths: list[list[np.ndarray]] = [[start[p].copy()] for p in range(n_pov)]
    jacobians_along: list[list[np.ndarray]] = [[] for _ in range(n_pov)]
    calls = 0
    if n_pov == 0:
        return SensoryPointsOfView(np.zeros((0, n_samples, n_motors)), np.zeros(0, bool), [],
                                   queries, steps, 0, 0.0, np.zeros((0, int(body.n_sensors))))

    target, jac, _ = sensory_jacobian(body, start, fd_step)
    calls += 1
    queries += rows_per_state
    for p in range(n_pov):
        jacobians_along[p].append(jac[p])
    full_rank = has_full_pose_rank(jac, rank_ratio)
    _, right = rank3_report(jac)
    tangent = right[:, -1, :].copy()
    # SVD null vectors have an arbitrary sign: start along the one whose
    # largest component is positive so a run is reproducible.
    tangent *= np.sign(tangent[np.arange(n_pov), np.argmax(np.abs(tangent), axis=1)])[:, None]
    for p in np.flatnonzero(~full_rank):
        reason[p] = RANK_DEFICIENT

    active = np.flatnonzero(full_rank)
    point = start[active].copy()             # last accepted (corrected) state
    direction = tangent[active].copy()
    step = np.full(len(active), float(initial_step))
    arc = np.zeros(len(active))
    bend = np.zeros_like(direction)          # d(tangent)/d(arc), from the last two steps
    while len(active):
        predicted = point + step[:, None] * direction + (0.5 * step * step)[:, None] * bend
        sensation, jac, _ = sensory_jacobian(body, predicted, fd_step)
        calls += 1
        queries[active] += rows_per_state
        correction, null = _correction_and_null(jac, sensation - target[active])
        size = np.linalg.norm(correction, axis=1)
        rejected = (size > 4.0 * predictor_tol) & (step > min_step)
        accepted = ~rejected
        new_point = predicted + correction
        null *= np.where(np.sum(null * direction, axis=1) < 0.0, -1.0, 1.0)[:, None]
        travelled = np.linalg.norm(new_point - point, axis=1)

        # Predictor error ~ h^2: aim the next correction at predictor_tol.
        scale = (predictor_tol / np.maximum(size, 1e-12)) ** (1.0 / 3.0)
        step = np.where(rejected, 0.5 * step,
                        np.clip(step * np.clip(0.9 * scale, 0.5, 1.5), min_step, max_step))
        new_bend = (null - direction) / np.maximum(travelled, 1e-12)[:, None]
        bend = np.where(accepted[:, None], new_bend, bend)
        point = np.where(accepted[:, None], new_point, point)
        direction = np.where(accepted[:, None], null, direction)
        arc += np.where(accepted, travelled, 0.0)
        steps[active] += accepted

        # Close when the start lies within one step ahead (or is very near).
        to_start = _wrap(start[active] - point)
        gap = np.linalg.norm(to_start, axis=1)
        ahead = np.sum(to_start * direction, axis=1) > 0.0
        closing = accepted & (arc > min_loop_length) & (
            (gap < 1.5 * step) & ahead | (gap < 0.5 * step))
        out_of_budget = queries[active] + rows_per_state > max_queries
        for k in np.flatnonzero(accepted):
            paths[active[k]].append(point[k].copy())
            jacobians_along[active[k]].append(jac[k])
        for k in np.flatnonzero(out_of_budget & ~closing):
            reason[active[k]] = NOT_CLOSED
        keep = ~(closing | out_of_budget)
        active, point, direction, bend, step, arc = (
            active[keep], point[keep], direction[keep], bend[keep], step[keep], arc[keep])

    samples = np.repeat(start[:, None, :], n_samples, axis=1)
    for p in range(n_pov):
        if reason[p] != VALID:
            continue
        path = np.asarray(paths[p])
        if np.any(loop_winding(path) != 0):
            reason[p] = SPLIT
            continue
        samples[p] = resample_loop_spline(path, n_samples)

    # Project the samples back onto the level set with one Gauss-Newton step
    # each. The Jacobian is the one measured at the nearest walk point (a few
    # 1e-2 rad away): its error only slows the convergence of a correction
    # that is already ~1e-6, so it costs one row per sample instead of M + 1.
    max_residual = 0.0
    good = np.flatnonzero([r == VALID for r in reason])
    if len(good):
        flat = samples[good, 1:].reshape(-1, n_motors)
        flat_target = np.repeat(target[good], n_samples - 1, axis=0)
        nearest_jac = np.concatenate([
            np.asarray(jacobians_along[p])[_nearest_rows(samples[p, 1:], np.asarray(paths[p]))]
            for p in good])
        for _ in range(polish_iterations):
            sensation = np.asarray(body.sense(flat), dtype=float)
            calls += 1
            queries[good] += n_samples - 1
            residual = sensation - flat_target
            max_residual = float(np.max(np.linalg.norm(residual, axis=1)))
            flat = flat + minimum_norm_correction(nearest_jac, residual)
        samples[good, 1:] = flat.reshape(len(good), n_samples - 1, n_motors)
    valid = np.array([r == VALID for r in reason])
    return SensoryPointsOfView(samples=samples, valid=valid, reason=reason, queries=queries,
                               steps=steps, calls=calls, max_residual=max_residual,
                               target_sensations=target)


def resample_loop_spline(path: np.ndarray, n_samples: int = 100) -> np.ndarray:
    """``n_samples`` points equally spaced in arc length along a closed loop
    interpolated by a periodic cubic spline through ``path`` ``(n, M)``.

    ``path`` starts at the POV's first state and ends near it (the loop is
    closed by appending the start, shifted by ``loop_winding`` turns). Arc
    length is Euclidean in unwrapped coordinates, as in
    ``points_of_view.resample_closed_path``, but measured on the spline
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
    chord = np.linalg.norm(np.diff(loop, axis=0), axis=1)
    keep = np.r_[True, chord > 1e-12]
    loop, chord = loop[keep], chord[keep[1:]]
    knots = np.concatenate([[0.0], np.cumsum(chord)])
    period = knots[-1]
    drift = TWO_PI * winding / period
    spline = CubicSpline(knots, loop - knots[:, None] * drift, bc_type="periodic")
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


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % TWO_PI - np.pi


def _check_walk_parameters(**values) -> None:
    positive = ("fd_step", "initial_step", "min_step", "max_step", "predictor_tol",
                "rank_ratio", "min_loop_length")
    for name in positive:
        if not np.isfinite(values[name]) or values[name] <= 0:
            raise ValueError(f"{name} must be a finite number > 0, got {values[name]}")
    if not values["min_step"] <= values["initial_step"] <= values["max_step"]:
        raise ValueError("initial_step must lie in [min_step, max_step], got "
                         f"{values['initial_step']} not in [{values['min_step']}, "
                         f"{values['max_step']}]")
    for name, minimum in (("n_samples", 2), ("max_queries", 1), ("polish_iterations", 0)):
        value = values[name]
        if int(value) != value or value < minimum:
            raise ValueError(f"{name} must be an integer >= {minimum}, got {value}")
