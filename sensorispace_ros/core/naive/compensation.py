"""Compensation from the sensorimotor flow alone (naive strategy).

The paper compensates an object displacement with Nelder-Mead on the tip
pose, knowing the forward model and the displacement (Sec. 4.2). The naive
agent knows neither: it looks for a motor state whose sensation in the
current (static) environment equals a remembered target sensation,
minimising ``|sense(m) - s_target|`` by Levenberg-Marquardt on
finite-difference sensory Jacobians.

Many searches (targets x restarts) run together: every LM iteration is ONE
``sense`` call carrying each search's trial state and its finite-difference
stencil. scipy's ``least_squares(method="lm")`` would need one call per
search per Jacobian (it cannot batch across problems): one round trip to the
ROS body per search instead of one for the whole batch.

A search is accepted only if the sensory error is tiny, the Gauss-Newton step
that would remove it is tiny in motor space, AND the sensory Jacobian at the
solution has rank 3 (third singular value not negligible against the
first). Without the rank test a blank or one-light sensation is
"compensated" anywhere: its level set is 2- or 3-dimensional.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core.naive.points_of_view import minimum_norm_correction, sensory_jacobian


@dataclass
class CompensationSearch:
    """Outcome of a batch of LM searches, one row per (target, start) search.

    ``motor_states`` final states ``(K, M)``; ``sensory_error`` final
    ``|sense(m) - s_target|``; ``motor_residual`` norm of the Gauss-Newton
    step that would remove that error (rad); ``rank_ratio`` third over first
    singular value of the sensory Jacobian at the final state; ``accepted``
    the three tests together; ``queries[k]`` motor states probed by search
    ``k``; ``iterations[k]``; ``calls`` ``sense`` calls of the whole batch.
    """

    motor_states: np.ndarray
    sensory_error: np.ndarray
    motor_residual: np.ndarray
    rank_ratio: np.ndarray
    accepted: np.ndarray
    queries: np.ndarray
    iterations: np.ndarray
    calls: int


def compensate(body, target_sensations: np.ndarray, starts: np.ndarray, *,
               fd_step: float = 1e-6, max_iterations: int = 40,
               error_tol: float = 1e-10, motor_tol: float = 1e-8,
               rank_ratio: float = 1e-3, max_step: float = 0.5,
               initial_damping: float = 1e-3, stall_iterations: int = 6,
               stall_factor: float = 0.5, stationary_ratio: float = 0.2,
               stop_found_targets: bool = True) -> CompensationSearch:
    """Batched Levenberg-Marquardt: drive ``sense(m)`` to ``target_sensations[k]``
    from ``starts[k]`` for every search ``k`` at once.

    ``target_sensations`` ``(K, S)``, ``starts`` ``(K, M)``. Each iteration
    solves ``(J^T J + lambda I) dm = -J^T r`` (Levenberg's isotropic damping:
    the step stays small along the level set's null direction instead of
    wandering along it), caps ``|dm|`` at ``max_step`` rad, and probes the
    trial state with its stencil in the batch's one ``sense`` call. A better
    trial is kept and ``lambda`` shrinks; a worse one is dropped and
    ``lambda`` grows (``lambda`` is relative to the mean squared singular
    value of ``J``). A search stops when accepted (``sensory_error <=
    error_tol`` and ``motor_residual <= motor_tol``), after ``max_iterations``,
    or when its error has not fallen below ``stall_factor`` times its value
    ``stall_iterations`` iterations earlier (a local minimum: the target is
    not reachable from there).

    Two more stops save ``sense`` calls (each a round trip to the body) without
    changing which targets are found (see docs/benchmarks.md):

    * at a stationary point: when the part of the residual in the range of
      ``J`` is below ``stationary_ratio`` times the residual, the linearised
      model can remove at most ``1 - sqrt(1 - ratio^2)`` (2 % at 0.2) of the
      error; at a local minimum with a nonzero residual (a target that is
      not reachable from there) it tends to 0 while the stall test would
      still wait ``stall_iterations`` iterations. ``0`` disables it.
    * ``stop_found_targets``: searches whose target rows are equal (restarts
      toward one target) stop as soon as one of them is accepted: an
      accepted state has a rank-3 sensory Jacobian, so the target sensation
      pins the eye's pose and another restart could only find that pose
      again.
    """
    targets, point = _checked_searches(
        body, target_sensations, starts, fd_step=fd_step, max_iterations=max_iterations,
        error_tol=error_tol, motor_tol=motor_tol, rank_ratio=rank_ratio, max_step=max_step,
        initial_damping=initial_damping, stall_iterations=stall_iterations,
        stall_factor=stall_factor, stationary_ratio=stationary_ratio)
    n_search = len(point)
    rows_per_state = point.shape[1] + 1
    queries = np.zeros(n_search, dtype=int)
    iterations = np.zeros(n_search, dtype=int)
    if n_search == 0:
        empty = np.zeros(0)
        return CompensationSearch(point, empty, empty, empty, np.zeros(0, bool),
                                  queries, iterations, 0)

    sensation, jac, _ = sensory_jacobian(body, point, fd_step)
    calls = 1
    queries += rows_per_state
    residual = sensation - targets
    error = np.linalg.norm(residual, axis=1)
    damping = np.full(n_search, float(initial_damping))
    history = [error.copy()]
    active = np.ones(n_search, dtype=bool)
    _, target_id = np.unique(targets, axis=0, return_inverse=True)
    target_id = target_id.reshape(-1)
    for iteration in range(1, max_iterations + 1):
        active &= ~_stopping(jac, residual, error, history, iteration, target_id,
                             error_tol=error_tol, motor_tol=motor_tol, rank_ratio=rank_ratio,
                             stall_iterations=stall_iterations, stall_factor=stall_factor,
                             stationary_ratio=stationary_ratio,
                             stop_found_targets=stop_found_targets)
        if not active.any():
            break
        idx = np.flatnonzero(active)
        _damped_step(body, idx, targets, point, jac, residual, error, damping,
                     fd_step=fd_step, max_step=max_step)
        calls += 1
        queries[idx] += rows_per_state
        iterations[idx] += 1
        history.append(error.copy())

    return _outcome(point, jac, residual, error, queries, iterations, calls,
                    error_tol=error_tol, motor_tol=motor_tol, rank_ratio=rank_ratio)


def _checked_searches(body, target_sensations, starts, **parameters):
    """``(targets (K, S), starts (K, M))`` as float arrays (the starts a
    copy, the searches' working states), after checking their shapes and
    ``parameters``."""
    targets = np.asarray(target_sensations, dtype=float)
    point = np.array(starts, dtype=float, copy=True)
    n_motors = int(body.n_motors)
    if point.ndim != 2 or point.shape[1] != n_motors:
        raise ValueError(f"starts must have shape (K, {n_motors}), got {point.shape}")
    if targets.ndim != 2 or len(targets) != len(point):
        raise ValueError(f"target_sensations must have shape ({len(point)}, S), "
                         f"got {targets.shape}")
    _check_search_parameters(**parameters)
    return targets, point


def _outcome(point, jac, residual, error, queries, iterations, calls, *, error_tol, motor_tol,
             rank_ratio) -> CompensationSearch:
    """The searches' final states, with the three acceptance tests."""
    singular = np.linalg.svd(jac, compute_uv=False)
    ratio = singular[:, 2] / np.maximum(singular[:, 0], 1e-300)
    motor_residual = _step_norm(jac, residual)
    accepted = (error <= error_tol) & (motor_residual <= motor_tol) & (ratio >= rank_ratio)
    return CompensationSearch(motor_states=point, sensory_error=error,
                              motor_residual=motor_residual, rank_ratio=ratio,
                              accepted=accepted, queries=queries, iterations=iterations,
                              calls=calls)


def _stopping(jac, residual, error, history, iteration, target_id, *, error_tol, motor_tol,
              rank_ratio, stall_iterations, stall_factor, stationary_ratio,
              stop_found_targets) -> np.ndarray:
    """Searches that stop before this iteration (``compensate``'s stops):
    converged, stalled, at a stationary point, or restarts toward a target
    another search already found."""
    done = _converged(jac, residual, error, error_tol, motor_tol)
    stop = done.copy()
    if iteration > stall_iterations:
        stop |= error > stall_factor * history[-1 - stall_iterations]
    if stationary_ratio > 0 or stop_found_targets:
        u, singular, _ = np.linalg.svd(jac, full_matrices=False)
    if stationary_ratio > 0:
        in_range = np.linalg.norm(np.einsum("bsk,bs->bk", u[:, :, :3], residual), axis=1)
        stop |= (in_range < stationary_ratio * error) & (error > error_tol)
    if stop_found_targets and done.any():
        found = done & (singular[:, 2] >= rank_ratio * singular[:, 0])
        stop |= np.isin(target_id, target_id[found])
    return stop


def _damped_step(body, idx, targets, point, jac, residual, error, damping, *, fd_step,
                 max_step) -> None:
    """One Levenberg-Marquardt iteration of the searches ``idx``, in one
    ``sense`` call: solve the damped normal equations, cap the step, probe
    the trial state with its stencil; keep a better trial (``point``,
    ``jac``, ``residual``, ``error`` updated in place) and shrink its
    damping, grow the damping of a worse one."""
    n_motors = point.shape[1]
    j = jac[idx]
    normal = np.swapaxes(j, 1, 2) @ j
    # A blank sensation has J = 0: keep the system solvable (step 0).
    scale = np.maximum(np.trace(normal, axis1=1, axis2=2) / n_motors, 1e-20)
    lhs = normal + (damping[idx] * scale)[:, None, None] * np.eye(n_motors)
    rhs = -np.einsum("bsm,bs->bm", j, residual[idx])
    step = np.linalg.solve(lhs, rhs[..., None])[..., 0]
    length = np.linalg.norm(step, axis=1)
    step *= np.minimum(1.0, max_step / np.maximum(length, 1e-300))[:, None]
    trial = point[idx] + step
    trial_sensation, trial_jac, _ = sensory_jacobian(body, trial, fd_step)
    trial_residual = trial_sensation - targets[idx]
    trial_error = np.linalg.norm(trial_residual, axis=1)
    better = trial_error < error[idx]
    keep = idx[better]
    point[keep] = trial[better]
    jac[keep] = trial_jac[better]
    residual[keep] = trial_residual[better]
    error[keep] = trial_error[better]
    damping[keep] = np.maximum(damping[keep] / 3.0, 1e-12)
    worse = idx[~better]
    damping[worse] = damping[worse] * 4.0


def _converged(jac, residual, error, error_tol, motor_tol):
    converged = error <= error_tol
    if converged.any():
        idx = np.flatnonzero(converged)
        gn = _step_norm(jac[idx], residual[idx])
        converged[idx] = gn <= motor_tol
    return converged


def _step_norm(jac, residual):
    """Norm of the Gauss-Newton step; infinite for a blank (J = 0) sensation."""
    step = minimum_norm_correction(jac, residual)
    with np.errstate(over="ignore", invalid="ignore"):
        norm = np.sqrt(np.sum(step * step, axis=1))
    return np.where(np.isfinite(norm), norm, np.inf)


def _check_search_parameters(**values) -> None:
    for name in ("fd_step", "error_tol", "motor_tol", "rank_ratio", "max_step",
                 "initial_damping"):
        if not np.isfinite(values[name]) or values[name] <= 0:
            raise ValueError(f"{name} must be a finite number > 0, got {values[name]}")
    for name in ("max_iterations", "stall_iterations"):
        value = values[name]
        if int(value) != value or value < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {value}")
    if not 0 < values["stall_factor"] < 1:
        raise ValueError(f"stall_factor must be in (0, 1), got {values['stall_factor']}")
    if not 0 <= values["stationary_ratio"] < 1:
        raise ValueError("stationary_ratio must be in [0, 1), got "
                         f"{values['stationary_ratio']}")
