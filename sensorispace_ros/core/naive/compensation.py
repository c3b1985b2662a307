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
solution has the body's pose rank ``r`` as the agent measured it
(``structure``): its ``r``-th singular value is not negligible against the
first, for the Jacobian and for its gain-free part
(``jacobians.gain_free_jacobian``). Without the rank test a blank or one-light sensation is
"compensated" anywhere: its level set is larger than a point of view.
Motor states are phases. The sensory error is judged against the sensory
gain *at the solution* (the largest singular value of its Jacobian):
``error_tol`` is a motor-equivalent amount, so no tolerance is in the units
of the receptors and a code that is steep in one place and flat in another
gets the same test everywhere.

Besides convergence, a stall and the iteration budget, two stops of
``compensate`` save ``sense`` calls without changing which targets are found
(see docs/benchmarks.md):

* at a stationary point: when the part of the residual in the range of
  ``J`` is below ``stationary_ratio`` times the residual, the linearised
  model can remove at most ``1 - sqrt(1 - ratio^2)`` (2 % at 0.2) of the
  error (at a local minimum it tends to 0). ``0`` disables it.
* ``stop_found_targets``: searches toward one target stop as soon as one
  of them is accepted: the target sensation pins the sensor's
  configuration, so another restart could only find it again (on the
  same POV; for a 0-D POV, another of its isolated solutions: pass False
  to collect those).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core.naive.jacobians import (AveragedStep, CloudStep, has_full_pose_rank,
    minimum_norm_correction,
    sensory_jacobian, stencil_rows)


@dataclass
class CompensationSearch:
    """Outcome of a batch of LM searches, one row per (target, start) search.

    ``motor_states`` final states ``(K, M)``; ``sensory_error`` final
    ``|sense(m) - s_target|``; ``gain`` the largest singular value of the
    sensory Jacobian there; ``motor_residual`` norm of the Gauss-Newton
    step that would remove that error; ``rank_ratio`` the ``rank``-th over
    the first singular value of the sensory Jacobian at the final state; ``accepted``
    the three tests together; ``queries[k]`` motor states probed by search
    ``k``; ``iterations[k]``; ``calls`` ``sense`` calls of the whole batch.
    """

    motor_states: np.ndarray
    sensory_error: np.ndarray
    gain: np.ndarray
    motor_residual: np.ndarray
    rank_ratio: np.ndarray
    accepted: np.ndarray
    queries: np.ndarray
    iterations: np.ndarray
    calls: int


def compensate(body, target_sensations: np.ndarray, starts: np.ndarray, *, rank: int,
               min_singular: float = 0.0, pattern_ratio: float = 1e-6, fd_step: float = 1e-6,
               max_iterations: int = 40, error_tol: float = 1e-10, motor_tol: float = 1e-8,
               rank_ratio: float = 1e-3, max_step: float = 0.5, initial_damping: float = 1e-3,
               stall_iterations: int = 6, stall_factor: float = 0.5, stationary_ratio: float = 0.2,
               stop_found_targets: bool = True, noise_step: float = 0.0, in_turn: bool = False,
               max_turns: int = 0, probe_first: bool = False) -> CompensationSearch:
    """Batched Levenberg-Marquardt: drive ``sense(m)`` to ``target_sensations[k]``
    from ``starts[k]`` for every search ``k`` at once.

    ``target_sensations`` ``(K, S)``, ``starts`` ``(K, M)``. The rank test
    is ``jacobians.has_full_pose_rank`` (``rank_ratio``, ``min_singular`` in
    sensation units, ``pattern_ratio`` for the gain-free part). Each iteration
    is a damped Gauss-Newton step (``_damped_step``, capped at ``max_step``).
    A search stops when accepted (``sensory_error <= error_tol * gain`` and
    ``motor_residual <= _motor_tolerance``), after ``max_iterations``, when its
    error has not fallen below ``stall_factor`` times its value
    ``stall_iterations`` iterations earlier (a local minimum), or at the two
    stops of the module docstring. ``in_turn``: a target's searches one at a time (``_Turns``),
    its ``max_turns`` best starts at most (0: every one; the others are sensed, not searched).
    ``probe_first``: the same searches, each trial sensed alone first (``_damped_step``).
    """
    targets, point = _checked_searches(
        body, target_sensations, starts, rank=rank, fd_step=fd_step, max_iterations=max_iterations,
        error_tol=error_tol, motor_tol=motor_tol, rank_ratio=rank_ratio, max_step=max_step,
        initial_damping=initial_damping, stall_iterations=stall_iterations,
        stall_factor=stall_factor, stationary_ratio=stationary_ratio)
    accept = dict(rank=int(rank), error_tol=error_tol, motor_tol=(motor_tol, noise_step),
                  rank_ratio=rank_ratio, min_singular=min_singular, pattern_ratio=pattern_ratio)
    n_search = len(point)
    iterations = np.zeros(n_search, dtype=int)
    if n_search == 0 or rank == 0:          # rank 0: no sensation pins anything
        return _none_accepted(point)
    target_id, sensation, jac, residual, error, queries, calls, turns = _first_call(
        body, point, targets, fd_step, in_turn, max_turns)
    damping = np.full(n_search, float(initial_damping))
    history = [error.copy()]
    active = np.ones(n_search, dtype=bool) if turns is None else turns.turn == 0
    for iteration in range(1, max_iterations * (1 if turns is None else turns.count) + 1):
        active &= ~_stopping(jac, residual + targets, residual, error, history,
                             iteration if turns is None else iterations + 1,
                             target_id, accept, stall_iterations=stall_iterations,
                             stall_factor=stall_factor, stationary_ratio=stationary_ratio,
                             stop_found_targets=stop_found_targets)
        if turns is not None:
            started = turns.next(active, iterations < max_iterations, _accepted(
                jac, residual + targets, residual, error, **accept)[0])
            calls += turns.stencils(started, point, residual + targets, jac, residual, error,
                                    targets, queries)
        if not active.any():
            break
        idx = np.flatnonzero(active)
        rows, step_calls = _damped_step(body, idx, targets, point, jac, residual, error, damping,
                                        fd_step=fd_step, max_step=max_step, alone=probe_first)
        calls, queries[idx] = calls + step_calls, queries[idx] + rows
        iterations[idx] += 1
        history.append(error.copy())
    return _outcome(point, jac, residual + targets, residual, error, queries, iterations, calls,
                    **accept)


def _first_call(body, point, targets, fd_step, in_turn, max_turns):
    """``compensate``'s first call: every start's stencil; in turn (``_Turns``),
    with a step whose stencil senses each state once, the starts alone, then the
    stencils of the first turn's searches (``_Turns.stencils``). Returns
    ``(target id of each search, sensations, Jacobians (0 where not sensed),
    residuals, errors, rows of each search, calls, turns or None)``."""
    n_search = len(point)
    target_id = np.unique(targets, axis=0, return_inverse=True)[1].reshape(-1)
    alone = in_turn and not isinstance(fd_step, (AveragedStep, CloudStep))
    if alone:
        sensation = np.asarray(body.sense(point), dtype=float).reshape(n_search, -1)
        jac = np.zeros(sensation.shape + (point.shape[1],))
        queries = np.ones(n_search, dtype=int)
    else:
        sensation, jac, _ = sensory_jacobian(body, point, fd_step)
        queries = np.full(n_search, stencil_rows(point.shape[1], fd_step), dtype=int)
    residual = sensation - targets
    error = np.linalg.norm(residual, axis=1)
    turns = _Turns(target_id, error, max_turns, body=body if alone else None,
                   fd_step=fd_step) if in_turn else None
    calls = 1 if turns is None else 1 + turns.stencils(
        turns.turn == 0, point, sensation, jac, residual, error, targets, queries)
    return target_id, sensation, jac, residual, error, queries, calls, turns


def _none_accepted(point) -> CompensationSearch:
    """The outcome of searches that were not run: none accepted, nothing sensed."""
    n_search, nothing = len(point), np.zeros(len(point))
    return CompensationSearch(point, np.full(n_search, np.inf), nothing, np.full(n_search, np.inf),
                              nothing.copy(), np.zeros(n_search, bool),
                              np.zeros(n_search, dtype=int), np.zeros(n_search, dtype=int), 0)


def _checked_searches(body, target_sensations, starts, rank, **parameters):
    """``(targets (K, S), starts (K, M))`` as float arrays (the starts a
    copy, the searches' working states), after checking their shapes,
    ``rank`` and ``parameters``."""
    targets = np.asarray(target_sensations, dtype=float)
    point = np.array(starts, dtype=float, copy=True)
    n_motors = int(body.n_motors)
    if int(rank) != rank or not 0 <= rank <= n_motors:
        raise ValueError(f"rank must be an integer in [0, {n_motors}], got {rank}")
    if point.ndim != 2 or point.shape[1] != n_motors:
        raise ValueError(f"starts must have shape (K, {n_motors}), got {point.shape}")
    if targets.ndim != 2 or len(targets) != len(point):
        raise ValueError(f"target_sensations must have shape ({len(point)}, S), "
                         f"got {targets.shape}")
    _check_search_parameters(**parameters)
    return targets, point


def _accepted(jac, sensation, residual, error, *, rank, error_tol, motor_tol, rank_ratio,
              min_singular, pattern_ratio):
    """The three acceptance tests of each search: ``(accepted, singular values, motor residual)``."""
    singular = np.linalg.svd(jac, compute_uv=False)
    motor_residual = _step_norm(jac, residual, rank)
    accepted = ((error <= error_tol * singular[:, 0])
                & (motor_residual <= _motor_tolerance(singular, rank, *motor_tol))
                & has_full_pose_rank(jac, rank, rank_ratio, min_singular, sensation,
                                     pattern_ratio))
    return accepted, singular, motor_residual


class _Turns:
    """``compensate(in_turn=True)``: after the first call, which senses every
    start, only the search toward each target whose start sensed most like it
    goes on; the next (by that error) only when those before it stopped
    unaccepted, each for ``max_iterations``; ``max_turns`` turns at most (0: every start)."""

    def __init__(self, target_id: np.ndarray, error: np.ndarray, max_turns: int = 0, *,
                 body=None, fd_step=None):
        order = np.lexsort((error, target_id))
        first = np.r_[True, target_id[order][1:] != target_id[order][:-1]]
        self.turn = np.empty(len(order), dtype=int)
        self.turn[order] = np.arange(len(order)) - np.maximum.accumulate(
            np.where(first, np.arange(len(order)), 0))
        if max_turns > 0:
            self.turn = np.where(self.turn < max_turns, self.turn, -1)     # -1: never searched
        self.target_id, self.waiting = target_id, self.turn > 0
        self.count = 1 + int(self.turn.max())
        self.body, self.fd_step = body, fd_step

    def next(self, active: np.ndarray, budget_left: np.ndarray, accepted: np.ndarray
             ) -> np.ndarray:
        """Stop (in ``active``, in place) the searches past their iterations and
        start the next turn of every target whose searches all stopped unaccepted.
        Returns the searches started."""
        active &= budget_left
        ids = self.target_id
        self.waiting &= ~np.isin(ids, ids[accepted])
        idle = np.flatnonzero(self.waiting & ~np.isin(ids, ids[active]))
        started = np.zeros(len(active), dtype=bool)
        if len(idle):
            idle = idle[np.lexsort((self.turn[idle], ids[idle]))]
            first = idle[np.r_[True, ids[idle][1:] != ids[idle][:-1]]]
            active[first], self.waiting[first] = True, False
            started[first] = True
        return started

    def stencils(self, started, point, sensation, jac, residual, error, targets, queries) -> int:
        """Where only the starts were sensed (``body`` given), sense the
        stencils of the searches ``started`` (their states already sensed:
        ``sensation``), filling ``jac``, ``residual`` and ``error`` in place.
        Returns the calls made (0 or 1)."""
        idx = np.flatnonzero(started)
        if self.body is None or not len(idx):
            return 0
        jac[idx], residual[idx], error[idx] = _stencils_of_sensed(
            self.body, point[idx], sensation[idx], targets[idx], self.fd_step)
        queries[idx] += stencil_rows(point.shape[1], self.fd_step) - 1
        return 1


def _stencils_of_sensed(body, states, sensed, targets, fd_step):
    """The stencils of ``states`` just sensed giving ``sensed``, in one call:
    ``(jac, residual, error)`` toward ``targets`` (a state with a lost row:
    J = 0 and a NaN residual and error)."""
    sensation, jac, _ = sensory_jacobian(body, states, fd_step, sensed=sensed)
    residual = sensation - targets
    return jac, residual, np.linalg.norm(residual, axis=1)


def _outcome(point, jac, sensation, residual, error, queries, iterations, calls, *, rank,
             error_tol, motor_tol, rank_ratio, min_singular,
             pattern_ratio) -> CompensationSearch:
    """The searches' final states, with the three acceptance tests."""
    accepted, singular, motor_residual = _accepted(
        jac, sensation, residual, error, rank=rank, error_tol=error_tol, motor_tol=motor_tol,
        rank_ratio=rank_ratio, min_singular=min_singular, pattern_ratio=pattern_ratio)
    ratio = singular[:, rank - 1] / np.maximum(singular[:, 0], 1e-300)
    return CompensationSearch(motor_states=point, sensory_error=error, gain=singular[:, 0],
                              motor_residual=motor_residual, rank_ratio=ratio,
                              accepted=accepted, queries=queries, iterations=iterations,
                              calls=calls)


def _stopping(jac, sensation, residual, error, history, iteration, target_id, accept, *,
              stall_iterations, stall_factor, stationary_ratio,
              stop_found_targets) -> np.ndarray:
    """Searches that stop before this iteration (``compensate``'s stops):
    converged, stalled, at a stationary point, or restarts toward a target
    another search already found. ``accept``: the acceptance thresholds."""
    rank, error_tol = accept["rank"], accept["error_tol"]
    done = _converged(jac, residual, error, error_tol, accept["motor_tol"], rank)
    stop = done.copy()
    if np.ndim(iteration):      # each search's own iterations (``compensate(in_turn=True)``)
        stop |= (iteration > stall_iterations) & (error > stall_factor * history[
            -1 - min(stall_iterations, len(history) - 1)])
    elif iteration > stall_iterations:
        stop |= error > stall_factor * history[-1 - stall_iterations]
    if stationary_ratio > 0 or stop_found_targets:
        u, singular, _ = np.linalg.svd(jac, full_matrices=False)
    if stationary_ratio > 0:
        in_range = np.linalg.norm(np.einsum("bsk,bs->bk", u[:, :, :rank], residual), axis=1)
        stop |= (in_range < stationary_ratio * error) & (error > error_tol * singular[:, 0])
    if stop_found_targets and done.any():
        found = done & has_full_pose_rank(jac, rank, accept["rank_ratio"],
                                          accept["min_singular"], sensation,
                                          accept["pattern_ratio"])
        stop |= np.isin(target_id, target_id[found])
    return stop


def _damped_step(body, idx, targets, point, jac, residual, error, damping, *, fd_step,
                 max_step, alone=False) -> tuple[np.ndarray, int]:
    """One Levenberg-Marquardt iteration of the searches ``idx``, in one
    ``sense`` call: solve ``(J^T J + lambda I) dm = -J^T r`` (Levenberg's
    isotropic damping, ``lambda`` relative to the mean squared singular
    value of ``J``: the step stays small along the level set's null
    directions), cap the step, probe
    the trial state with its stencil; keep a better trial (``point``,
    ``jac``, ``residual``, ``error`` updated in place) and shrink its
    damping, grow the damping of a worse one. With ``alone`` the trial
    states are sensed alone and only the better ones' stencils after them
    (a row instead of a stencil per rejected trial, two calls for an
    accepted one; not with a step that senses a state more than once).
    Returns the rows each search of ``idx`` probed and the calls made."""
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
    trial_jac, trial_residual, trial_error, better, rows, calls = _sense_trials(
        body, trial, targets[idx], error[idx], fd_step, alone)
    keep = idx[better]
    point[keep] = trial[better]
    jac[keep] = trial_jac[better]
    residual[keep] = trial_residual[better]
    error[keep] = trial_error[better]
    damping[keep] = np.maximum(damping[keep] / 3.0, 1e-12)
    worse = idx[~better]
    damping[worse] = damping[worse] * 4.0
    return rows, calls


def _sense_trials(body, trial, targets, error, fd_step, alone):
    """Sense a step's ``trial`` states with their stencils in one call or,
    with ``alone`` (not for a step that senses a state more than once), the
    trials alone and then the stencils of those better than ``error``.
    Returns ``(jac, residual, error, better, rows, calls)``: ``better`` the
    trials below ``error`` with a Jacobian, ``rows`` each trial's."""
    stencil = stencil_rows(trial.shape[1], fd_step)
    whole = not alone or isinstance(fd_step, (AveragedStep, CloudStep))
    if whole:
        sensation, jac, _ = sensory_jacobian(body, trial, fd_step)
    else:
        sensation = np.asarray(body.sense(trial), dtype=float).reshape(len(trial), -1)
        jac = np.zeros((*sensation.shape, trial.shape[1]))
    residual = sensation - targets
    trial_error = np.linalg.norm(residual, axis=1)
    better = trial_error < error
    if whole:
        return jac, residual, trial_error, better, np.full(len(trial), stencil), 1
    if not better.any():
        return jac, residual, trial_error, better, np.ones(len(trial), dtype=int), 1
    jac[better], residual[better], trial_error[better] = _stencils_of_sensed(
        body, trial[better], sensation[better], targets[better], fd_step)
    rows = np.where(better, stencil, 1)
    return jac, residual, trial_error, better & np.isfinite(trial_error), rows, 2


def _motor_tolerance(singular, rank, motor_tol, noise_step):
    """Accepted Gauss-Newton step per search: ``motor_tol``, or the step a
    residual of measured noise asks for through the ``rank``-th singular
    value (``noise_step`` in sensation units)."""
    if noise_step <= 0:
        return motor_tol
    with np.errstate(divide="ignore", over="ignore"):
        return np.maximum(motor_tol, noise_step / singular[:, rank - 1])


def _converged(jac, residual, error, error_tol, motor_tol, rank):
    converged = error <= error_tol * np.linalg.norm(jac, ord=2, axis=(1, 2))
    if converged.any():
        idx = np.flatnonzero(converged)
        gn = _step_norm(jac[idx], residual[idx], rank)
        singular = np.linalg.svd(jac[idx], compute_uv=False) if motor_tol[1] > 0 else None
        converged[idx] = gn <= _motor_tolerance(singular, rank, *motor_tol)
    return converged


def _step_norm(jac, residual, rank):
    """Norm of the Gauss-Newton step; infinite for a blank (J = 0) sensation."""
    step = minimum_norm_correction(jac, residual, rank)
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
